//! Level-of-detail blocks (type 8, format-spec/lod.md): small blobs of
//! levels below M, several to a block, so that a level that is a few hundred
//! bytes per node does not cost a block per node.

use super::all_zero;
use super::frame::FRAME_LEN;
use crate::store::StorageError;

/// Offset of the first blob in a LOD block.
pub const BLOBS_START: usize = FRAME_LEN + 8;

/// Bytes a blob of `len` bytes takes in a block: its length word, padded to 4.
pub fn footprint(len: usize) -> usize {
    4 + len.next_multiple_of(4)
}

/// The largest blob a LOD block of `block_size` bytes holds.
pub fn max_blob(block_size: u32) -> usize {
    block_size as usize - BLOBS_START - 4
}

/// Fills one LOD block with blobs, in order.
#[derive(Debug)]
pub struct LodBlockWriter {
    block: Vec<u8>,
    used: usize,
    count: u32,
}

impl LodBlockWriter {
    /// An empty block of `block_size` bytes.
    pub fn new(block_size: u32) -> LodBlockWriter {
        LodBlockWriter { block: vec![0u8; block_size as usize], used: BLOBS_START, count: 0 }
    }

    /// True when no blob was added.
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// True when a blob of `len` bytes still fits.
    pub fn fits(&self, len: usize) -> bool {
        self.used + footprint(len) <= self.block.len()
    }

    /// Appends `blob` (which must fit) and returns its offset from the block's start.
    pub fn push(&mut self, blob: &[u8]) -> u32 {
        debug_assert!(self.fits(blob.len()));
        let at = self.used;
        self.block[at..at + 4].copy_from_slice(&(blob.len() as u32).to_le_bytes());
        self.block[at + 4..at + 4 + blob.len()].copy_from_slice(blob);
        self.used += footprint(blob.len());
        self.count += 1;
        at as u32
    }

    /// The block, frame left for the pager to seal.
    pub fn finish(mut self) -> Vec<u8> {
        self.block[FRAME_LEN..FRAME_LEN + 4].copy_from_slice(&self.count.to_le_bytes());
        self.block[FRAME_LEN + 4..BLOBS_START].copy_from_slice(&(self.used as u32).to_le_bytes());
        self.block
    }
}

fn word(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

/// Checks LOD block `id`'s header and returns the end of its used bytes.
pub fn check(id: u32, block: &[u8]) -> Result<usize, StorageError> {
    let bad = |field, detail: String| StorageError::corrupt(id, field, detail);
    if block.len() < BLOBS_START {
        return Err(bad("lod block", "too small".into()));
    }
    let (count, used) = (word(block, FRAME_LEN), word(block, FRAME_LEN + 4) as usize);
    if count == 0 || used < BLOBS_START + 4 || used > block.len() || !used.is_multiple_of(4) {
        return Err(bad("used_bytes", format!("{count} blobs in {used} bytes")));
    }
    if !all_zero(&block[used..]) {
        return Err(bad("reserved", "bytes after the last blob are not zero".into()));
    }
    Ok(used)
}

/// The blob at `offset` of LOD block `id`.
pub fn blob_at(id: u32, block: &[u8], offset: u32) -> Result<&[u8], StorageError> {
    let used = check(id, block)?;
    let at = offset as usize;
    if at < BLOBS_START || !at.is_multiple_of(4) || at + 4 > used {
        return Err(StorageError::corrupt(id, "lod offset", format!("{offset} is not a blob")));
    }
    let len = word(block, at) as usize;
    if at + footprint(len) > used {
        return Err(StorageError::corrupt(id, "blob length", format!("{len} bytes at {offset} overrun")));
    }
    Ok(&block[at + 4..at + 4 + len])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blobs_round_trip_and_bad_offsets_are_caught() {
        let mut w = LodBlockWriter::new(1024);
        let a = w.push(&[1, 2, 3]);
        let b = w.push(&[9; 8]);
        assert!(w.fits(max_blob(1024) - 40) && !w.fits(max_blob(1024)));
        let block = w.finish();
        assert_eq!(blob_at(5, &block, a).unwrap(), &[1, 2, 3]);
        assert_eq!(blob_at(5, &block, b).unwrap(), &[9; 8]);
        for off in [0, a + 1, b + 12, 2000] {
            assert!(blob_at(5, &block, off).is_err(), "offset {off}");
        }
        let mut torn = block.clone();
        torn[FRAME_LEN + 5] = 8; // used bytes past the block's end
        assert!(check(5, &torn).is_err());
        let mut tail = block;
        tail[1000] = 1;
        assert!(check(5, &tail).is_err());
    }

    #[test]
    fn a_block_holds_one_blob_of_max_size() {
        let mut w = LodBlockWriter::new(1024);
        assert!(w.fits(max_blob(1024)));
        let at = w.push(&vec![7; max_blob(1024)]);
        let block = w.finish();
        assert_eq!(blob_at(1, &block, at).unwrap().len(), max_blob(1024));
    }
}
