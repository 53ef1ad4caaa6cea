//! The 16-byte block frame and the block checksum (format-spec/blocks.md).

use zerocopy::byteorder::little_endian::{U32, U64};
use zerocopy::{FromBytes, Immutable, IntoBytes, KnownLayout, Unaligned};

use crate::store::StorageError;

/// Bytes taken by the frame at the start of every block but block 0.
pub const FRAME_LEN: usize = 16;

/// The frame (format-spec/blocks.md).
#[derive(Debug, Clone, Copy, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
#[repr(C)]
pub struct Frame {
    /// CRC-32 over the block id (a u32, not stored), then bytes 4 .. `block_size` of the block.
    pub checksum: U32,
    /// The block's type, a [`BlockType`] code.
    pub block_type: u8,
    /// Zero.
    pub reserved: [u8; 3],
    /// The id of the transaction that wrote the block.
    pub txn: U64,
}
const _: () = assert!(size_of::<Frame>() == FRAME_LEN);

/// Block types (format-spec/blocks.md).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum BlockType {
    /// The meta block: tree root, counts, build parameters, LOD table (format-spec/meta.md).
    Meta = 1,
    /// Node records (format-spec/node.md).
    Node = 2,
    /// A stretch of the stream of object records (format-spec/geometry.md).
    Geometry = 3,
    /// Ranges of free blocks (format-spec/freelist.md).
    FreeList = 5,
    /// A free block scrubbed by recovery: payload all zero (format-spec/commit.md).
    Free = 7,
    /// Keys in order, with their objects' ids, names, payloads and boxes (format-spec/keys.md).
    KeyLeaf = 8,
    /// The key index's inner blocks (format-spec/keys.md).
    KeyBranch = 9,
    /// The group bounds of one node block's records (format-spec/group.md).
    Group = 10,
}

impl BlockType {
    /// The type with this code, if any.
    pub fn from_code(code: u8) -> Option<BlockType> {
        use BlockType::*;
        [Meta, Node, Geometry, FreeList, Free, KeyLeaf, KeyBranch, Group]
            .into_iter()
            .find(|t| *t as u8 == code)
    }

    /// Lower-case name for reports.
    pub fn name(self) -> &'static str {
        match self {
            BlockType::Meta => "meta",
            BlockType::Node => "node",
            BlockType::Geometry => "geometry",
            BlockType::FreeList => "free-list",
            BlockType::Free => "free",
            BlockType::KeyLeaf => "key-leaf",
            BlockType::KeyBranch => "key-branch",
            BlockType::Group => "group-bound",
        }
    }
}

/// The checksum of block `id` with contents `block`: CRC-32 over the id, then
/// every byte after the checksum field.
pub fn block_checksum(id: u32, block: &[u8]) -> u32 {
    let mut h = crc32fast::Hasher::new();
    h.update(&id.to_le_bytes());
    h.update(&block[4..]);
    h.finalize()
}

/// Writes the frame of block `id` and its checksum; the payload must already be in place.
pub fn seal(id: u32, block: &mut [u8], block_type: BlockType, txn: u64) -> u32 {
    let frame = Frame { checksum: 0.into(), block_type: block_type as u8, reserved: [0; 3], txn: txn.into() };
    block[..FRAME_LEN].copy_from_slice(frame.as_bytes());
    let sum = block_checksum(id, block);
    block[..4].copy_from_slice(&sum.to_le_bytes());
    sum
}

/// The frame of a block whose checksum matches, or a corruption error naming the block.
pub fn open(id: u32, block: &[u8]) -> Result<(Frame, BlockType), StorageError> {
    let (frame, _) = Frame::read_from_prefix(block)
        .map_err(|_| StorageError::corrupt(id, "frame", "block shorter than its frame"))?;
    let sum = block_checksum(id, block);
    if frame.checksum.get() != sum {
        return Err(StorageError::corrupt(
            id,
            "checksum",
            format!("stored {:#010x}, computed {sum:#010x}", frame.checksum.get()),
        ));
    }
    let block_type = BlockType::from_code(frame.block_type).ok_or_else(|| {
        StorageError::corrupt(id, "type", format!("unknown block type {}", frame.block_type))
    })?;
    if frame.reserved != [0; 3] {
        return Err(StorageError::corrupt(id, "reserved", "frame reserved bytes are not zero"));
    }
    Ok((frame, block_type))
}

/// Verifies block `id`: checksum, the expected type, and (when a parent holds
/// it) the expected checksum, which catches a stale block left by a lost write.
pub fn verify(
    id: u32,
    block: &[u8],
    expected: BlockType,
    parent_checksum: Option<u32>,
) -> Result<Frame, StorageError> {
    let (frame, block_type) = open(id, block)?;
    if block_type != expected {
        return Err(StorageError::corrupt(
            id,
            "type",
            format!("expected a {} block, found a {} block", expected.name(), block_type.name()),
        ));
    }
    if let Some(want) = parent_checksum
        && want != frame.checksum.get()
    {
        return Err(StorageError::corrupt(
            id,
            "checksum",
            format!("the parent expects {want:#010x}, the block carries {:#010x}", frame.checksum.get()),
        ));
    }
    Ok(frame)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_sealed_block_verifies_and_a_moved_one_does_not() {
        let mut b = vec![0u8; 1024];
        b[100] = 7;
        let sum = seal(5, &mut b, BlockType::Node, 3);
        assert!(verify(5, &b, BlockType::Node, Some(sum)).is_ok());
        assert!(verify(6, &b, BlockType::Node, None).is_err(), "checksum covers the block id");
        assert!(verify(5, &b, BlockType::Geometry, None).is_err(), "type is checked");
        b[1000] ^= 1;
        assert!(verify(5, &b, BlockType::Node, None).is_err(), "payload is covered");
    }
}
