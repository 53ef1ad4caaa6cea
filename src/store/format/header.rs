//! Block 0: the fixed header and the two commit slots, each kept in two
//! copies (format-spec/header.md).

use zerocopy::byteorder::little_endian::{U32, U64};
use zerocopy::{FromBytes, FromZeros, Immutable, IntoBytes, KnownLayout, Unaligned};

use super::{FORMAT_VERSION, all_zero, validate_block_size, validate_lod_levels};
use crate::store::StorageError;

/// The largest transaction id: every id names a reader's lock byte
/// (`store/lock.rs`), which must stay below 2^63. No file reaches it by
/// committing; a slot beyond it is forged or damaged.
pub const MAX_TXN: u64 = (1 << 62) - 2;

/// `\x89MKT\r\n\x1a\n`.
pub const MAGIC: [u8; 8] = [0x89, b'M', b'K', b'T', b'\r', b'\n', 0x1a, b'\n'];
/// Bytes a reader needs to learn the block size and read both slots.
pub const PREFIX_LEN: usize = 1024;
/// Bytes of one copy of a commit slot.
pub const SLOT_LEN: usize = 128;
/// Offset of copy `copy` (0 or 1) of slot `slot` (0 or 1) in block 0.
pub const fn slot_offset(slot: usize, copy: usize) -> usize {
    512 + SLOT_LEN * (2 * copy + slot)
}

/// The fixed region, bytes 0 .. 512 of block 0.
#[derive(Debug, Clone, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
#[repr(C)]
pub struct FixedHeader {
    /// [`MAGIC`]: catches text-mode transfers, as PNG's does.
    pub magic: [u8; 8],
    /// The format version ([`FORMAT_VERSION`]; format-spec/versions.md).
    pub format_version: U32,
    /// Bytes per block: a multiple of 16 in 1,024 ..= 4,194,304.
    pub block_size: U32,
    /// M, the number of levels of detail, 1 ..= 16; level M is the exact geometry.
    pub lod_levels: u8,
    /// Zero.
    pub reserved: [u8; 491],
    /// CRC-32 over bytes 0 .. 508, then the tail of block 0 (bytes 1024 .. `block_size`).
    pub header_checksum: U32,
}
const _: () = assert!(size_of::<FixedHeader>() == 512);

/// Slot states.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum SlotState {
    /// No commit: the copy is all zero bytes.
    Empty = 0,
    /// A write transaction began and has not committed.
    Pending = 1,
    /// Committed (written as state 3 when [`Commit::listed`]).
    Committed = 2,
}

/// The state byte of a slot committed with one sync, whose meta block
/// lists the blocks it wrote.
const LISTED: u8 = 3;

/// One copy of a commit slot (128 bytes).
#[derive(Debug, Clone, Copy, PartialEq, Eq, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
#[repr(C)]
pub struct Slot {
    /// Transaction id, at most [`MAX_TXN`]; 0 only in an empty slot.
    pub txn: U64,
    /// 0 empty, 1 pending, 2 committed, 3 committed with one sync (the meta
    /// block lists the blocks written).
    pub state: u8,
    /// Zero.
    pub reserved0: [u8; 3],
    /// Block id of the meta block; 0 = no tree (an empty database).
    pub meta_block: U32,
    /// The checksum the meta block must carry (0 when `meta_block` is 0).
    pub meta_checksum: U32,
    /// File length in blocks at this commit.
    pub block_count: U32,
    /// First free-list block; 0 = no free blocks.
    pub freelist_block: U32,
    /// The checksum that free-list block must carry (0 when none).
    pub freelist_checksum: U32,
    /// Number of free blocks the list holds.
    pub free_blocks: U32,
    /// Zero.
    pub reserved1: [u8; 88],
    /// CRC-32 over bytes 0 .. 124 of the copy, then the slot index and the
    /// copy index, each as a u32.
    pub slot_checksum: U32,
}
const _: () = assert!(size_of::<Slot>() == SLOT_LEN);

