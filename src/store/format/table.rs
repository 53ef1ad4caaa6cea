//! A tree kept in a table of a host database (redb): the state record, the
//! table's value 0, which takes the place of block 0 and its commit slots
//! (format-spec/redb.md).

use zerocopy::byteorder::little_endian::{U32, U64};
use zerocopy::{FromBytes, Immutable, IntoBytes, KnownLayout, Unaligned};

use super::{FORMAT_VERSION, all_zero, validate_block_size, validate_lod_levels};
use crate::store::StorageError;

/// `\x89MKR\r\n\x1a\n`: an MKtree's state in a redb table (the file's magic says MKT).
pub const STATE_MAGIC: [u8; 8] = [0x89, b'M', b'K', b'R', b'\r', b'\n', 0x1a, b'\n'];

/// The fixed part of the state record.
#[derive(Debug, Clone, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
#[repr(C)]
pub(crate) struct StateRecord {
    pub(crate) magic: [u8; 8],
    pub(crate) format_version: U32,
    pub(crate) block_size: U32,
    pub(crate) lod_levels: u8,
    pub(crate) reserved0: [u8; 3],
    pub(crate) meta_block: U32,
    pub(crate) txn: U64,
    pub(crate) meta_checksum: U32,
    pub(crate) block_count: U32,
    pub(crate) free_blocks: U32,
    pub(crate) range_count: U32,
    pub(crate) reserved1: [u8; 16],
}
const STATE_LEN: usize = size_of::<StateRecord>();
const _: () = assert!(STATE_LEN == 64);

#[derive(Debug, Clone, Copy, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
#[repr(C)]
struct RangeRecord {
    first: U32,
    count: U32,
}
const RANGE_LEN: usize = size_of::<RangeRecord>();

/// The committed state of a tree in a table, decoded.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TableState {
    /// Bytes per block.
    pub block_size: u32,
    /// M, the number of levels of detail.
    pub lod_levels: u8,
    /// The mktree transaction that wrote it; 1 for a new, empty tree.
    pub txn: u64,
    /// 0: no tree yet.
    pub meta_block: u32,
    /// The checksum the meta block must carry.
    pub meta_checksum: u32,
    /// One past the largest block id in use.
    pub block_count: u32,
    /// Ids below `block_count` that hold no block: (first, count), sorted,
    /// disjoint, not touching.
    pub free: Vec<(u32, u32)>,
}

impl TableState {
    /// The state of a new table: no tree, no blocks.
    pub fn empty(block_size: u32, lod_levels: u8) -> TableState {
        TableState {
            block_size,
            lod_levels,
            txn: 1,
            meta_block: 0,
            meta_checksum: 0,
            block_count: 1,
            free: Vec::new(),
        }
    }

    /// Blocks the free ranges hold.
    pub fn free_blocks(&self) -> u32 {
        self.free.iter().map(|r| r.1).sum()
    }

    /// The record's bytes.
    pub fn encode(&self) -> Vec<u8> {
        let head = StateRecord {
            magic: STATE_MAGIC,
            format_version: FORMAT_VERSION.into(),
            block_size: self.block_size.into(),
            lod_levels: self.lod_levels,
            reserved0: [0; 3],
            meta_block: self.meta_block.into(),
            txn: self.txn.into(),
            meta_checksum: self.meta_checksum.into(),
            block_count: self.block_count.into(),
            free_blocks: self.free_blocks().into(),
            range_count: (self.free.len() as u32).into(),
            reserved1: [0; 16],
        };
        let mut out = head.as_bytes().to_vec();
        for &(first, count) in &self.free {
            out.extend_from_slice(RangeRecord { first: first.into(), count: count.into() }.as_bytes());
        }
        out
    }

