//! Group-bound blocks (type 10, format-spec/group.md): the group bounds
//! b(S_n,k) of the records of one node block, each an inline voxel blob
//! (format-spec/lod.md) found by its record's offset and its level. A node
//! block names its group block in its head; a record's flags say which
//! levels the group block holds for it (node.md), so the reads of fetching
//! b(S_n,k) are known from the record: one, unless the block is held.

use zerocopy::byteorder::little_endian::{U16, U32};
use zerocopy::{FromBytes, Immutable, IntoBytes, KnownLayout, Unaligned};

use super::all_zero;
use super::frame::FRAME_LEN;
use crate::store::StorageError;

/// Offset of the first directory entry.
pub const ENTRIES_START: usize = FRAME_LEN + 8;
/// Bytes of a directory entry.
pub const ENTRY_LEN: usize = 12;

#[derive(Debug, Clone, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
#[repr(C)]
struct HeadRaw {
    used_bytes: U32,
    entry_count: U16,
    reserved: [u8; 2],
}
const _: () = assert!(size_of::<HeadRaw>() == 8);

#[derive(Debug, Clone, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
#[repr(C)]
struct EntryRaw {
    record: U32,
    level: u8,
    reserved: [u8; 3],
    offset: U32,
}
const _: () = assert!(size_of::<EntryRaw>() == ENTRY_LEN);

/// A group bound to write: the blob of b(S_n,`level`) for the record at
/// byte `record` of the node block.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct GroupEntry {
    /// The record's byte offset in its node block.
    pub record: u32,
    /// The level k, 2 ..= 8 and below M.
    pub level: u8,
    /// The voxel blob (format-spec/lod.md).
    pub blob: Vec<u8>,
}

/// Bytes a group block's entries take from its payload (head, directory, blobs).
pub fn entries_len<'a>(entries: impl IntoIterator<Item = &'a GroupEntry>) -> usize {
    8 + entries.into_iter().map(|e| ENTRY_LEN + e.blob.len()).sum::<usize>()
}

/// Bytes of group entries a block of `block_size` holds.
pub fn capacity(block_size: u32) -> usize {
    block_size as usize - FRAME_LEN
}

/// Encodes `entries` (sorted by (record, level), no repeat) into `block`'s payload.
pub fn encode(entries: &[GroupEntry], block: &mut [u8]) -> Result<(), String> {
    if entries.is_empty() || entries.windows(2).any(|w| (w[0].record, w[0].level) >= (w[1].record, w[1].level)) {
        return Err("group entries must be sorted by (record, level), at least one".into());
    }
    let len = entries_len(entries);
    if FRAME_LEN + len > block.len() {
        return Err(format!("{len} bytes of group bounds exceed the block"));
    }
    let count = u16::try_from(entries.len()).map_err(|_| "too many group entries".to_string())?;
    let head = HeadRaw { used_bytes: ((len - 8) as u32).into(), entry_count: count.into(), reserved: [0; 2] };
    block[FRAME_LEN..ENTRIES_START].copy_from_slice(head.as_bytes());
    let mut at = ENTRIES_START + ENTRY_LEN * entries.len();
    for (i, e) in entries.iter().enumerate() {
        if e.blob.is_empty() {
            return Err("an empty group bound".into());
        }
        let raw = EntryRaw { record: e.record.into(), level: e.level, reserved: [0; 3], offset: (at as u32).into() };
        let d = ENTRIES_START + ENTRY_LEN * i;
        block[d..d + ENTRY_LEN].copy_from_slice(raw.as_bytes());
        block[at..at + e.blob.len()].copy_from_slice(&e.blob);
        at += e.blob.len();
    }
    block[at..].fill(0);
    Ok(())
}