/// A slot's contents, decoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Commit {
    /// Transaction id, 1 ..= [`MAX_TXN`].
    pub txn: u64,
    /// Block id of the meta block; 0 = no tree.
    pub meta_block: u32,
    /// The checksum the meta block must carry.
    pub meta_checksum: u32,
    /// File length in blocks.
    pub block_count: u32,
    /// First free-list block; 0 = no free blocks.
    pub freelist_block: u32,
    /// The checksum that free-list block must carry.
    pub freelist_checksum: u32,
    /// Number of free blocks the list holds.
    pub free_blocks: u32,
    /// Committed with one sync (state 3): the meta block lists every other
    /// block the commit wrote, which a reader verifies before it takes the
    /// commit as whole (format-spec/commit.md).
    pub listed: bool,
}

/// A slot copy as read: empty, pending, committed, or failing its checksum
/// (torn or damaged).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SlotRead {
    /// All zero bytes: never written.
    Empty,
    /// A write transaction began and has not committed.
    Pending {
        /// The transaction's id.
        txn: u64,
    },
    /// A commit (state 2 or 3).
    Committed(Commit),
    /// The checksum fails, a reserved byte is set, or the id or state is out of range.
    Invalid,
}

impl SlotRead {
    /// Order of preference between two valid copies of one slot: the later
    /// transaction, and committed over pending (a commit interrupted between
    /// its two copies is durable once one copy says committed).
    fn rank(&self) -> Option<(u64, u8)> {
        match self {
            SlotRead::Empty => Some((0, 0)),
            SlotRead::Pending { txn } => Some((*txn, 1)),
            SlotRead::Committed(c) => Some((c.txn, 2)),
            SlotRead::Invalid => None,
        }
    }
}

/// A slot as its two copies give it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SlotPair {
    /// Copy 0 and copy 1, as read.
    pub copies: [SlotRead; 2],
}

impl SlotPair {
    /// The slot's value: the preferred valid copy; `Invalid` only when both
    /// copies fail, which a crash cannot cause (format-spec/commit.md).
    pub fn value(&self) -> SlotRead {
        let [a, b] = self.copies;
        match (a.rank(), b.rank()) {
            (None, None) => SlotRead::Invalid,
            (Some(_), None) => a,
            (None, Some(_)) => b,
            (Some(x), Some(y)) => {
                if y > x {
                    b
                } else {
                    a
                }
            }
        }
    }

    /// Copies failing their checksum.
    pub fn invalid_copies(&self) -> impl Iterator<Item = usize> + '_ {
        (0..2).filter(|&i| self.copies[i] == SlotRead::Invalid)
    }

    /// The order to rewrite the copies in: a failing copy first, so that a
    /// crash during either write leaves one valid copy.
    pub fn write_order(&self) -> [usize; 2] {
        if self.copies[1] == SlotRead::Invalid && self.copies[0] != SlotRead::Invalid {
            [1, 0]
        } else {
            [0, 1]
        }
    }
}

impl Slot {
    fn checksum(&self, slot: usize, copy: usize) -> u32 {
        let mut h = crc32fast::Hasher::new();
        h.update(&self.as_bytes()[..SLOT_LEN - 4]);
        h.update(&(slot as u32).to_le_bytes());
        h.update(&(copy as u32).to_le_bytes());
        h.finalize()
    }

    /// The bytes of copy `copy` of slot `slot` in state `state` for `commit`.
    pub fn encode(slot: usize, copy: usize, state: SlotState, commit: &Commit) -> [u8; SLOT_LEN] {
        let mut s = Slot::new_zeroed();
        if state != SlotState::Empty {
            s.txn = commit.txn.into();
            s.state = if state == SlotState::Committed && commit.listed { LISTED } else { state as u8 };
            s.meta_block = commit.meta_block.into();
            s.meta_checksum = commit.meta_checksum.into();
            s.block_count = commit.block_count.into();
            s.freelist_block = commit.freelist_block.into();
            s.freelist_checksum = commit.freelist_checksum.into();
            s.free_blocks = commit.free_blocks.into();
            s.slot_checksum = s.checksum(slot, copy).into();
        }
        let mut out = [0u8; SLOT_LEN];
        out.copy_from_slice(s.as_bytes());
        out
    }

