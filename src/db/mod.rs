//! `Database`: one `.mkt` file, opened with recovery, shared by read
//! transactions (snapshots, MVCC in a process) and one write transaction at a
//! time; locked exclusively against other processes. The protocol is
//! format-spec/commit.md.

mod check;
mod codes;
mod hierarchy;
mod lod;
mod read;
mod tree_writer;
mod write;

use std::collections::BTreeMap;
use std::fs::{File, OpenOptions};
use std::path::Path;
use std::sync::{Arc, Mutex, MutexGuard};

pub use check::{CheckReport, check};
pub use codes::{method_from_code, method_to_code};
pub use hierarchy::read_hierarchy;
pub use lod::{Level, LodInfo, Piece};
pub(crate) use read::view;
pub use read::{NodeRef, ReadTransaction, Reads, TreeInfo};
pub use write::WriteTransaction;

use crate::store::device::FileDevice;
use crate::store::format::frame::{self, BlockType};
use crate::store::format::freelist::FreeListBlock;
use crate::store::format::header::{self, Commit, PREFIX_LEN, Slot, SlotRead, SlotState};
use crate::store::format::meta::Meta;
use crate::store::format::{validate_block_size, validate_lod_levels};
use crate::store::{BlockCache, BlockDevice, Pager, ReadStats, StorageError};

/// Default block size, bytes. See the README's measurements.
pub const DEFAULT_BLOCK_SIZE: u32 = 16 * 1024;
/// Default number of levels of detail M.
pub const DEFAULT_LOD_LEVELS: u8 = 4;
/// Blocks the shared read cache holds by default (16 MiB of 16 KiB blocks).
pub const DEFAULT_CACHE_BLOCKS: usize = 1024;

/// Settings fixed when a file is created.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CreateOptions {
    /// Bytes per block: a multiple of 16 from 1,024 to 4,194,304.
    pub block_size: u32,
    /// M, the levels of detail each node record carries (1 ..= 16).
    pub lod_levels: u8,
}

impl Default for CreateOptions {
    fn default() -> CreateOptions {
        CreateOptions { block_size: DEFAULT_BLOCK_SIZE, lod_levels: DEFAULT_LOD_LEVELS }
    }
}

/// What opening the file found and repaired.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Recovery {
    /// A write transaction had been interrupted (crash or abort).
    pub interrupted: bool,
    /// Torn free blocks rewritten as free blocks.
    pub scrubbed_blocks: u64,
    /// Blocks past the committed end removed.
    pub truncated_blocks: u64,
}

/// The committed state a reader sees.
#[derive(Debug)]
pub(crate) struct Snapshot {
    pub txn: u64,
    pub meta: Option<Meta>,
    pub block_count: u32,
}

#[derive(Debug)]
struct State {
    committed: Commit,
    committed_slot: usize,
    /// Free ranges of the committed state (what its free list holds).
    free: Vec<(u32, u32)>,
    snapshot: Arc<Snapshot>,
    /// Live readers by snapshot transaction.
    readers: BTreeMap<u64, usize>,
    /// Blocks made free by commit `txn`: reusable once no reader older than `txn` lives.
    freed_at: Vec<(u64, Vec<(u32, u32)>)>,
}

pub(crate) struct Inner {
    pager: Pager,
    cache: BlockCache,
    state: Mutex<State>,
    writer: Mutex<()>,
}

/// An MKtree file.
///
/// ```
/// use mktree::db::{CreateOptions, Database};
/// use mktree::build::BuildParams;
/// use mktree::geom::Aabb;
/// use mktree::scene::generate::{GenOptions, Preset, generate_scene};
///
/// let dir = tempfile::tempdir()?;
/// let scene = generate_scene(&GenOptions { preset: Preset::Tanker1, objects: None, seed: 1 })?;
/// let db = Database::create(dir.path().join("t1.mkt"), CreateOptions::default())?;
/// let mut w = db.begin_write()?;
/// w.bulk_load(&scene, &BuildParams::default(), &|_| {})?;
/// w.commit()?;
/// let r = db.begin_read()?;
/// let hits = r.query_box(&scene.aabb())?;
/// assert_eq!(hits.objects.len(), scene.len());
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub struct Database {
    inner: Arc<Inner>,
    recovery: Recovery,
}

impl std::fmt::Debug for Database {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Database").field("pager", &self.inner.pager).finish()
    }
}

fn lock(file: &File) -> Result<(), StorageError> {
    file.try_lock().map_err(|e| match e {
        std::fs::TryLockError::WouldBlock => StorageError::Locked,
        std::fs::TryLockError::Error(e) => StorageError::Io(e),
    })
}