    /// Reads and validates a state record (format-spec/redb.md, "Validity").
    pub fn decode(bytes: &[u8]) -> Result<TableState, StorageError> {
        let bad = |field: &'static str, detail: String| StorageError::corrupt(0, field, detail);
        let head_bytes = bytes.get(..STATE_LEN).ok_or(StorageError::NotMktree)?;
        let h = StateRecord::read_from_bytes(head_bytes).map_err(|_| StorageError::NotMktree)?;
        if h.magic != STATE_MAGIC {
            return Err(StorageError::NotMktree);
        }
        if h.format_version.get() != FORMAT_VERSION {
            return Err(StorageError::UnsupportedVersion {
                found: h.format_version.get(),
                supported: FORMAT_VERSION,
            });
        }
        let block_size = validate_block_size(h.block_size.get().into())?;
        let lod_levels = validate_lod_levels(h.lod_levels.into())?;
        if !all_zero(&h.reserved0) || !all_zero(&h.reserved1) {
            return Err(bad("reserved", "reserved bytes are not zero".into()));
        }
        let n = h.range_count.get() as usize;
        if bytes.len() != STATE_LEN + RANGE_LEN * n {
            return Err(bad("range_count", format!("{n} ranges in a record of {} bytes", bytes.len())));
        }
        let (txn, block_count) = (h.txn.get(), h.block_count.get());
        if txn == 0 {
            return Err(bad("txn", "0 is no transaction".into()));
        }
        if block_count == 0 {
            return Err(bad("block_count", "0: block id 0 is the state record's".into()));
        }
        let records = <[RangeRecord]>::ref_from_bytes(&bytes[STATE_LEN..])
            .map_err(|_| bad("ranges", "misaligned ranges".into()))?;
        let mut free = Vec::with_capacity(n);
        let mut next = 1u64;
        for r in records {
            let (first, count) = (r.first.get(), r.count.get());
            let end = u64::from(first) + u64::from(count);
            if count == 0 || u64::from(first) < next || end > u64::from(block_count) {
                return Err(bad(
                    "ranges",
                    format!("range ({first}, {count}) is empty, out of order, touching or past the end"),
                ));
            }
            free.push((first, count));
            // Touching ranges would have been merged.
            next = end + 1;
        }
        let state = TableState {
            block_size,
            lod_levels,
            txn,
            meta_block: h.meta_block.get(),
            meta_checksum: h.meta_checksum.get(),
            block_count,
            free,
        };
        if u64::from(state.free_blocks()) != u64::from(h.free_blocks.get()) {
            return Err(bad(
                "free_blocks",
                format!("the record says {}, its ranges hold {}", h.free_blocks.get(), state.free_blocks()),
            ));
        }
        let m = state.meta_block;
        if m != 0 && (m >= block_count || state.free.iter().any(|&(f, c)| (f..f + c).contains(&m))) {
            return Err(bad("meta_block", format!("block {m} is free or past the end")));
        }
        if m == 0 && (state.meta_checksum != 0 || block_count != 1) {
            return Err(bad("meta_block", "no tree, yet a checksum or blocks".into()));
        }
        Ok(state)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// Any state with valid ranges reads back as written.
        #[test]
        fn a_state_reads_back_as_written(
            gaps in prop::collection::vec((1u32..50, 1u32..50), 0..20),
            txn in 1u64..u64::MAX,
            tail in 1u32..100,
        ) {
            let mut free = Vec::new();
            let mut at = 1;
            for (used, gap) in gaps {
                at += used;
                free.push((at, gap));
                at += gap;
            }
            let block_count = at + tail;
            let s = TableState { block_size: 16_368, lod_levels: 4, txn, meta_block: at, meta_checksum: 7, block_count, free };
            prop_assert_eq!(TableState::decode(&s.encode()).unwrap(), s);
        }
    }

    #[test]
    fn damaged_states_are_refused() {
        let s = TableState {
            free: vec![(2, 3)],
            meta_block: 1,
            meta_checksum: 9,
            block_count: 10,
            ..TableState::empty(16_368, 4)
        };
        let good = s.encode();
        assert!(matches!(TableState::decode(&good[..10]), Err(StorageError::NotMktree)));
        let mut b = good.clone();
        b[8] = 4;
        assert!(matches!(TableState::decode(&b), Err(StorageError::UnsupportedVersion { found: 4, .. })));
        let mut b = good.clone();
        b.pop();
        assert!(TableState::decode(&b).unwrap_err().is_corruption());
        // The meta block inside a free range.
        let bad = TableState { meta_block: 3, ..s.clone() };
        assert!(TableState::decode(&bad.encode()).unwrap_err().is_corruption());
        // Touching ranges.
        let bad = TableState { free: vec![(2, 3), (5, 1)], ..s };
        assert!(TableState::decode(&bad.encode()).unwrap_err().is_corruption());
    }
}
