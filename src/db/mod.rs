//! `Database`: one `.mkt` file. Read transactions are snapshots, in this
//! process and across processes; one write transaction runs at a time over
//! all processes sharing the file, and it alone repairs what a crash left.
//! The protocol is format-spec/commit.md.

mod changes;
mod check;
mod committed;
mod drift;
mod everything;
mod group;
mod hierarchy;
mod hosted;
mod key_index;
mod load;
mod lod;
mod path;
mod source;
mod staged;
mod stored;
mod write;
mod write_request;

use std::collections::{BTreeMap, HashMap};
use std::fs::OpenOptions;
use std::path::Path;
use std::sync::{Arc, Condvar, Mutex, MutexGuard};

pub use check::{CheckReport, check};
internal_use!(crate::tree::{method_from_code, method_to_code});
pub use drift::LayoutDrift;
pub use group::{GroupLevel, GroupSummary};
internal_use!(hierarchy::read_hierarchy);
#[cfg(feature = "internals")]
pub use hierarchy::read_hierarchy_blocks;
internal_use!(drift::read_tree_and_drift);
pub use crate::tree::{LodInfo, ReadTransaction, TreeInfo};
pub(crate) use crate::tree::{Snapshot, view};
pub(crate) use everything::walk_everything;
pub(crate) use hosted::Host;
pub use key_index::ObjectRecord;
pub use lod::{Level, Piece};
internal_use!(crate::tree::{NodeRef, Reads});
pub use staged::StagedScene;
pub use write::{ChangeStats, WriteTransaction};
pub use write_request::{JsonKey, JsonObject, WriteAnswer, WriteRequest, apply_write};

use crate::store::device::{FileDevice, TransferCounts};
use crate::store::format::frame;
use crate::store::format::freelist::FreeRange;
use crate::store::format::header::{self, Commit, PREFIX_LEN, SlotPair, SlotState};
use crate::store::format::{validate_block_size, validate_lod_levels};
use crate::store::lock::{FileLocks, Holder};
use crate::store::{BlockCache, BlockDevice, Pager, StorageError};
use crate::tree::Owner;
use committed::{Loaded, load, load_from, newest, read_slots, warnings};
use committed::{interrupted, recover};

/// Default block size, bytes (the format's; see the README's measurements).
pub const DEFAULT_BLOCK_SIZE: u32 = crate::store::format::DEFAULT_BLOCK_SIZE;
/// Default number of levels of detail M.
pub const DEFAULT_LOD_LEVELS: u8 = 4;
pub use crate::store::cache::DEFAULT_CACHE_BLOCKS;

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

/// What a write transaction repaired before it began.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Recovery {
    /// A write transaction had been interrupted (crash or abort).
    pub interrupted: bool,
    /// Torn free blocks rewritten as free blocks.
    pub scrubbed_blocks: u64,
    /// Blocks past the committed end removed.
    pub truncated_blocks: u64,
    /// Copies of the committed slot rewritten from the other copy.
    pub repaired_slot_copies: u64,
}

/// Something reading the header noticed that does not stop reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum Warning {
    /// A copy of a commit slot fails its checksum (a torn write or damage);
    /// the other copy holds the slot and the next write rewrites this one.
    DamagedSlotCopy {
        /// The slot, 0 or 1.
        slot: u8,
        /// The copy, 0 or 1.
        copy: u8,
    },
    /// A write transaction was interrupted (crash or abort); the next write
    /// transaction cleans up after it.
    Interrupted,
    /// Commit `txn`, synced once, did not reach the disk whole (a crash
    /// before its sync returned, so it never reported success): the state
    /// before it is read, and the next write transaction clears its slot.
    UnfinishedCommit {
        /// The commit's transaction id.
        txn: u64,
    },
}

