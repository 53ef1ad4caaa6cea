//! Free-list blocks (format-spec/freelist.md).

use zerocopy::byteorder::little_endian::{U32, U64};
use zerocopy::{FromBytes, Immutable, IntoBytes, KnownLayout, Unaligned};

use super::all_zero;
use super::frame::FRAME_LEN;
use crate::store::StorageError;

#[derive(Debug, Clone, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
#[repr(C)]
pub(crate) struct FreeListHeader {
    pub(crate) next_block: U32,
    pub(crate) next_checksum: U32,
    pub(crate) range_count: U32,
    pub(crate) reserved: [u8; 4],
}

#[derive(Debug, Clone, Copy, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
#[repr(C)]
struct RangeRecord {
    first: U32,
    count: U32,
    freed: U64,
}
const RANGE_LEN: usize = size_of::<RangeRecord>();

/// Free blocks `first .. first + count`, made free by commit `freed`: a
/// reader of a state older than `freed` may still read them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FreeRange {
    /// The first free block.
    pub first: u32,
    /// The number of blocks in the range.
    pub count: u32,
    /// The transaction id of the commit that freed them.
    pub freed: u64,
}

const HEADER_END: usize = FRAME_LEN + size_of::<FreeListHeader>();

/// Ranges one free-list block holds.
pub fn ranges_per_block(block_size: u32) -> usize {
    (block_size as usize - HEADER_END) / RANGE_LEN
}

/// One decoded free-list block.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FreeListBlock {
    /// The next free-list block; 0 for the last.
    pub next_block: u32,
    /// The checksum the next block must carry; 0 for none.
    pub next_checksum: u32,
    /// The ranges this block holds.
    pub ranges: Vec<FreeRange>,
}

impl FreeListBlock {
    /// Writes the payload into `block`.
    pub fn encode(&self, block: &mut [u8]) {
        let h = FreeListHeader {
            next_block: self.next_block.into(),
            next_checksum: self.next_checksum.into(),
            range_count: (self.ranges.len() as u32).into(),
            reserved: [0; 4],
        };
        block[FRAME_LEN..HEADER_END].copy_from_slice(h.as_bytes());
        for (i, r) in self.ranges.iter().enumerate() {
            let rec = RangeRecord { first: r.first.into(), count: r.count.into(), freed: r.freed.into() };
            let at = HEADER_END + RANGE_LEN * i;
            block[at..at + RANGE_LEN].copy_from_slice(rec.as_bytes());
        }
    }

    /// Reads free-list block `id` (checksum already verified).
    pub fn decode(id: u32, block: &[u8]) -> Result<FreeListBlock, StorageError> {
        let h = FreeListHeader::read_from_bytes(&block[FRAME_LEN..HEADER_END])
            .map_err(|_| StorageError::corrupt(id, "free list", "block too small"))?;
        let n = h.range_count.get() as usize;
        if n > ranges_per_block(block.len() as u32) {
            return Err(StorageError::corrupt(id, "range_count", format!("{n} ranges do not fit a block")));
        }
        if h.reserved != [0; 4] || !all_zero(&block[HEADER_END + RANGE_LEN * n..]) {
            return Err(StorageError::corrupt(id, "reserved", "reserved bytes are not zero"));
        }
        let ranges = <[RangeRecord]>::ref_from_bytes(&block[HEADER_END..HEADER_END + RANGE_LEN * n])
            .map_err(|_| StorageError::corrupt(id, "ranges", "misaligned"))?
            .iter()
            .map(|r| FreeRange { first: r.first.get(), count: r.count.get(), freed: r.freed.get() })
            .collect();
        Ok(FreeListBlock { next_block: h.next_block.get(), next_checksum: h.next_checksum.get(), ranges })
    }
}
