//! The pager: every block read goes through here, is verified (checksum over
//! id and type, the parent's checksum when it holds one), and is counted
//! where it happens, so the counts a query reports cannot drift from the reads
//! the device sees.

use std::sync::Arc;

use super::format::frame::{self, BlockType};
use super::{BlockDevice, StorageError};

/// Block reads of one operation, by kind. Cache hits are not reads.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct ReadStats {
    /// Node blocks read from the device.
    pub node: u64,
    /// Geometry blocks read from the device.
    pub geometry: u64,
    /// Key index blocks read from the device.
    pub keys: u64,
    /// Group-bound blocks (b(S_n,k), format-spec/group.md) read from the device.
    pub group: u64,
    /// Other blocks (meta, names, free list) read from the device.
    pub other: u64,
    /// Blocks found in a cache instead of read.
    pub cache_hits: u64,
}

impl ReadStats {
    /// All device reads.
    pub fn total(&self) -> u64 {
        self.node + self.geometry + self.keys + self.group + self.other
    }

    fn count(&mut self, t: BlockType) {
        match t {
            BlockType::Node => self.node += 1,
            BlockType::Geometry => self.geometry += 1,
            BlockType::KeyLeaf | BlockType::KeyBranch => self.keys += 1,
            BlockType::Group => self.group += 1,
            _ => self.other += 1,
        }
    }
}

impl std::ops::AddAssign for ReadStats {
    fn add_assign(&mut self, o: ReadStats) {
        self.node += o.node;
        self.geometry += o.geometry;
        self.keys += o.keys;
        self.group += o.group;
        self.other += o.other;
        self.cache_hits += o.cache_hits;
    }
}

/// The reads since `o` was taken (counts only grow).
impl std::ops::Sub for ReadStats {
    type Output = ReadStats;
    fn sub(self, o: ReadStats) -> ReadStats {
        ReadStats {
            node: self.node - o.node,
            geometry: self.geometry - o.geometry,
            keys: self.keys - o.keys,
            group: self.group - o.group,
            other: self.other - o.other,
            cache_hits: self.cache_hits - o.cache_hits,
        }
    }
}

/// Reads and writes whole blocks of one file.
#[derive(Clone)]
pub struct Pager {
    device: Arc<dyn BlockDevice>,
    block_size: u32,
    lod_levels: u8,
}

impl std::fmt::Debug for Pager {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Pager")
            .field("block_size", &self.block_size)
            .field("lod_levels", &self.lod_levels)
            .finish()
    }
}

impl Pager {
    /// A pager over `device` with the file's block size and levels.
    pub fn new(device: Arc<dyn BlockDevice>, block_size: u32, lod_levels: u8) -> Pager {
        Pager { device, block_size, lod_levels }
    }

    /// Bytes per block.
    pub fn block_size(&self) -> u32 {
        self.block_size
    }

    /// M, the file's number of levels of detail.
    pub fn lod_levels(&self) -> u8 {
        self.lod_levels
    }

    /// The device.
    pub fn device(&self) -> &Arc<dyn BlockDevice> {
        &self.device
    }

    fn offset(&self, id: u32) -> u64 {
        u64::from(id) * u64::from(self.block_size)
    }

    /// Tells the device that blocks `ids` will be read soon (a device over a
    /// network fetches them together); nothing is read or counted here.
    /// True when the device holds them all now.
    pub fn fetch_ahead(&self, ids: &[u32]) -> bool {
        let bs = u64::from(self.block_size);
        let spans: Vec<std::ops::Range<u64>> =
            ids.iter().map(|&id| u64::from(id) * bs..(u64::from(id) + 1) * bs).collect();
        self.device.fetch_ahead(&spans)
    }

    /// Reads block `id` raw, without verifying it (for `check` and recovery).
    pub fn read_raw(&self, id: u32) -> Result<Vec<u8>, StorageError> {
        let mut buf = vec![0u8; self.block_size as usize];
        self.device.read_at(self.offset(id), &mut buf).map_err(|e| match e.kind() {
            std::io::ErrorKind::UnexpectedEof => {
                StorageError::Truncated { detail: format!("block {id} lies past the end of the file") }
            }
            _ => StorageError::from(e),
        })?;
        Ok(buf)
    }