/// Checks every rule of format-spec/group.md on group block `id` (its
/// checksum already verified) for a file of M = `lod_levels`; returns its
/// entries as (record, level, blob range), sorted.
pub fn validate(id: u32, block: &[u8], lod_levels: u8) -> Result<Vec<(u32, u8, std::ops::Range<usize>)>, StorageError> {
    let bad = |field: &'static str, detail: String| StorageError::corrupt(id, field, detail);
    let head = block
        .get(FRAME_LEN..ENTRIES_START)
        .and_then(|b| HeadRaw::read_from_bytes(b).ok())
        .ok_or_else(|| bad("group block", "too small".into()))?;
    let used = head.used_bytes.get() as usize;
    let end = ENTRIES_START.checked_add(used).filter(|&e| e <= block.len());
    let Some(end) = end else { return Err(bad("used_bytes", format!("{used} bytes do not fit the block"))) };
    if head.reserved != [0; 2] || !all_zero(&block[end..]) {
        return Err(bad("reserved", "reserved bytes are not zero".into()));
    }
    let count = usize::from(head.entry_count.get());
    // Each entry takes its directory slot and at least one blob byte: the count is bounded by the bytes.
    if count == 0 || count > used / (ENTRY_LEN + 1) {
        return Err(bad("entry_count", format!("{count} entries in {used} bytes")));
    }
    let blobs_start = ENTRIES_START + ENTRY_LEN * count;
    let mut out: Vec<(u32, u8, std::ops::Range<usize>)> = Vec::with_capacity(count);
    let mut expected = blobs_start;
    for i in 0..count {
        let d = ENTRIES_START + ENTRY_LEN * i;
        let (e, _) = EntryRaw::ref_from_prefix(&block[d..]).map_err(|_| bad("entry", "cut".into()))?;
        let (record, level, offset) = (e.record.get(), e.level, e.offset.get() as usize);
        if e.reserved != [0; 3] {
            return Err(bad("reserved", "reserved bytes are not zero".into()));
        }
        if level < 2 || level >= lod_levels || level > super::node::MAX_GROUP_LEVEL {
            return Err(bad("level", format!("a group bound at level {level} (M = {lod_levels})")));
        }
        if !record.is_multiple_of(4) || (record as usize) < super::node::RECORDS_START {
            return Err(bad("record", format!("{record} is not a record offset")));
        }
        if out.last().is_some_and(|l| (l.0, l.1) >= (record, level)) {
            return Err(bad("entries", "entries are not in (record, level) order".into()));
        }
        // Blobs follow the directory in entry order, each at least one byte, no gap.
        if (i == 0 && offset != expected) || offset < expected || offset >= end {
            return Err(bad("offset", format!("entry {i}'s blob starts at {offset}")));
        }
        if let Some(last) = out.last_mut() {
            last.2.end = offset;
        }
        out.push((record, level, offset..end));
        expected = offset + 1;
    }
    for (record, level, r) in &out {
        if r.start >= r.end {
            return Err(bad("offset", format!("the bound of record {record} at level {level} is empty")));
        }
        if super::blob::sets_no_cell(&block[r.clone()]) {
            return Err(bad("blob", format!("the bound of record {record} at level {level} sets no cell")));
        }
    }
    Ok(out)
}

/// The blob of b(S_n,`level`) for the record at `record`, in a group block
/// [`validate`] accepted; `None` when the block holds none.
pub fn find<'a>(
    block: &'a [u8],
    entries: &[(u32, u8, std::ops::Range<usize>)],
    record: u32,
    level: u8,
) -> Option<&'a [u8]> {
    let i = entries.binary_search_by(|e| (e.0, e.1).cmp(&(record, level))).ok()?;
    block.get(entries[i].2.clone())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn blob() -> Vec<u8> {
        // Lattice level 0, bitmap form, one cell set.
        vec![0, super::super::blob::FORM_BITMAP, 1]
    }

    #[test]
    fn entries_round_trip_and_are_found() {
        let es = vec![
            GroupEntry { record: 32, level: 2, blob: blob() },
            GroupEntry { record: 32, level: 3, blob: [blob(), vec![0]].concat() },
            GroupEntry { record: 140, level: 2, blob: blob() },
        ];
        let mut b = vec![0u8; 1024];
        encode(&es, &mut b).unwrap();
        let v = validate(7, &b, 4).unwrap();
        assert_eq!(v.len(), 3);
        assert_eq!(find(&b, &v, 32, 3), Some(&es[1].blob[..]));
        assert_eq!(find(&b, &v, 140, 2), Some(&es[2].blob[..]));
        assert_eq!(find(&b, &v, 140, 3), None);
    }

    #[test]
    fn broken_rules_are_corruption() {
        let es = vec![GroupEntry { record: 32, level: 2, blob: blob() }, GroupEntry { record: 36, level: 2, blob: blob() }];
        let mut good = vec![0u8; 1024];
        encode(&es, &mut good).unwrap();
        assert!(validate(1, &good, 4).is_ok());
        for (at, value) in [
            (ENTRIES_START + 4, 9u8),                // level 9 >= M
            (ENTRIES_START + 4, 1),                  // level 1
            (ENTRIES_START, 33),                     // a record offset not a multiple of 4
            (ENTRIES_START + ENTRY_LEN, 28),         // records out of order
            (ENTRIES_START + 8, 0),                  // a blob offset moved
            (ENTRIES_START + 5, 1),                  // reserved
            (FRAME_LEN + 4, 200),                    // entry count
            (FRAME_LEN + 1, 255),                    // used bytes
            (1000, 1),                               // bytes after the used ones
        ] {
            let mut b = good.clone();
            b[at] = value;
            assert!(validate(1, &b, 4).is_err(), "byte {at} = {value} is refused");
        }
        assert!(encode(&[], &mut good.clone()).is_err());
        assert!(encode(&[es[1].clone(), es[0].clone()], &mut good.clone()).is_err());
    }
}
