//! Runs: a byte stream in consecutive blocks, a first block with a run header
//! then continuation blocks, each holding the next block's checksum
//! (format-spec/runs.md). The names use it.

use zerocopy::byteorder::little_endian::{U32, U64};
use zerocopy::{FromBytes, Immutable, IntoBytes, KnownLayout, Unaligned};

use super::all_zero;
use super::frame::FRAME_LEN;
use crate::store::StorageError;

#[derive(Debug, Clone, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
#[repr(C)]
pub(crate) struct RunHeader {
    pub(crate) run_blocks: U32,
    pub(crate) record_count: U32,
    pub(crate) data_bytes: U64,
    pub(crate) next_checksum: U32,
    pub(crate) reserved: [u8; 4],
}

/// Offset of the stream in the first block.
pub const FIRST_DATA: usize = FRAME_LEN + size_of::<RunHeader>();
/// Offset of the stream in a continuation block, after the next block's
/// checksum and four reserved bytes.
const NEXT_DATA: usize = FRAME_LEN + 8;

/// Where a run block holds the checksum of the block after it.
fn next_at(index: usize) -> usize {
    if index == 0 { FRAME_LEN + 16 } else { FRAME_LEN }
}

/// The checksum run block `index` holds for the block after it (0 after the last).
pub fn next_checksum(index: usize, block: &[u8]) -> u32 {
    let at = next_at(index);
    u32::from_le_bytes([block[at], block[at + 1], block[at + 2], block[at + 3]])
}

/// Sets the checksum run block `index` holds for the block after it; the
/// writer writes a run last block first.
pub fn set_next_checksum(index: usize, block: &mut [u8], checksum: u32) {
    let at = next_at(index);
    block[at..at + 4].copy_from_slice(&checksum.to_le_bytes());
}

/// Stream bytes the first block of a run holds.
pub fn first_capacity(block_size: u32) -> u64 {
    block_size as u64 - FIRST_DATA as u64
}

/// Blocks a stream of `data_bytes` takes.
pub fn blocks_for(data_bytes: u64, block_size: u32) -> u64 {
    let rest = data_bytes.saturating_sub(first_capacity(block_size));
    1 + rest.div_ceil(block_size as u64 - NEXT_DATA as u64)
}

/// The payloads of the run's blocks (frames left for `seal`).
pub fn encode(stream: &[u8], record_count: u32, block_size: u32) -> Vec<Vec<u8>> {
    let n = blocks_for(stream.len() as u64, block_size) as usize;
    let bs = block_size as usize;
    let mut blocks = Vec::with_capacity(n);
    let mut first = vec![0u8; bs];
    let h = RunHeader {
        run_blocks: (n as u32).into(),
        record_count: record_count.into(),
        data_bytes: (stream.len() as u64).into(),
        next_checksum: 0.into(),
        reserved: [0; 4],
    };
    first[FRAME_LEN..FIRST_DATA].copy_from_slice(h.as_bytes());
    let take = stream.len().min(bs - FIRST_DATA);
    first[FIRST_DATA..FIRST_DATA + take].copy_from_slice(&stream[..take]);
    blocks.push(first);
    for chunk in stream[take..].chunks(bs - NEXT_DATA) {
        let mut b = vec![0u8; bs];
        b[NEXT_DATA..NEXT_DATA + chunk.len()].copy_from_slice(chunk);
        blocks.push(b);
    }
    blocks
}

/// The run header of a first block: (run blocks, record count, data bytes).
pub fn header(id: u32, first: &[u8]) -> Result<(u32, u32, u64), StorageError> {
    let h = RunHeader::read_from_bytes(&first[FRAME_LEN..FIRST_DATA])
        .map_err(|_| StorageError::corrupt(id, "run header", "too small"))?;
    let (blocks, records, bytes) = (h.run_blocks.get(), h.record_count.get(), h.data_bytes.get());
    if h.reserved != [0; 4] {
        return Err(StorageError::corrupt(id, "reserved", "run header reserved bytes are not zero"));
    }
    if u64::from(blocks) != blocks_for(bytes, first.len() as u32) {
        return Err(StorageError::corrupt(
            id,
            "run_blocks",
            format!("{blocks} blocks cannot hold exactly {bytes} bytes"),
        ));
    }
    Ok((blocks, records, bytes))
}

/// Reassembles the stream from the run's blocks (first block first, each
/// already verified against the checksum the block before it holds), as u32
/// words so that arrays cast from it are aligned.
pub fn assemble(first_id: u32, blocks: &[&[u8]]) -> Result<(u32, Vec<u32>, usize), StorageError> {
    let (n, records, bytes) = header(first_id, blocks[0])?;
    if n as usize != blocks.len() {
        return Err(StorageError::corrupt(first_id, "run_blocks", "run length changed while reading"));
    }
    let bytes = bytes as usize;
    let mut words = vec![0u32; bytes.div_ceil(4)];
    let out: &mut [u8] = bytemuck::cast_slice_mut(&mut words);
    let mut at = 0;
    for (i, b) in blocks.iter().enumerate() {
        let start = if i == 0 { FIRST_DATA } else { NEXT_DATA };
        let take = (bytes - at).min(b.len() - start);
        out[at..at + take].copy_from_slice(&b[start..start + take]);
        if i > 0 && !all_zero(&b[FRAME_LEN + 4..NEXT_DATA]) {
            return Err(StorageError::corrupt(
                first_id + i as u32,
                "reserved",
                "reserved bytes are not zero",
            ));
        }
        if i + 1 == blocks.len() && next_checksum(i, b) != 0 {
            return Err(StorageError::corrupt(
                first_id + i as u32,
                "next_checksum",
                "the run's last block names a next block",
            ));
        }
        if !all_zero(&b[start + take..]) {
            return Err(StorageError::corrupt(
                first_id + i as u32,
                "padding",
                "bytes after the stream are not zero",
            ));
        }
        at += take;
    }
    Ok((records, words, bytes))
}