impl std::fmt::Display for Warning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Warning::DamagedSlotCopy { slot, copy } => write!(
                f,
                "copy {copy} of commit slot {slot} fails its checksum (a torn write or damage); \
                 the other copy holds the slot, and the next write rewrites it"
            ),
            Warning::Interrupted => {
                write!(f, "a write transaction was interrupted; the next write cleans up after it")
            }
            Warning::UnfinishedCommit { txn } => write!(
                f,
                "commit {txn} did not reach the disk whole (a crash before its sync): \
                 the state before it is read, and the next write clears it"
            ),
        }
    }
}

/// What [`Database::compact`] did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct Compaction {
    /// The file's blocks before.
    pub blocks_before: u32,
    /// The file's blocks after.
    pub blocks_after: u32,
    /// Blocks still free after (held for readers of older snapshots, or
    /// holes the tree did not fill).
    pub free_after: u32,
    /// Times the tree was moved (copied into new blocks as it is).
    pub rewrites: u32,
    /// The state a reader (here or in another process) was reading, which
    /// kept the tree from moving: a move would have grown the file by the
    /// tree, since the reader's blocks stay until it ends. Only the free end
    /// was cut off then.
    pub held_by_reader: Option<u64>,
}

#[derive(Debug)]
struct State {
    slots: [SlotPair; 2],
    committed: Commit,
    committed_slot: usize,
    /// Free ranges of the committed state (what its free list holds).
    free: Vec<FreeRange>,
    /// The committed free list's blocks, head first.
    chain: Vec<u32>,
    /// A newer commit that did not reach the disk whole ([`Loaded::unfinished`]).
    unfinished: Option<u64>,
    snapshot: Arc<Snapshot>,
    /// Live readers in this process by snapshot transaction.
    readers: BTreeMap<u64, usize>,
    /// Free blocks freed after the oldest reader's state: block -> (the
    /// commit that freed it, the transaction that wrote it, from its frame),
    /// so that each is read once while it stays free.
    born: HashMap<u32, (u64, Option<u64>)>,
}

pub(crate) struct Inner {
    pager: Pager,
    cache: BlockCache,
    state: Mutex<State>,
    writer: Seat,
    /// Locks shared with other processes (files only).
    locks: Option<FileLocks>,
    /// The database whose transaction commits the tree, when its blocks
    /// live there (`hosted.rs`); `None` for a file or device of its own.
    host: Option<Arc<dyn Host>>,
    read_only: bool,
}

/// An MKtree file.
///
/// ```
/// use mktree::db::{CreateOptions, Database};
/// use mktree::bulk::BuildParams;
/// use mktree::geom::Aabb;
/// use mktree::scene::generate::{GenOptions, Preset, generate_scene};
///
/// let dir = tempfile::tempdir()?;
/// let scene = generate_scene(&GenOptions { preset: Preset::Tanker1, objects: None, seed: 1 })?;
/// let db = Database::create(dir.path().join("t1.mkt"), CreateOptions::default())?;
/// let mut w = db.begin_write()?;
/// w.bulk_load(&scene, &BuildParams::paper(), &|_| {})?;
/// w.commit()?;
/// let r = db.begin_read()?;
/// let hits = r.query_box(&scene.aabb())?;
/// assert_eq!(hits.objects.len(), scene.len());
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub struct Database {
    inner: Arc<Inner>,
    warnings: Vec<Warning>,
}

impl std::fmt::Debug for Database {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Database").field("pager", &self.inner.pager).finish()
    }
}

/// How [`Database::begin_write_with`] meets another process's write.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum WriterWait {
    /// Fail with [`StorageError::Locked`].
    #[default]
    Fail,
    /// Wait until it ends.
    Wait,
}

impl Database {
    /// Creates a new file at `path` (it must not exist) with an empty tree.
    pub fn create(path: impl AsRef<Path>, options: CreateOptions) -> Result<Database, StorageError> {
        let file = open_file(path.as_ref(), OpenOptions::new().read(true).write(true).create_new(true))?;
        let locks = FileLocks::new(file.try_clone()?);
        // Another process may open the file before its header is written: it
        // sees no magic and gives up, and it cannot write meanwhile.
        if !locks.lock_writer(false)? {
            return Err(locked(&locks));
        }
        let device = Arc::new(FileDevice::new(file));
        initialize(device.as_ref(), options)?;
        locks.unlock_writer()?;
        Database::open_with(device, Some(locks), false)
    }