    /// Reads and verifies block `id` of type `expected` (and the checksum its
    /// parent holds, when given), counting the read in `stats`; returns the
    /// bytes and the block's checksum.
    pub fn read(
        &self,
        id: u32,
        expected: BlockType,
        parent_checksum: Option<u32>,
        stats: &mut ReadStats,
    ) -> Result<(Box<[u8]>, u32), StorageError> {
        if id == 0 {
            return Err(StorageError::corrupt(
                0,
                "reference",
                format!("a {} reference points to block 0", expected.name()),
            ));
        }
        let buf = self.read_raw(id)?;
        stats.count(expected);
        let f = frame::verify(id, &buf, expected, parent_checksum).inspect_err(|_| {
            // A device that keeps what it fetched drops it: a damaged
            // transfer is fetched again by the next read, not kept.
            self.device.forget(self.offset(id)..self.offset(id) + u64::from(self.block_size));
        })?;
        Ok((buf.into(), f.checksum.get()))
    }

    /// Seals (frame + checksum) and writes block `id`; returns its checksum.
    pub fn write(
        &self,
        id: u32,
        block: &mut [u8],
        block_type: BlockType,
        txn: u64,
    ) -> Result<u32, StorageError> {
        let sum = frame::seal(id, block, block_type, txn);
        self.device.write_at(self.offset(id), block)?;
        Ok(sum)
    }

    /// Seals the consecutive blocks `blocks` holds, the first `first`, and
    /// writes them in one device write (a bulk load's geometry: one call,
    /// not one per block); returns their checksums in order. `blocks` is
    /// whole blocks.
    pub fn write_run(
        &self,
        first: u32,
        blocks: &mut [u8],
        block_type: BlockType,
        txn: u64,
    ) -> Result<Vec<u32>, StorageError> {
        let bs = self.block_size as usize;
        debug_assert_eq!(blocks.len() % bs, 0, "a run of whole blocks");
        let sums = (first..).zip(blocks.chunks_exact_mut(bs)).map(|(id, b)| frame::seal(id, b, block_type, txn)).collect();
        self.device.write_at(self.offset(first), blocks)?;
        Ok(sums)
    }

    /// Writes block 0 or a slot at a byte offset of block 0.
    pub fn write_header_bytes(&self, offset: u64, bytes: &[u8]) -> Result<(), StorageError> {
        Ok(self.device.write_at(offset, bytes)?)
    }

    /// The durability barrier.
    pub fn sync(&self) -> Result<(), StorageError> {
        Ok(self.device.sync()?)
    }

    /// File length in whole blocks (a trailing partial block is not counted).
    pub fn block_count(&self) -> Result<u64, StorageError> {
        Ok(self.device.len()? / u64::from(self.block_size))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::store::device::MemDevice;

    /// A run of blocks is sealed and stored as the same blocks written one
    /// by one would be, with the same checksums.
    #[test]
    fn a_run_is_written_as_its_blocks_one_by_one_are() {
        let bs = 1024u32;
        let (one, run) = (Pager::new(Arc::new(MemDevice::new()), bs, 2), Pager::new(Arc::new(MemDevice::new()), bs, 2));
        let bytes: Vec<u8> = (0..3 * bs).map(|i| (i * 7 % 251) as u8).collect();
        let mut a = bytes.clone();
        let sums: Vec<u32> = (5..)
            .zip(a.chunks_exact_mut(bs as usize))
            .map(|(id, b)| one.write(id, b, BlockType::Geometry, 9).unwrap())
            .collect();
        let mut b = bytes;
        assert_eq!(run.write_run(5, &mut b, BlockType::Geometry, 9).unwrap(), sums);
        assert_eq!(a, b);
        for id in 5..8 {
            assert_eq!(run.read_raw(id).unwrap(), one.read_raw(id).unwrap(), "block {id}");
        }
    }
}
