//! Verified blocks and the shared read cache. A block enters memory once:
//! its checksum and type are verified and, for a node block, every record
//! is validated, so readers walk it in place afterwards. Readers on any
//! thread share one least-recently-used pool ([`BlockCache`], redb's idea of
//! a shared read cache); a writer drops the blocks it reuses, and every hit
//! is checked against the checksum its reference holds, so a hit is never
//! stale.

use std::collections::BTreeMap;

use rustc_hash::FxHashMap;
use std::sync::{Arc, Mutex};

/// A verified block in memory.
#[derive(Debug)]
pub struct Block {
    pub(crate) id: u32,
    pub(crate) checksum: u32,
    pub(crate) bytes: Box<[u8]>,
    /// Node blocks: the offsets of their records; key blocks: of their
    /// entries (format-spec/keys.md). Validated when the block was read.
    pub(crate) records: Vec<u32>,
    /// Group blocks: their entries (record, level, blob bytes), validated.
    pub(crate) groups: Vec<(u32, u8, std::ops::Range<usize>)>,
}

impl Block {
    /// The block's bytes, frame included.
    pub fn bytes(&self) -> &[u8] {
        &self.bytes
    }

    /// The block's id.
    pub fn id(&self) -> u32 {
        self.id
    }
}

#[derive(Debug, Default)]
struct Lru {
    clock: u64,
    blocks: FxHashMap<u32, (Arc<Block>, u64)>,
    by_age: BTreeMap<u64, u32>,
}

/// Blocks the shared read cache holds by default (16 MiB of 16 KiB blocks).
pub const DEFAULT_CACHE_BLOCKS: usize = 1024;

/// A least-recently-used pool of verified blocks, shared by readers
/// (`Arc<BlockCache>` or `&BlockCache` from any thread).
#[derive(Debug)]
pub struct BlockCache {
    capacity: usize,
    lru: Mutex<Lru>,
}

impl BlockCache {
    /// A pool of at most `capacity` blocks (0 keeps none).
    pub fn new(capacity: usize) -> BlockCache {
        BlockCache { capacity, lru: Mutex::new(Lru::default()) }
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Lru> {
        self.lru.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Blocks held.
    pub fn len(&self) -> usize {
        self.lock().blocks.len()
    }

    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The most blocks it holds.
    pub fn capacity(&self) -> usize {
        self.capacity
    }

    /// True when block `id` is held with checksum `checksum`; unlike
    /// [`get`](Self::get), it leaves the order of eviction as it was.
    pub(crate) fn holds(&self, id: u32, checksum: u32) -> bool {
        self.lock().blocks.get(&id).is_some_and(|(b, _)| b.checksum == checksum)
    }

    /// Block `id` if held with checksum `checksum`.
    pub(crate) fn get(&self, id: u32, checksum: u32) -> Option<Arc<Block>> {
        let mut guard = self.lock();
        let lru = &mut *guard;
        let (b, age) = lru.blocks.get_mut(&id)?;
        if b.checksum != checksum {
            return None;
        }
        lru.by_age.remove(age);
        lru.clock += 1;
        *age = lru.clock;
        let b = b.clone();
        lru.by_age.insert(lru.clock, id);
        Some(b)
    }

    pub(crate) fn put(&self, block: Arc<Block>) {
        if self.capacity == 0 {
            return;
        }
        let mut lru = self.lock();
        if let Some((_, age)) = lru.blocks.remove(&block.id) {
            lru.by_age.remove(&age);
        }
        while lru.blocks.len() >= self.capacity {
            let Some((_, old)) = lru.by_age.pop_first() else { break };
            lru.blocks.remove(&old);
        }
        lru.clock += 1;
        let clock = lru.clock;
        lru.by_age.insert(clock, block.id);
        lru.blocks.insert(block.id, (block, clock));
    }

    /// Drops blocks `first .. first + count` (a writer is about to reuse them).
    pub(crate) fn forget(&self, first: u32, count: u32) {
        let mut lru = self.lock();
        if lru.blocks.is_empty() {
            return;
        }
        for id in first..first.saturating_add(count) {
            if let Some((_, age)) = lru.blocks.remove(&id) {
                lru.by_age.remove(&age);
            }
        }
    }

    /// Drops every block.
    pub fn clear(&self) {
        *self.lock() = Lru::default();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn block(id: u32, checksum: u32) -> Arc<Block> {
        Arc::new(Block { id, checksum, bytes: vec![0; 4].into(), records: Vec::new(), groups: Vec::new() })
    }

    #[test]
    fn lru_evicts_the_least_recently_used() {
        let c = BlockCache::new(2);
        c.put(block(1, 0));
        c.put(block(2, 0));
        assert!(c.get(1, 0).is_some());
        c.put(block(3, 0));
        assert!(c.get(2, 0).is_none(), "2 was the least recently used");
        assert!(c.get(1, 0).is_some() && c.get(3, 0).is_some());
    }

    #[test]
    fn a_hit_needs_the_checksum_its_reference_holds() {
        let c = BlockCache::new(4);
        c.put(block(1, 7));
        assert!(c.get(1, 8).is_none(), "a reused block id with other contents");
        c.forget(0, 4);
        assert!(c.get(1, 7).is_none());
    }

    #[test]
    fn the_pool_is_shared_across_threads() {
        let c = Arc::new(BlockCache::new(64));
        std::thread::scope(|s| {
            for t in 0..4 {
                let c = c.clone();
                s.spawn(move || {
                    for i in 0..16 {
                        c.put(block(t * 16 + i, 0));
                    }
                });
            }
        });
        assert_eq!(c.len(), 64);
    }
}