    /// Decodes copy `copy` of slot `slot` from its bytes.
    pub fn decode(slot: usize, copy: usize, bytes: &[u8]) -> SlotRead {
        let Ok(s) = Slot::read_from_bytes(bytes) else { return SlotRead::Invalid };
        if all_zero(bytes) {
            return SlotRead::Empty;
        }
        if s.slot_checksum.get() != s.checksum(slot, copy)
            || !all_zero(&s.reserved0)
            || !all_zero(&s.reserved1)
            || s.txn.get() == 0
            || s.txn.get() > MAX_TXN
        {
            return SlotRead::Invalid;
        }
        match s.state {
            1 => SlotRead::Pending { txn: s.txn.get() },
            2 | LISTED => SlotRead::Committed(Commit {
                txn: s.txn.get(),
                meta_block: s.meta_block.get(),
                meta_checksum: s.meta_checksum.get(),
                block_count: s.block_count.get(),
                freelist_block: s.freelist_block.get(),
                freelist_checksum: s.freelist_checksum.get(),
                free_blocks: s.free_blocks.get(),
                listed: s.state == LISTED,
            }),
            _ => SlotRead::Invalid,
        }
    }
}

fn header_checksum(block0: &[u8]) -> u32 {
    let mut h = crc32fast::Hasher::new();
    h.update(&block0[..508]);
    h.update(&block0[PREFIX_LEN..]);
    h.finalize()
}

/// A new block 0 with empty slots.
pub fn encode_block0(block_size: u32, lod_levels: u8) -> Vec<u8> {
    let mut b = vec![0u8; block_size as usize];
    let mut f = FixedHeader::new_zeroed();
    f.magic = MAGIC;
    f.format_version = FORMAT_VERSION.into();
    f.block_size = block_size.into();
    f.lod_levels = lod_levels;
    b[..512].copy_from_slice(f.as_bytes());
    let sum = header_checksum(&b);
    b[508..512].copy_from_slice(&sum.to_le_bytes());
    b
}

/// Block size and number of levels from the first [`PREFIX_LEN`] bytes.
pub fn decode_prefix(prefix: &[u8]) -> Result<(u32, u8), StorageError> {
    let (f, _) = FixedHeader::read_from_prefix(prefix).map_err(|_| StorageError::NotMktree)?;
    if f.magic != MAGIC {
        return Err(StorageError::NotMktree);
    }
    if f.format_version.get() != FORMAT_VERSION {
        return Err(StorageError::UnsupportedVersion {
            found: f.format_version.get(),
            supported: FORMAT_VERSION,
        });
    }
    let block_size = validate_block_size(f.block_size.get().into())?;
    let lod_levels = validate_lod_levels(f.lod_levels.into())?;
    Ok((block_size, lod_levels))
}

/// Both copies of both slots from the first [`PREFIX_LEN`] bytes of block 0.
pub fn decode_slots(prefix: &[u8]) -> [SlotPair; 2] {
    [0, 1].map(|slot| SlotPair {
        copies: [0, 1].map(|copy| {
            let at = slot_offset(slot, copy);
            prefix.get(at..at + SLOT_LEN).map_or(SlotRead::Invalid, |b| Slot::decode(slot, copy, b))
        }),
    })
}

/// Writes both copies of slot `slot` into `block0` (for tools that forge or
/// build a file image in memory; the writer writes them one at a time).
pub fn put_slot(block0: &mut [u8], slot: usize, state: SlotState, commit: &Commit) {
    for copy in 0..2 {
        let at = slot_offset(slot, copy);
        block0[at..at + SLOT_LEN].copy_from_slice(&Slot::encode(slot, copy, state, commit));
    }
}

