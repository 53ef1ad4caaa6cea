//! The pager: every block read goes through here, is verified (checksum over
//! id and type, the parent's checksum when it holds one), and is counted
//! where it happens, so the counts a query reports cannot drift from the reads
//! the device sees.

use std::collections::{BTreeMap, HashMap};
use std::sync::Arc;

use super::format::frame::{self, BlockType};
use super::{BlockDevice, StorageError};

/// Block reads of one operation, by kind. Cache hits are not reads.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct ReadStats {
    /// Node blocks read from the device.
    pub node: u64,
    /// Geometry and continuation blocks read from the device.
    pub geometry: u64,
    /// Level-of-detail blocks (levels below M) read from the device.
    pub lod: u64,
    /// Other blocks (meta, names, free list) read from the device.
    pub other: u64,
    /// Blocks found in the buffer pool instead of read.
    pub cache_hits: u64,
}

impl ReadStats {
    /// All device reads.
    pub fn total(&self) -> u64 {
        self.node + self.geometry + self.lod + self.other
    }

    fn count(&mut self, t: BlockType) {
        match t {
            BlockType::Node => self.node += 1,
            BlockType::Geometry | BlockType::Continuation => self.geometry += 1,
            BlockType::Lod | BlockType::LodRun | BlockType::LodContinuation => self.lod += 1,
            _ => self.other += 1,
        }
    }
}

impl std::ops::AddAssign for ReadStats {
    fn add_assign(&mut self, o: ReadStats) {
        self.node += o.node;
        self.geometry += o.geometry;
        self.lod += o.lod;
        self.other += o.other;
        self.cache_hits += o.cache_hits;
    }
}

/// A least-recently-used pool of verified blocks, owned by one reader (a
/// snapshot), so a cached block can never be stale.
#[derive(Debug)]
pub struct BlockCache {
    capacity: usize,
    clock: u64,
    blocks: HashMap<u32, (Arc<[u8]>, u64)>,
    by_age: BTreeMap<u64, u32>,
}

impl BlockCache {
    /// A pool of at most `capacity` blocks (0 disables it).
    pub fn new(capacity: usize) -> BlockCache {
        BlockCache { capacity, clock: 0, blocks: HashMap::new(), by_age: BTreeMap::new() }
    }

    /// Blocks held.
    pub fn len(&self) -> usize {
        self.blocks.len()
    }

    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.blocks.is_empty()
    }

    fn get(&mut self, id: u32) -> Option<Arc<[u8]>> {
        let (b, age) = self.blocks.get_mut(&id)?;
        self.by_age.remove(age);
        self.clock += 1;
        *age = self.clock;
        self.by_age.insert(self.clock, id);
        Some(b.clone())
    }

    fn put(&mut self, id: u32, block: Arc<[u8]>) {
        if self.capacity == 0 {
            return;
        }
        while self.blocks.len() >= self.capacity {
            let Some((_, old)) = self.by_age.pop_first() else { break };
            self.blocks.remove(&old);
        }
        self.clock += 1;
        self.by_age.insert(self.clock, id);
        self.blocks.insert(id, (block, self.clock));
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

    /// Reads block `id` raw, without verifying it (for `check` and recovery).
    pub fn read_raw(&self, id: u32) -> Result<Vec<u8>, StorageError> {
        let mut buf = vec![0u8; self.block_size as usize];
        self.device.read_at(self.offset(id), &mut buf).map_err(|e| match e.kind() {
            std::io::ErrorKind::UnexpectedEof => {
                StorageError::Truncated { detail: format!("block {id} lies past the end of the file") }
            }
            _ => StorageError::Io(e),
        })?;
        Ok(buf)
    }

    /// Reads and verifies block `id` of type `expected`, counting it in `stats`
    /// (or as a hit when `cache` holds it).
    pub fn read(
        &self,
        id: u32,
        expected: BlockType,
        parent_checksum: Option<u32>,
        stats: &mut ReadStats,
        cache: Option<&mut BlockCache>,
    ) -> Result<Arc<[u8]>, StorageError> {
        if id == 0 {
            return Err(StorageError::corrupt(
                0,
                "reference",
                format!("a {} reference points to block 0", expected.name()),
            ));
        }
        if let Some(c) = cache {
            if let Some(b) = c.get(id) {
                stats.cache_hits += 1;
                // Verified when it was read; a damaged file may still name it as another type.
                if b.get(frame::TYPE_OFFSET) != Some(&(expected as u8)) {
                    return Err(StorageError::corrupt(
                        id,
                        "type",
                        format!("a {} reference names a block of another type", expected.name()),
                    ));
                }
                return Ok(b);
            }
            let b = self.read_uncached(id, expected, parent_checksum, stats)?;
            c.put(id, b.clone());
            return Ok(b);
        }
        self.read_uncached(id, expected, parent_checksum, stats)
    }

    fn read_uncached(
        &self,
        id: u32,
        expected: BlockType,
        parent_checksum: Option<u32>,
        stats: &mut ReadStats,
    ) -> Result<Arc<[u8]>, StorageError> {
        let buf = self.read_raw(id)?;
        stats.count(expected);
        frame::verify(id, &buf, expected, parent_checksum)?;
        Ok(buf.into())
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

    #[test]
    fn lru_evicts_the_least_recently_used() {
        let mut c = BlockCache::new(2);
        let b: Arc<[u8]> = vec![0u8; 4].into();
        c.put(1, b.clone());
        c.put(2, b.clone());
        assert!(c.get(1).is_some());
        c.put(3, b);
        assert!(c.get(2).is_none(), "2 was the least recently used");
        assert!(c.get(1).is_some() && c.get(3).is_some());
    }

    #[test]
    fn a_pooled_block_is_refused_under_another_type() {
        let pager = Pager::new(Arc::new(crate::store::device::MemDevice::new()), 1024, 2);
        pager.write(1, &mut vec![0u8; 1024], BlockType::Node, 1).unwrap();
        let (mut cache, mut stats) = (BlockCache::new(8), ReadStats::default());
        pager.read(1, BlockType::Node, None, &mut stats, Some(&mut cache)).unwrap();
        assert!(pager.read(1, BlockType::Node, None, &mut stats, Some(&mut cache)).is_ok());
        let err = pager.read(1, BlockType::Lod, None, &mut stats, Some(&mut cache)).unwrap_err();
        assert!(err.is_corruption(), "{err}");
        assert_eq!((stats.node, stats.cache_hits), (1, 2));
    }
}