    /// Opens the file at `path` to read and write, creating it with
    /// `options` when it does not exist or holds nothing a reader could use:
    /// it is empty, or shorter than a header and all zeros or the start of
    /// the magic number (what a crash while a file was created leaves). Any
    /// other file that is not an mktree file is refused with
    /// [`StorageError::NotMktree`] and left as it was. Returns whether the
    /// file was created; an existing file keeps its block size and M.
    pub fn open_or_create(
        path: impl AsRef<Path>,
        options: CreateOptions,
    ) -> Result<(Database, bool), StorageError> {
        let file =
            open_file(path.as_ref(), OpenOptions::new().read(true).write(true).create(true).truncate(false))?;
        if !file.metadata()?.is_file() {
            return Err(StorageError::NotAFile { path: path.as_ref().to_path_buf() });
        }
        let locks = FileLocks::new(file.try_clone()?);
        let device = Arc::new(FileDevice::new(file));
        let mut created = false;
        if holds_nothing(device.as_ref())? {
            // Under the writer's lock, so that two processes creating one
            // file write one header: the second finds it written.
            locks.lock_writer(true)?;
            let result = (|| {
                if holds_nothing(device.as_ref())? {
                    device.set_len(0)?;
                    initialize(device.as_ref(), options)?;
                    created = true;
                }
                Ok::<(), StorageError>(())
            })();
            locks.unlock_writer()?;
            result?;
        } else if device.len()? < PREFIX_LEN as u64 {
            return Err(StorageError::NotMktree);
        }
        Ok((Database::open_with(device, Some(locks), false)?, created))
    }

    /// Opens an existing file to read and write. Opening never writes: a
    /// crash's leftovers are cleaned up by the next write transaction.
    pub fn open(path: impl AsRef<Path>) -> Result<Database, StorageError> {
        let file = open_file(path.as_ref(), OpenOptions::new().read(true).write(true))?;
        let locks = FileLocks::new(file.try_clone()?);
        Database::open_with(Arc::new(FileDevice::new(file)), Some(locks), false)
    }

    /// Opens an existing file to read only (a read-only file or mount will
    /// do); [`begin_write`](Self::begin_write) fails with [`StorageError::ReadOnly`].
    pub fn open_read_only(path: impl AsRef<Path>) -> Result<Database, StorageError> {
        let file = open_file(path.as_ref(), OpenOptions::new().read(true))?;
        let locks = FileLocks::new(file.try_clone()?);
        Database::open_with(Arc::new(FileDevice::new(file)), Some(locks), true)
    }

    /// Creates a database on an empty device.
    pub fn create_on(device: Arc<dyn BlockDevice>, options: CreateOptions) -> Result<Database, StorageError> {
        initialize(device.as_ref(), options)?;
        Database::open_on(device)
    }

    /// Opens a database on a device no other process writes: reads the
    /// header, chooses the newest committed slot, reads its free list and
    /// meta block (format-spec/commit.md).
    pub fn open_on(device: Arc<dyn BlockDevice>) -> Result<Database, StorageError> {
        Database::open_with(device, None, false)
    }

    /// Opens a database on a device to read only: no write transaction, and
    /// nothing is written to the device (a crash's leftovers stay for a
    /// writer to clean up).
    pub fn open_on_read_only(device: Arc<dyn BlockDevice>) -> Result<Database, StorageError> {
        Database::open_with(device, None, true)
    }