/// Checks the whole of block 0's fixed region and tail, then reads both slots.
pub fn decode_block0(block0: &[u8]) -> Result<(u32, u8, [SlotPair; 2]), StorageError> {
    let (block_size, lod_levels) = decode_prefix(block0)?;
    if block0.len() != block_size as usize {
        return Err(StorageError::corrupt(0, "block_size", "block 0 is shorter than a block"));
    }
    let stored = u32::from_le_bytes([block0[508], block0[509], block0[510], block0[511]]);
    if stored != header_checksum(block0) {
        return Err(StorageError::corrupt(
            0,
            "header_checksum",
            "the fixed header or block 0's tail is damaged",
        ));
    }
    if !all_zero(&block0[17..508]) || !all_zero(&block0[PREFIX_LEN..]) {
        return Err(StorageError::corrupt(0, "reserved", "reserved bytes of block 0 are not zero"));
    }
    Ok((block_size, lod_levels, decode_slots(block0)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slots_round_trip_and_know_their_position() {
        let c = Commit { txn: 9, meta_block: 4, meta_checksum: 77, block_count: 12, ..Commit::default() };
        let bytes = Slot::encode(1, 0, SlotState::Committed, &c);
        assert_eq!(Slot::decode(1, 0, &bytes), SlotRead::Committed(c));
        assert_eq!(
            Slot::decode(0, 0, &bytes),
            SlotRead::Invalid,
            "a slot copied to the other slot is caught"
        );
        assert_eq!(Slot::decode(1, 1, &bytes), SlotRead::Invalid, "a copy moved to the other copy is caught");
        assert_eq!(Slot::decode(0, 0, &[0u8; SLOT_LEN]), SlotRead::Empty);
    }

    #[test]
    fn a_transaction_id_past_the_largest_is_invalid() {
        let c = |txn| Commit { txn, meta_block: 4, block_count: 12, ..Commit::default() };
        let at = |txn| Slot::decode(0, 1, &Slot::encode(0, 1, SlotState::Committed, &c(txn)));
        assert_eq!(at(MAX_TXN), SlotRead::Committed(c(MAX_TXN)));
        assert_eq!(at(MAX_TXN + 1), SlotRead::Invalid);
        assert_eq!(at(u64::MAX), SlotRead::Invalid, "a writer's next id would wrap to 0");
    }

    #[test]
    fn a_slot_is_its_preferred_valid_copy() {
        let c = Commit { txn: 9, meta_block: 4, block_count: 12, ..Commit::default() };
        let pair = |a, b| SlotPair { copies: [a, b] };
        let (done, pending) = (SlotRead::Committed(c), SlotRead::Pending { txn: 9 });
        assert_eq!(pair(SlotRead::Invalid, done).value(), done, "one damaged copy loses nothing");
        assert_eq!(pair(done, pending).value(), done, "a commit torn between its copies holds");
        assert_eq!(pair(pending, SlotRead::Invalid).value(), pending);
        assert_eq!(pair(SlotRead::Invalid, SlotRead::Invalid).value(), SlotRead::Invalid);
        assert_eq!(
            pair(done, SlotRead::Invalid).write_order(),
            [1, 0],
            "the failing copy is rewritten first"
        );
        assert_eq!(pair(SlotRead::Invalid, done).write_order(), [0, 1]);
    }

    #[test]
    fn block0_round_trips_and_rejects_other_versions() {
        let b = encode_block0(4096, 4);
        let (bs, m, slots) = decode_block0(&b).unwrap();
        let empty = SlotPair { copies: [SlotRead::Empty; 2] };
        assert_eq!((bs, m, slots), (4096, 4, [empty, empty]));
        let mut v1 = b.clone();
        v1[8] = 1;
        assert!(matches!(decode_prefix(&v1), Err(StorageError::UnsupportedVersion { found: 1, .. })));
        let mut bad = b;
        bad[2000] = 1;
        assert!(decode_block0(&bad).is_err());
    }
}