impl Database {
    /// Creates a new file at `path` (it must not exist) with an empty tree.
    pub fn create(path: impl AsRef<Path>, options: CreateOptions) -> Result<Database, StorageError> {
        let file = OpenOptions::new().read(true).write(true).create_new(true).open(path)?;
        lock(&file)?;
        Database::create_on(Arc::new(FileDevice::new(file)), options)
    }

    /// Opens an existing file, recovering from an interrupted transaction.
    pub fn open(path: impl AsRef<Path>) -> Result<Database, StorageError> {
        let file = OpenOptions::new().read(true).write(true).open(path)?;
        lock(&file)?;
        Database::open_on(Arc::new(FileDevice::new(file)))
    }

    /// Creates a database on an empty device.
    pub fn create_on(device: Arc<dyn BlockDevice>, options: CreateOptions) -> Result<Database, StorageError> {
        let block_size = validate_block_size(options.block_size.into())?;
        let lod_levels = validate_lod_levels(options.lod_levels.into())?;
        if !device.is_empty()? {
            return Err(StorageError::Invalid("create needs an empty device".into()));
        }
        let mut block0 = header::encode_block0(block_size, lod_levels);
        let first = Commit { txn: 1, block_count: 1, ..Commit::default() };
        block0[header::slot_offset(0)..header::slot_offset(1)].copy_from_slice(&Slot::encode(
            0,
            SlotState::Committed,
            &first,
        ));
        device.write_at(0, &block0)?;
        device.sync()?;
        Database::open_on(device)
    }

    /// Opens a database on a device: reads the header, chooses the newest
    /// committed slot, reads its free list and meta block, and recovers from
    /// an interrupted transaction (format-spec/commit.md).
    pub fn open_on(device: Arc<dyn BlockDevice>) -> Result<Database, StorageError> {
        let len = device.len()?;
        if len < PREFIX_LEN as u64 {
            return Err(if len == 0 {
                StorageError::NotMktree
            } else {
                StorageError::Truncated { detail: format!("{len} bytes is shorter than a header") }
            });
        }
        let mut prefix = vec![0u8; PREFIX_LEN];
        device.read_at(0, &mut prefix)?;
        let (block_size, lod_levels) = header::decode_prefix(&prefix)?;
        let pager = Pager::new(device.clone(), block_size, lod_levels);
        let block0 = pager.read_raw(0)?;
        let (_, _, slots) = header::decode_block0(&block0)?;
        let committed_slot = match slots {
            [SlotRead::Committed(a), SlotRead::Committed(b)] => usize::from(b.txn > a.txn),
            [SlotRead::Committed(_), _] => 0,
            [_, SlotRead::Committed(_)] => 1,
            _ => return Err(StorageError::corrupt(0, "slots", "no valid committed slot")),
        };
        let SlotRead::Committed(committed) = slots[committed_slot] else { unreachable!("chosen above") };
        let other = slots[1 - committed_slot];
        let blocks_on_disk = pager.block_count()?;
        if blocks_on_disk < u64::from(committed.block_count) {
            return Err(StorageError::Truncated {
                detail: format!(
                    "the commit holds {} blocks, the file {blocks_on_disk}",
                    committed.block_count
                ),
            });
        }
        let free = read_free_list(&pager, &committed)?;
        let meta = read_meta(&pager, &committed)?;
        let interrupted = matches!(other, SlotRead::Pending { .. } | SlotRead::Invalid)
            || blocks_on_disk > u64::from(committed.block_count)
            || len % u64::from(block_size) != 0;
        let mut recovery = Recovery { interrupted, ..Recovery::default() };
        if interrupted {
            recover(&pager, &committed, 1 - committed_slot, &free, &mut recovery)?;
        }
        let snapshot = Arc::new(Snapshot { txn: committed.txn, meta, block_count: committed.block_count });
        let state = State {
            committed,
            committed_slot,
            free,
            snapshot,
            readers: BTreeMap::new(),
            freed_at: Vec::new(),
        };
        Ok(Database {
            inner: Arc::new(Inner {
                pager,
                cache: BlockCache::new(DEFAULT_CACHE_BLOCKS),
                state: Mutex::new(state),
                writer: Mutex::new(()),
            }),
            recovery,
        })
    }

    /// What opening found and repaired.
    pub fn recovery(&self) -> Recovery {
        self.recovery
    }

    /// Bytes per block.
    pub fn block_size(&self) -> u32 {
        self.inner.pager.block_size()
    }

    /// M, the levels of detail per node.
    pub fn lod_levels(&self) -> u8 {
        self.inner.pager.lod_levels()
    }

