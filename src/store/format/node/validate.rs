//! Validating node blocks (format-spec/node.md): every rule of a block
//! and its records is checked once, when the block is read, so that the
//! views of it never fail on structure.

use zerocopy::FromBytes;
use zerocopy::byteorder::little_endian::{F64, U16};

use super::{
    BOUND_HEAD_LEN, BlockHead, BoundRaw, FLAG_FRAME, FLAG_GROUPS, FRAME_BOX_LEN, INTERNAL_LEN, InternalRaw,
    KIND_INTERNAL, KIND_LEAF, LEAF_HEAD_LEN, LeafRaw, NodeView, OBJECT_LEN, ObjectRaw, RECORDS_START, leaf_len,
};
use crate::scene::KeyRef;
use crate::store::StorageError;
use crate::store::format::frame::FRAME_LEN;
use crate::store::format::{all_zero, blob, geometry};

/// What validation needs to know of the file.
#[derive(Debug, Clone, Copy)]
pub struct Limits {
    /// Bytes per block.
    pub block_size: u32,
    /// M: bound levels lie in 2 ..= M - 1.
    pub lod_levels: u8,
    /// Object ids lie below this.
    pub object_count: u32,
}

/// Checks every rule of format-spec/node.md on node block `id` (its checksum
/// already verified), so that [`NodeView`]s of it never fail on structure.
/// Returns the record offsets.
pub fn validate_block(id: u32, block: &[u8], limits: &Limits) -> Result<Vec<u32>, StorageError> {
    let bad = |field: &'static str, detail: String| StorageError::corrupt(id, field, detail);
    let head = block
        .get(FRAME_LEN..RECORDS_START)
        .and_then(|b| BlockHead::read_from_bytes(b).ok())
        .ok_or_else(|| bad("node block", "too small".into()))?;
    let used = head.used_bytes.get() as usize;
    let end = RECORDS_START.checked_add(used).filter(|&e| e <= block.len() && used.is_multiple_of(4));
    let Some(end) = end else { return Err(bad("used_bytes", format!("{used} bytes do not fit the block"))) };
    if head.reserved != [0; 2] || !all_zero(&block[end..]) {
        return Err(bad("reserved", "reserved bytes are not zero".into()));
    }
    let count = usize::from(head.record_count.get());
    // Each record is at least a leaf head, so the count is bounded by the bytes.
    if count == 0 || count > used / LEAF_HEAD_LEN {
        return Err(bad("record_count", format!("{count} records in {used} bytes")));
    }
    let mut offsets = Vec::with_capacity(count);
    let mut at = RECORDS_START;
    let mut groups = 0u8;
    for i in 0..count {
        if at >= end {
            return Err(bad("record_count", format!("record {i} starts past the used bytes")));
        }
        offsets.push(at as u32);
        groups |= record_flags(&block[at..end]) & FLAG_GROUPS;
        at += validate_record(id, i as u32, &block[at..end], limits)?;
    }
    // A group block is named when, and only when, some record has a group bound there.
    let (gb, gs) = (head.group_block.get(), head.group_checksum.get());
    if (gb == 0) != (groups == 0) || (gb == 0 && gs != 0) || gb == id {
        return Err(bad(
            "group_block",
            format!("group block {gb} (checksum {gs:#x}) for records with group levels {groups:#x}"),
        ));
    }
    if at != end {
        return Err(bad("used_bytes", format!("{} bytes after the last record", end - at)));
    }
    // In-block children name a record of this block.
    for (i, &o) in offsets.iter().enumerate() {
        if let Ok(NodeView::Internal(n)) = NodeView::at(block, o) {
            for c in 0..2 {
                let r = n.child_ref(c);
                if r.block == 0 && offsets.binary_search(&r.offset).is_err() {
                    return Err(StorageError::corrupt_record(
                        id,
                        i as u32,
                        "child_offset",
                        format!("{} is not a record of this block", r.offset),
                    ));
                }
            }
        }
    }
    Ok(offsets)
}