    /// Opens, to read only, a committed file where it lies in object storage
    /// (`s3://`, `gs://`, `az://`, `http(s)://`, `file://`; the store's
    /// settings and credentials come from the environment and `options`).
    /// The reader is pinned to the object it opened: if the object is
    /// replaced, a later read fails with [`StorageError::ObjectChanged`].
    /// [`Database::transfer_counts`] says what it fetched.
    #[cfg(feature = "object-store")]
    pub fn open_url(
        url: &str,
        options: &crate::store::device::RemoteOptions,
    ) -> Result<Database, StorageError> {
        let device = crate::store::device::ObjectStoreDevice::open(url, options)?;
        Database::open_on_read_only(Arc::new(device))
    }

    /// Uploads the file as one object to `url` (`s3://`, `gs://`, `az://`,
    /// `file://`), holding the writer's lock meanwhile, so that the object is
    /// the file at one commit: readers of the object see the old upload or
    /// the new one, never a mixture (format-spec/remote.md, "Publishing").
    /// Waits for another process's write to end first.
    #[cfg(feature = "object-store")]
    pub fn publish(
        &self,
        url: &str,
        options: &crate::store::device::RemoteOptions,
    ) -> Result<crate::store::device::Published, StorageError> {
        // No writer may change the file meanwhile; none is started, so
        // nothing of a transaction is in the file.
        let _writer = self.writer_seat(WriterWait::Wait)?;
        crate::store::device::upload(self.inner.pager.device().clone(), url, options)
    }

    /// Requests, bytes and round trips the database's device has made over a
    /// network since it opened (a file in object storage); `None` for local
    /// storage.
    pub fn transfer_counts(&self) -> Option<TransferCounts> {
        self.inner.pager.device().transfer_counts()
    }

    fn open_with(
        device: Arc<dyn BlockDevice>,
        locks: Option<FileLocks>,
        read_only: bool,
    ) -> Result<Database, StorageError> {
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
        let pager = Pager::new(device, block_size, lod_levels);
        // The fixed region and the tail never change after creation: checked once.
        header::decode_block0(&pager.read_raw(0)?)?;
        let loaded = load(&pager)?;
        let warnings = warnings(&pager, &loaded)?;
        let state = State {
            slots: loaded.slots,
            committed: loaded.committed,
            committed_slot: loaded.committed_slot,
            free: loaded.free,
            chain: loaded.chain,
            unfinished: loaded.unfinished,
            snapshot: Arc::new(Snapshot::of(&loaded.committed, loaded.meta)),
            readers: BTreeMap::new(),
            born: HashMap::new(),
        };
        Ok(Database::assemble(pager, state, locks, None, read_only, warnings))
    }

    /// A database on `pager` in `state`, with no reader and no writer yet.
    fn assemble(
        pager: Pager,
        state: State,
        locks: Option<FileLocks>,
        host: Option<Arc<dyn Host>>,
        read_only: bool,
        warnings: Vec<Warning>,
    ) -> Database {
        Database {
            inner: Arc::new(Inner {
                pager,
                cache: BlockCache::new(DEFAULT_CACHE_BLOCKS),
                state: Mutex::new(state),
                writer: Seat::default(),
                locks,
                host,
                read_only,
            }),
            warnings,
        }
    }

    /// What opening noticed: damaged slot copies, an interrupted transaction.
    pub fn warnings(&self) -> &[Warning] {
        &self.warnings
    }

    /// Bytes per block.
    pub fn block_size(&self) -> u32 {
        self.inner.pager.block_size()
    }

    /// M, the levels of detail per node.
    pub fn lod_levels(&self) -> u8 {
        self.inner.pager.lod_levels()
    }