    /// Starts the write transaction; waits for a running one to finish.
    pub fn begin_write(&self) -> Result<WriteTransaction<'_>, StorageError> {
        let guard = self.inner.writer.lock().unwrap_or_else(|e| e.into_inner());
        WriteTransaction::begin(&self.inner, guard)
    }

    /// A read transaction on the last committed state.
    pub fn begin_read(&self) -> Result<ReadTransaction, StorageError> {
        let mut s = self.inner.lock_state();
        let snapshot = s.snapshot.clone();
        *s.readers.entry(snapshot.txn).or_default() += 1;
        Ok(ReadTransaction::new(self.inner.clone(), snapshot))
    }

    pub(crate) fn pager(&self) -> &Pager {
        &self.inner.pager
    }

    /// The committed slot and its free ranges (for `check`).
    pub(crate) fn committed(&self) -> (Commit, Vec<(u32, u32)>) {
        let s = self.inner.lock_state();
        (s.committed, s.free.clone())
    }
}

impl Inner {
    fn lock_state(&self) -> MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// A reader of snapshot `txn` ended.
    pub(crate) fn release_reader(&self, txn: u64) {
        let mut s = self.lock_state();
        if let Some(n) = s.readers.get_mut(&txn) {
            *n -= 1;
            if *n == 0 {
                s.readers.remove(&txn);
            }
        }
    }

    pub(crate) fn pager(&self) -> &Pager {
        &self.pager
    }

    pub(crate) fn cache(&self) -> &BlockCache {
        &self.cache
    }
}

/// The free ranges the commit's free-list chain holds, checked against the spec.
pub(crate) fn read_free_list(pager: &Pager, c: &Commit) -> Result<Vec<(u32, u32)>, StorageError> {
    let mut ranges: Vec<(u32, u32)> = Vec::new();
    let (mut block, mut sum) = (c.freelist_block, c.freelist_checksum);
    let mut stats = ReadStats::default();
    let mut hops = 0u64;
    while block != 0 {
        hops += 1;
        if block >= c.block_count || hops > u64::from(c.block_count) {
            return Err(StorageError::corrupt(block, "next_block", "the free list leaves the file or loops"));
        }
        let (b, _) = pager.read(block, BlockType::FreeList, Some(sum), &mut stats)?;
        let fl = FreeListBlock::decode(block, &b)?;
        for &(first, count) in &fl.ranges {
            let last = ranges.last().map_or(1, |&(f, n)| f + n + 1);
            if count == 0 || first < last || u64::from(first) + u64::from(count) > u64::from(c.block_count) {
                return Err(StorageError::corrupt(
                    block,
                    "ranges",
                    format!("range ({first}, {count}) is out of order or out of the file"),
                ));
            }
            ranges.push((first, count));
        }
        (block, sum) = (fl.next_block, fl.next_checksum);
    }
    let total: u64 = ranges.iter().map(|r| u64::from(r.1)).sum();
    if total != u64::from(c.free_blocks) {
        return Err(StorageError::corrupt(
            0,
            "free_blocks",
            format!("the slot says {}, the list holds {total}", c.free_blocks),
        ));
    }
    Ok(ranges)
}

/// The commit's meta block, if it has a tree.
pub(crate) fn read_meta(pager: &Pager, c: &Commit) -> Result<Option<Meta>, StorageError> {
    if c.meta_block == 0 {
        return Ok(None);
    }
    if c.meta_block >= c.block_count {
        return Err(StorageError::corrupt(
            0,
            "meta_block",
            format!("block {} is past the end", c.meta_block),
        ));
    }
    let (b, _) =
        pager.read(c.meta_block, BlockType::Meta, Some(c.meta_checksum), &mut ReadStats::default())?;
    let meta = Meta::decode(c.meta_block, &b)?;
    if meta.root_block == 0 || meta.root_block >= c.block_count {
        return Err(StorageError::corrupt(
            c.meta_block,
            "root_block",
            format!("{} is not a block of the file", meta.root_block),
        ));
    }
    Ok(Some(meta))
}

/// Recovery after an interrupted transaction (format-spec/commit.md).
fn recover(
    pager: &Pager,
    c: &Commit,
    other_slot: usize,
    free: &[(u32, u32)],
    r: &mut Recovery,
) -> Result<(), StorageError> {
    let bs = u64::from(pager.block_size());
    let len = pager.device().len()?;
    let end = u64::from(c.block_count) * bs;
    if len > end {
        r.truncated_blocks = (len - end).div_ceil(bs);
        pager.device().set_len(end)?;
    }
    for &(first, count) in free {
        for id in first..first + count {
            let mut b = pager.read_raw(id)?;
            if frame::open(id, &b).is_err() {
                b.fill(0);
                pager.write(id, &mut b, BlockType::Free, c.txn)?;
                r.scrubbed_blocks += 1;
            }
        }
    }
    pager.sync()?;
    pager.write_header_bytes(header::slot_offset(other_slot) as u64, &[0u8; 256])?;
    pager.sync()?;
    Ok(())
}