/// A record's flags byte (0 for a record too short to have one).
fn record_flags(bytes: &[u8]) -> u8 {
    match bytes.first() {
        Some(&KIND_INTERNAL) => bytes.get(2).copied().unwrap_or(0),
        Some(&KIND_LEAF) => bytes.get(1).copied().unwrap_or(0),
        _ => 0,
    }
}

/// A broken rule of a record: the field, and what is wrong with it.
type Fault = (&'static str, String);

/// Validates one record at the start of `bytes`; returns its length.
fn validate_record(id: u32, index: u32, bytes: &[u8], limits: &Limits) -> Result<usize, StorageError> {
    let checked = match bytes.first() {
        Some(&KIND_INTERNAL) => validate_internal(id, bytes, limits),
        Some(&KIND_LEAF) => validate_leaf(bytes, limits),
        Some(k) => Err(("kind", format!("{k} is neither internal (1) nor leaf (2)"))),
        None => Err(("record", "empty".into())),
    };
    checked.map_err(|(field, detail)| StorageError::corrupt_record(id, index, field, detail))
}

/// No lower step of a quantized box exceeds its upper one.
fn qbox_ok(q: &[U16; 6]) -> bool {
    (0..3).all(|a| q[a].get() <= q[a + 3].get())
}

/// An internal record (kind 1) of node block `id`; returns its length.
fn validate_internal(id: u32, bytes: &[u8], limits: &Limits) -> Result<usize, Fault> {
    let (raw, rest) = InternalRaw::ref_from_prefix(bytes).map_err(|_| ("record", "short".to_string()))?;
    validate_groups(raw.flags, limits).map_err(|d| ("flags", d))?;
    let frame = validate_frame(raw.flags, rest).map_err(|d| ("frame", d))?;
    if raw.split & 0b11 > 2 || raw.split >> 2 > 2 {
        return Err(("split", format!("{:#x} is not an axis and order", raw.split)));
    }
    let (overlap, gap) = (raw.split_overlap.get(), raw.split_gap.get());
    if !overlap.is_finite() || overlap < 0.0 || !gap.is_finite() {
        return Err(("split_overlap", format!("overlap {overlap}, gap {gap}")));
    }
    if raw.object_count.get() < 2 {
        return Err(("object_count", "an internal node holds fewer than two objects".into()));
    }
    for c in &raw.children {
        if !qbox_ok(&c.qbox) {
            return Err(("child_box", "a lower step exceeds the upper one".into()));
        }
        let (b, s) = (c.block.get(), c.checksum.get());
        if b == id || (b == 0 && s != 0) {
            return Err(("child_block", format!("block {b} with checksum {s}")));
        }
        if c.offset.get() % 4 != 0 || (c.offset.get() as usize) < RECORDS_START {
            return Err(("child_offset", format!("{} is not a record offset", c.offset.get())));
        }
    }
    if raw.reserved != 0 {
        return Err(("reserved", "reserved bytes are not zero".into()));
    }
    Ok(INTERNAL_LEN + frame)
}

/// A leaf record (kind 2); returns its length.
fn validate_leaf(bytes: &[u8], limits: &Limits) -> Result<usize, Fault> {
    let (raw, rest) = LeafRaw::ref_from_prefix(bytes).map_err(|_| ("record", "short".to_string()))?;
    validate_groups(raw.flags, limits).map_err(|d| ("flags", d))?;
    let frame = validate_frame(raw.flags, rest).map_err(|d| ("frame", d))?;
    // The rest of the record is read as if the frame were not there.
    let bytes = &bytes[frame..];
    let (n, span) = (usize::from(raw.object_count.get()), usize::from(raw.span.get()));
    if n == 0 || span == 0 || raw.first_block.get() == 0 {
        return Err(("object_count", format!("{n} objects over {span} blocks from {}", raw.first_block)));
    }
    let bounds = raw.bounds_bytes.get() as usize;
    let keys = usize::from(raw.keys_bytes.get());
    let len = bounds.checked_add(leaf_len(n, span, 0, keys)).filter(|&l| l <= bytes.len());
    let Some(len) = len else {
        return Err(("bounds_bytes", "the record overruns the block".into()));
    };
    let payload = limits.block_size as u64 - FRAME_LEN as u64;
    let objects_at = LEAF_HEAD_LEN + 4 * span;
    let (objects, last) = validate_objects(&bytes[objects_at..], n, payload, limits)?;
    let end_at = objects_at + n * OBJECT_LEN;
    validate_end(&bytes[end_at..], last, span, payload)?;
    let bounds_end = end_at + 4 + bounds;
    validate_bounds(&bytes[end_at + 4..bounds_end], n, limits).map_err(|d| ("bounds", d))?;
    validate_keys(&bytes[bounds_end..len], objects).map_err(|d| ("keys", d))?;
    Ok(len + frame)
}

/// A leaf's `n` object entries, at the start of `entries`, over a span of
/// blocks of `payload` bytes. Returns the number of objects (an object
/// larger than a block has an entry per part) and the last entry's position.
fn validate_objects(
    entries: &[u8],
    n: usize,
    payload: u64,
    limits: &Limits,
) -> Result<(usize, Option<u64>), Fault> {
    let mut prev: Option<u64> = None;
    // The first entry of each object: its parts follow it, so no id starts twice.
    let mut starts: Vec<u32> = Vec::new();
    for i in 0..n {
        let (o, _) = ObjectRaw::ref_from_prefix(&entries[i * OBJECT_LEN..])
            .map_err(|_| ("objects", "short".to_string()))?;
        if o.object_id.get() >= limits.object_count {
            return Err(("object_id", format!("{} >= {} objects", o.object_id, limits.object_count)));
        }
        if !qbox_ok(&o.qbox) {
            return Err(("object_box", "a lower step exceeds the upper one".into()));
        }
        if starts.last() != Some(&o.object_id.get()) {
            starts.push(o.object_id.get());
        }
        let p = u64::from(o.position.get()) * 4;
        if i == 0 && p >= payload {
            return Err(("position", "the first object does not start in the span's first block".into()));
        }
        if prev.is_some_and(|q| p < q + geometry::HEADER_LEN as u64) {
            return Err(("position", format!("object {i} starts inside the one before")));
        }
        prev = Some(p);
    }
    let objects = starts.len();
    starts.sort_unstable();
    if let Some(w) = starts.windows(2).find(|w| w[0] == w[1]) {
        return Err(("object_id", format!("object {}'s entries are not consecutive", w[0])));
    }
    Ok((objects, prev))
}

/// A leaf's end, the word at the start of `bytes` (in words of the span):
/// past the record at `last`, the last entry's position, and within the
/// last of the span's `span` blocks of `payload` bytes.
fn validate_end(bytes: &[u8], last: Option<u64>, span: usize, payload: u64) -> Result<(), Fault> {
    let word = bytes[..4].try_into().map_err(|_| ("end", "short".to_string()))?;
    let end = u64::from(u32::from_le_bytes(word)) * 4;
    if last.is_some_and(|q| end < q + geometry::HEADER_LEN as u64) || end > payload * span as u64 {
        return Err(("end", format!("the span's records end at {end} bytes, past its {span} blocks")));
    }
    if (end - 1) / payload + 1 != span as u64 {
        return Err(("span", format!("{span} blocks for records ending at byte {end}")));
    }
    Ok(())
}

/// A record's own frame, when its flags say it has one: six finite f64,
/// lower corner below the upper, within the coordinate range. Returns its
/// bytes (0 without one).
fn validate_frame(flags: u8, rest: &[u8]) -> Result<usize, String> {
    // Every bit is named: bit 0 the frame, bits 1-7 group levels (validate_groups).
    if flags & FLAG_FRAME == 0 {
        return Ok(0);
    }
    let (f, _) = <[F64; 6]>::ref_from_prefix(rest).map_err(|_| "the frame is cut".to_string())?;
    let f = f.map(|x| x.get());
    let range = geometry::MAX_COORDINATE;
    if !f.iter().all(|x| x.is_finite() && x.abs() <= range) || (0..3).any(|a| f[a] > f[a + 3]) {
        return Err(format!("{f:?} is not a box in the coordinate range"));
    }
    Ok(FRAME_BOX_LEN)
}

/// A record's group levels lie in 2 ..= M - 1.
fn validate_groups(flags: u8, limits: &Limits) -> Result<(), String> {
    let levels = flags & FLAG_GROUPS;
    // Bit j is level j + 1: any bit at or above M - 1 names a level >= M.
    let allowed = if limits.lod_levels >= 3 { FLAG_GROUPS & ((1u16 << (limits.lod_levels - 1)) - 1) as u8 } else { 0 };
    if levels & !allowed != 0 {
        return Err(format!("group levels {levels:#x} with M = {}", limits.lod_levels));
    }
    Ok(())
}

/// A leaf's keys area holds one key per object, then fewer than 4 zero bytes.
fn validate_keys(mut area: &[u8], objects: usize) -> Result<(), String> {
    for i in 0..objects {
        let (_, n) = KeyRef::decode(area).ok_or_else(|| format!("object {i}'s key is cut or unknown"))?;
        area = &area[n..];
    }
    if area.len() >= 4 || !all_zero(area) {
        return Err("bytes after the keys are not padding".into());
    }
    Ok(())
}

fn validate_bounds(mut area: &[u8], targets: usize, limits: &Limits) -> Result<(), String> {
    let mut last: Option<(u16, u8)> = None;
    // Entries while a head fits; fewer than 4 bytes left are the zero padding.
    while area.len() >= BOUND_HEAD_LEN {
        let (raw, rest) = BoundRaw::ref_from_prefix(area).map_err(|_| "a bound's head is cut".to_string())?;
        let (t, k) = (raw.target.get(), raw.level());
        if usize::from(t) >= targets || k < 2 || k >= limits.lod_levels {
            return Err(format!("a bound of target {t} at level {k}"));
        }
        // One bound per target and level, in order: a reader finds them by scanning once.
        if last.is_some_and(|l| l >= (t, k)) {
            return Err("bounds are not in (target, level) order".into());
        }
        last = Some((t, k));
        let n = raw.blob_bytes();
        if n > rest.len() {
            return Err(format!("a bound of {n} bytes overruns its record"));
        }
        // A bound is of a surface, which touches some cell: one of no cell
        // would rule its object out of every query.
        if blob::sets_no_cell(&rest[..n]) {
            return Err(format!("the bound of target {t} at level {k} sets no cell"));
        }
        area = &rest[n..];
    }
    if !all_zero(area) {
        return Err("the bounds' padding is not zero".into());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::store::format::node::encode_block;
    use crate::store::format::node::tests::{drafts, limits};

    #[test]
    fn broken_rules_are_corruption() {
        let mut block = vec![0u8; 1024];
        let offsets = encode_block(&drafts(), &mut block).unwrap();
        // (byte, value): the kind, the used bytes, an in-block child offset,
        // the reserved tail, an object id out of range, the third entry's id
        // made 3 (object 3 again, after 4), the bound's bitmap (its blob:
        // level 1, form 1, one byte) cleared; a key's unknown tag, a key's
        // length past the keys, padding that is not zero.
        let third = offsets[1] as usize + 20 + 4 + 2 * 20;
        let bitmap = offsets[1] as usize + 20 + 4 + 3 * 20 + 4 + 4 + 2;
        // The keys after the bound's 8 bytes: 9 of an integer, 6 of "four", 1 of padding.
        let keys = offsets[1] as usize + 20 + 4 + 3 * 20 + 4 + 8;
        let cases = [
            (keys, 5),
            (keys + 10, 9),
            (keys + 15, 1),
            (RECORDS_START, 7),
            (16, 1),
            (RECORDS_START + 20 + 16, 1),
            // A group level with no group block, a group block no record names.
            (RECORDS_START + 2, 1 << 1),
            (FRAME_LEN + 8, 9),
            // A group level at M (level 4 of a file of M = 4).
            (RECORDS_START + 2, 1 << 3),
            (1000, 1),
            (offsets[1] as usize + 20 + 4, 99),
            (third, 3),
            (bitmap, 0),
        ];
        for (i, (at, value)) in cases.into_iter().enumerate() {
            let mut b = block.clone();
            b[at] = value;
            assert!(validate_block(3, &b, &limits()).is_err(), "case {i}");
        }
    }
}