    /// Starts the write transaction; waits for one running in this process,
    /// and fails with [`StorageError::Locked`] if another process writes.
    pub fn begin_write(&self) -> Result<WriteTransaction<'_>, StorageError> {
        self.begin_write_with(WriterWait::Fail)
    }

    /// Starts the write transaction, meeting another process's write as `wait` says.
    pub fn begin_write_with(&self, wait: WriterWait) -> Result<WriteTransaction<'_>, StorageError> {
        let (guard, file_lock) = self.writer_seat(wait)?;
        WriteTransaction::begin(&self.inner, guard, file_lock)
    }

    /// The writer's seat in this process and its lock over processes.
    fn writer_seat(&self, wait: WriterWait) -> Result<(SeatGuard<'_>, Option<WriterLock<'_>>), StorageError> {
        if self.inner.read_only {
            return Err(StorageError::ReadOnly);
        }
        let guard = self.inner.writer.take();
        let file_lock = match &self.inner.locks {
            Some(l) if !l.lock_writer(wait == WriterWait::Wait)? => return Err(locked(l)),
            Some(l) => Some(WriterLock(l)),
            None => None,
        };
        Ok((guard, file_lock))
    }

    /// Gives the file's free blocks back to the file system. The tree is
    /// moved once past the file's end, so that every block below it is
    /// free, then again into the lowest blocks, and the free end is cut off
    /// (VACUUM-like: the file briefly holds the tree three times). While a
    /// reader holds a state, the tree is not moved (the file would only
    /// grow): the free end is cut off, and `held_by_reader` says why. A move
    /// copies the tree's blocks as they are, pointing only their references
    /// at the new places: nothing is laid out or computed again. Blocks a
    /// reader of an older snapshot may still read are kept.
    pub fn compact(&self) -> Result<Compaction, crate::Error> {
        self.compact_with(WriterWait::Fail)
    }

    /// [`compact`](Self::compact), meeting another process's write as
    /// `wait` says before each of its transactions.
    pub fn compact_with(&self, wait: WriterWait) -> Result<Compaction, crate::Error> {
        let space = |db: &Database| -> Result<(u32, u32), StorageError> {
            let w = db.begin_write_with(wait)?;
            let space = w.base_space();
            w.abort()?;
            Ok(space)
        };
        let blocks_before = space(self)?.0;
        // A tree the commits below would cut short is refused before any of them.
        {
            let w = self.begin_write_with(wait)?;
            w.check_movable()?;
            w.abort()?;
        }
        let mut rewrites = 0;
        self.trim_end(wait)?;
        // A reader of any state keeps the blocks a move frees: moving the
        // tree would leave the file larger than it began (issue 24).
        let held_by_reader = self.inner.oldest_reader(u64::MAX)?;
        if held_by_reader.is_none() && space(self)?.1 > 0 {
            for at_end in [true, false] {
                let mut w = self.begin_write_with(wait)?;
                w.relocate(at_end)?;
                w.commit()?;
                rewrites += 1;
                self.trim_end(wait)?;
            }
        }
        let (blocks_after, free_after) = space(self)?;
        Ok(Compaction { blocks_before, blocks_after, free_after, rewrites, held_by_reader })
    }

    /// Commits without changes until the file stops shrinking: each commit
    /// cuts off the free end, or moves the free list below it so that the
    /// next one can.
    fn trim_end(&self, wait: WriterWait) -> Result<(), crate::Error> {
        let end = |db: &Database| -> Result<u32, StorageError> {
            let w = db.begin_write_with(wait)?;
            let end = w.base_space().0;
            w.abort()?;
            Ok(end)
        };
        let mut last = end(self)?;
        loop {
            self.begin_write_with(wait)?.commit()?;
            self.begin_write_with(wait)?.commit()?;
            let now = end(self)?;
            if now >= last {
                return Ok(());
            }
            last = now;
        }
    }

    /// A read transaction on the newest committed state, which stays
    /// readable however many commits follow while it lives.
    pub fn begin_read(&self) -> Result<ReadTransaction, StorageError> {
        let inner = &self.inner;
        if inner.locks.is_none() {
            return inner.read_installed();
        }
        // Pin the newest state, then make sure it is still the newest: a
        // writer that began before the pin could otherwise reuse its blocks.
        for _ in 0..PIN_ATTEMPTS {
            inner.refresh()?;
            let snapshot = inner.lock_state().snapshot.clone();
            inner.pin(snapshot.txn)?;
            if newest(&read_slots(&inner.pager)?)?.1.txn == snapshot.txn {
                return Ok(ReadTransaction::new(inner.clone(), snapshot));
            }
            inner.release_reader(snapshot.txn);
        }
        Err(StorageError::Contended { attempts: PIN_ATTEMPTS })
    }

    pub(crate) fn pager(&self) -> &Pager {
        &self.inner.pager
    }

    /// True when a writer, in this process or another, may be writing free
    /// blocks right now: `check`, a reader, never keeps writers out, so it
    /// asks this before it counts a free block's damage as a fault.
    pub(crate) fn writer_active(&self) -> Result<bool, StorageError> {
        if self.inner.writer.is_taken() {
            return Ok(true);
        }
        match &self.inner.locks {
            Some(l) => Ok(l.writer_holder()?.is_some()),
            None => Ok(false),
        }
    }

    /// The committed slot, its free ranges and the header's warnings (for `check`).
    pub(crate) fn committed(&self) -> Result<(Commit, Vec<FreeRange>, Vec<Warning>), StorageError> {
        let s = self.inner.lock_state();
        let loaded = Loaded {
            slots: s.slots,
            committed: s.committed,
            committed_slot: s.committed_slot,
            free: s.free.clone(),
            chain: s.chain.clone(),
            meta: None,
            unfinished: s.unfinished,
        };
        let w = warnings(&self.inner.pager, &loaded)?;
        Ok((s.committed, s.free.clone(), w))
    }
}

/// The error for a writer's lock another owner holds, naming its role.
fn locked(locks: &FileLocks) -> StorageError {
    match locks.writer_holder() {
        Ok(Some(Holder::OldChecker)) => StorageError::LockedByCheck,
        // A writer, or one that ended since the refusal: "writing" is the likely truth.
        _ => StorageError::Locked,
    }
}

/// Opens `path` as `options` say; an error names the path.
fn open_file(path: &Path, options: &OpenOptions) -> Result<std::fs::File, StorageError> {
    // Opening a FIFO waits for its other end: refuse anything but a regular file.
    if let Ok(m) = std::fs::metadata(path)
        && !m.is_file()
    {
        let error = std::io::Error::new(std::io::ErrorKind::InvalidInput, "not a regular file");
        return Err(StorageError::Open { path: path.to_path_buf(), error });
    }
    options.open(path).map_err(|error| StorageError::Open { path: path.to_path_buf(), error })
}

/// Times a reader retries when commits keep landing between its reads.
const PIN_ATTEMPTS: u32 = 1000;

/// The writer's lock between processes, held for the transaction's life.
pub(crate) struct WriterLock<'a>(&'a FileLocks);

impl Drop for WriterLock<'_> {
    fn drop(&mut self) {
        // Closing the file would release it too; an error here leaves nothing wrong.
        let _ = self.0.unlock_writer();
    }
}

/// The one writer of this process: a flag and a condition variable rather
/// than a mutex, whose guard may not move to another thread, so that a
/// write transaction is `Send`.
#[derive(Default)]
pub(crate) struct Seat {
    taken: Mutex<bool>,
    freed: Condvar,
}

impl Seat {
    /// Waits until no writer of this process holds the seat, and takes it.
    fn take(&self) -> SeatGuard<'_> {
        let mut taken = self.taken.lock().unwrap_or_else(|e| e.into_inner());
        while *taken {
            taken = self.freed.wait(taken).unwrap_or_else(|e| e.into_inner());
        }
        *taken = true;
        SeatGuard(self)
    }

    /// True while a writer of this process holds the seat.
    fn is_taken(&self) -> bool {
        *self.taken.lock().unwrap_or_else(|e| e.into_inner())
    }
}

/// The seat, held until dropped.
pub(crate) struct SeatGuard<'a>(&'a Seat);

impl Drop for SeatGuard<'_> {
    fn drop(&mut self) {
        *self.0.taken.lock().unwrap_or_else(|e| e.into_inner()) = false;
        self.0.freed.notify_one();
    }
}

/// True when the file at `path` starts with an mktree file's magic number
/// (what it holds is checked by [`Database::open`]).
pub fn is_mktree_file(path: impl AsRef<Path>) -> bool {
    let mut magic = [0u8; 8];
    // Opening a FIFO waits for a writer: only a regular file is opened.
    std::fs::metadata(path.as_ref()).is_ok_and(|m| m.is_file())
        && std::fs::File::open(path).and_then(|mut f| std::io::Read::read_exact(&mut f, &mut magic)).is_ok()
        && magic == header::MAGIC
}

/// True when `device` holds nothing a reader could use: see [`Database::open_or_create`].
fn holds_nothing(device: &dyn BlockDevice) -> Result<bool, StorageError> {
    let len = device.len()?;
    if len >= PREFIX_LEN as u64 {
        return Ok(false);
    }
    let mut head = vec![0u8; len as usize];
    device.read_at(0, &mut head)?;
    let start = head.len().min(header::MAGIC.len());
    Ok(head[..start] == header::MAGIC[..start] || head.iter().all(|&b| b == 0))
}

/// Writes block 0 of a new file: both copies of slot 0 hold an empty tree.
fn initialize(device: &dyn BlockDevice, options: CreateOptions) -> Result<(), StorageError> {
    let block_size = validate_block_size(options.block_size.into())?;
    let lod_levels = validate_lod_levels(options.lod_levels.into())?;
    if !device.is_empty()? {
        return Err(StorageError::NotEmpty);
    }
    let mut block0 = header::encode_block0(block_size, lod_levels);
    let first = Commit { txn: 1, block_count: 1, ..Commit::default() };
    header::put_slot(&mut block0, 0, SlotState::Committed, &first);
    device.write_at(0, &block0)?;
    device.sync()?;
    Ok(())
}

impl Inner {
    fn lock_state(&self) -> MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// A reader of snapshot `txn` begins: the first in this process pins it for other processes.
    fn pin(&self, txn: u64) -> Result<(), StorageError> {
        let mut s = self.lock_state();
        let n = s.readers.entry(txn).or_default();
        *n += 1;
        if *n == 1
            && let Some(l) = &self.locks
            && let Err(e) = l.pin(txn)
        {
            s.readers.remove(&txn);
            return Err(e.into());
        }
        Ok(())
    }

    /// A reader of the state this process last installed (no other process
    /// can commit: there is none, or this one holds the writer's seat).
    pub(crate) fn read_installed(self: &Arc<Self>) -> Result<ReadTransaction, StorageError> {
        let snapshot = self.lock_state().snapshot.clone();
        self.pin(snapshot.txn)?;
        Ok(ReadTransaction::new(self.clone(), snapshot))
    }

    /// The oldest state a reader in this or another process still reads.
    fn oldest_reader(&self, below: u64) -> Result<Option<u64>, StorageError> {
        let here = self.lock_state().readers.keys().next().copied();
        let there = match &self.locks {
            Some(l) => l.oldest_pin(below)?,
            None => None,
        };
        Ok(here.into_iter().chain(there).min())
    }

    /// Whether a reader, here or in another process, reads the state of a
    /// transaction in `lo .. hi`.
    fn pinned_between(&self, lo: u64, hi: u64) -> Result<bool, StorageError> {
        if hi <= lo {
            return Ok(false);
        }
        if self.lock_state().readers.range(lo..hi).next().is_some() {
            return Ok(true);
        }
        match &self.locks {
            Some(l) => Ok(l.pinned_between(lo, hi)?),
            None => Ok(false),
        }
    }

    /// The free blocks of `free` a writer may overwrite (format-spec/commit.md,
    /// "Many processes"): every range freed at or before `oldest`, the oldest
    /// state a reader reads; and of those freed since, each block written
    /// (its frame's transaction) after every state a reader reads before
    /// the block was freed. A reader's state reaches a block only if the
    /// block was written at or before it and freed after it.
    fn reusable(&self, free: &[FreeRange], oldest: Option<u64>) -> Result<Vec<(u32, u32)>, StorageError> {
        let mut out: Vec<(u32, u32)> = Vec::new();
        let mut born = std::mem::take(&mut self.lock_state().born);
        let mut kept = HashMap::new();
        // Blocks of one commit share (written, freed): one probe each.
        let mut pinned: HashMap<(u64, u64), bool> = HashMap::new();
        for r in free {
            let Some(oldest) = oldest.filter(|&o| r.freed > o) else {
                out.push((r.first, r.count));
                continue;
            };
            for b in r.first..r.first.saturating_add(r.count) {
                let written = match born.remove(&b) {
                    Some((freed, written)) if freed == r.freed => written,
                    // A block that fails its checksum is left alone: what wrote it is unknown.
                    _ => self
                        .pager
                        .read_raw(b)
                        .ok()
                        .and_then(|raw| frame::open(b, &raw).ok())
                        .map(|(f, _)| f.txn.get()),
                };
                kept.insert(b, (r.freed, written));
                let Some(written) = written else { continue };
                let span = (written.max(oldest), r.freed);
                let held = match pinned.get(&span) {
                    Some(&h) => h,
                    None => {
                        let h = self.pinned_between(span.0, span.1)?;
                        pinned.insert(span, h);
                        h
                    }
                };
                if !held {
                    match out.last_mut() {
                        Some((first, count)) if *first + *count == b => *count += 1,
                        _ => out.push((b, 1)),
                    }
                }
            }
        }
        self.lock_state().born = kept;
        out.sort_unstable();
        Ok(out)
    }

    /// Catches up with commits made by other processes (files only).
    fn refresh(&self) -> Result<(), StorageError> {
        if self.locks.is_none() {
            return Ok(());
        }
        let slots = read_slots(&self.pager)?;
        let txn = newest(&slots)?.1.txn;
        if txn == self.lock_state().committed.txn {
            self.lock_state().slots = slots;
            return Ok(());
        }
        let loaded = load(&self.pager)?;
        self.install(loaded);
        Ok(())
    }

    /// Makes `l` the committed state, unless a newer one is installed.
    fn install(&self, l: Loaded) {
        let mut s = self.lock_state();
        if l.committed.txn < s.committed.txn {
            return;
        }
        s.slots = l.slots;
        s.unfinished = l.unfinished;
        if l.committed.txn == s.committed.txn {
            return;
        }
        s.committed = l.committed;
        s.committed_slot = l.committed_slot;
        s.free = l.free;
        s.chain = l.chain;
        s.unfinished = l.unfinished;
        s.snapshot = Arc::new(Snapshot::of(&l.committed, l.meta));
    }

    /// The newest committed state, for a writer: the installed one, when
    /// the slots still name it, without reading its free list and meta
    /// block again; else as read.
    fn load_newest(&self) -> Result<Loaded, StorageError> {
        let slots = read_slots(&self.pager)?;
        if let Ok((i, c)) = newest(&slots) {
            let s = self.lock_state();
            if i == s.committed_slot && c == s.committed {
                return Ok(Loaded {
                    slots,
                    committed: c,
                    committed_slot: i,
                    free: s.free.clone(),
                    chain: s.chain.clone(),
                    meta: s.snapshot.meta.clone(),
                    unfinished: s.unfinished,
                });
            }
        }
        load_from(&self.pager, slots)
    }
}

/// The pager and cache a reader reads through are the ones the writer
/// uses: db's own code reaches them through this too.
impl Owner for Inner {
    fn pager(&self) -> &Pager {
        &self.pager
    }

    fn cache(&self) -> &BlockCache {
        &self.cache
    }

    fn release_reader(&self, txn: u64) {
        let mut s = self.lock_state();
        if let Some(n) = s.readers.get_mut(&txn) {
            *n -= 1;
            if *n == 0 {
                s.readers.remove(&txn);
                if let Some(l) = &self.locks {
                    // Closing the file releases it too; a failure only delays reuse.
                    let _ = l.unpin(txn);
                }
            }
        }
    }
}
