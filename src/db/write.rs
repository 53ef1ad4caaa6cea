//! The write transaction: bulk-loads a scene into new blocks (copy on write)
//! and commits it with the protocol of format-spec/commit.md.

use std::collections::{BTreeMap, VecDeque};
use std::sync::Arc;
use std::time::Instant;

use super::StagedScene;
use super::load::{Load, Sink};
use super::source::{self, ObjectSource};
use super::{Inner, ReadTransaction, Recovery, SeatGuard, Snapshot, WriterLock, interrupted, recover};
use crate::bulk::{BuildParams, BuildProgress, Hierarchy, LoadProgress, build_owned, check_range};
use crate::lod::LodParams;
use crate::scene::{Key, KeyError, Object, ObjectId, Scene};
use crate::store::alloc::{FreeSpace, free_keeping, label_freed};
use crate::store::format::change_log::{ChangeKind, ChangeLog};
use crate::store::format::frame::BlockType;
use crate::store::format::freelist::{FreeListBlock, FreeRange, ranges_per_block};
use crate::store::format::geometry;
use crate::store::format::header::{self, Commit, Slot, SlotState};
use crate::store::format::meta::{Meta, log_room, written_capacity};
use crate::store::{Block, StorageError};
use crate::tree::Owner;

mod cow;
mod hosted;
mod relocate;

pub use cow::ChangeStats;
use cow::{Change, Edits};

/// The one write transaction. Dropping it without `commit` aborts it: the
/// committed state is untouched.
pub struct WriteTransaction<'db> {
    inner: &'db Arc<Inner>,
    _guard: SeatGuard<'db>,
    _file_lock: Option<WriterLock<'db>>,
    txn: u64,
    base: Commit,
    /// The base state's free ranges, labelled with the commits that freed them.
    base_free: Vec<FreeRange>,
    /// The base state's free-list blocks.
    base_chain: Vec<u32>,
    /// A reader of the base state, held for the transaction's lookups.
    base_reader: Option<Arc<ReadTransaction>>,
    slot: usize,
    /// The order slot `slot`'s copies are written in: the pending mark's first.
    slot_order: [usize; 2],
    recovery: Recovery,
    /// Blocks this transaction may allocate.
    avail: FreeSpace,
    /// Blocks this transaction wrote (as a set of ranges).
    written: FreeSpace,
    /// The new meta block (block, checksum), once a tree is loaded.
    meta: Option<(u32, u32, Meta)>,
    /// A change commit's meta block (block, fields), written at commit
    /// after the free list, so that it can list what the commit wrote.
    change_meta: Option<(u32, Meta)>,
    /// The checksum of each block this transaction's changes wrote, for
    /// the meta block's list (the last write of a block counts).
    sums: BTreeMap<u32, u32>,
    /// Blocks this commit wrote that the next one reads again (node blocks
    /// and key branches, as verified blocks): the shared cache takes them
    /// once the commit is installed, so that the next commit does not read
    /// and validate its path again. At most the cache's capacity, the last
    /// written (parents come after their children).
    rewritten: VecDeque<Arc<Block>>,
    /// While a change commit is tried in place: the blocks it allocated,
    /// given back if it stops short.
    taken: Option<Vec<(u32, u32)>>,
    /// Set when the commit keeps the committed tree: the committed blocks
    /// it frees (the committed free list's, and what the new tree no longer
    /// reaches). The new free list is then the committed one less what the
    /// commit wrote, plus these.
    kept: Option<Vec<(u32, u32)>>,
    /// How the levels of detail below M are built.
    lod_params: LodParams,
    /// Objects inserted, updated and deleted, by key, once the first change began.
    edits: Option<Edits>,
    /// What the last commit of changes wrote.
    change_stats: ChangeStats,
    /// The oldest snapshot a reader held when the transaction began.
    oldest_reader: Option<u64>,
    /// Allocates past the file's end only (the first step of a compaction).
    append_only: bool,
    /// A commit of changes: the committed change log and how this commit
    /// changed each key, for the new meta block's log. `None` for a bulk
    /// load, whose tree starts a new log.
    logged: Option<(ChangeLog, Vec<(ChangeKind, Key)>)>,
    done: bool,
}

/// What a commit installs besides its slot: the tree (or none), the free
/// ranges, and the free list's blocks (head first).
struct NewState {
    meta: Option<Meta>,
    free: Vec<FreeRange>,
    chain: Vec<u32>,
}

/// The state a write transaction begins on, as its commit protocol gives it.
struct Begun {
    txn: u64,
    base: Commit,
    base_free: Vec<FreeRange>,
    base_chain: Vec<u32>,
    slot: usize,
    /// The order slot `slot`'s copies are written in: the pending mark's first.
    slot_order: [usize; 2],
    recovery: Recovery,
    avail: FreeSpace,
    oldest_reader: Option<u64>,
}

impl<'db> WriteTransaction<'db> {
    pub(super) fn begin(
        inner: &'db Arc<Inner>,
        guard: SeatGuard<'db>,
        file_lock: Option<WriterLock<'db>>,
    ) -> Result<WriteTransaction<'db>, StorageError> {
        if inner.host.is_some() {
            return Ok(WriteTransaction::new(inner, guard, file_lock, hosted::begin(inner)?));
        }
        let pager = inner.pager().clone();
        // Another process may have committed since this one last looked.
        let mut loaded = inner.load_newest()?;
        let mut recovery = Recovery::default();
        let (base, c_slot) = (loaded.committed, loaded.committed_slot);
        if interrupted(&pager, &loaded)? {
            recovery.interrupted = true;
            recover(&pager, &loaded.committed, &loaded.free, &mut recovery)?;
        }
        if loaded.unfinished.take().is_some() {
            // The slot of a commit that did not reach the disk whole is
            // cleared, a copy at a time, before this transaction reuses its
            // blocks (format-spec/commit.md, "Recovery").
            for copy in 0..2 {
                write_slot_copy(&pager, 1 - c_slot, copy, SlotState::Empty, &Commit::default())?;
            }
            loaded.slots[1 - c_slot] = header::SlotPair { copies: [header::SlotRead::Empty; 2] };
        }
        if base.txn >= header::MAX_TXN {
            return Err(StorageError::Invalid(format!("transaction ids are exhausted at {}", base.txn)));
        }
        // A damaged copy of the slot in force is rewritten from the other.
        let in_force = loaded.slots[c_slot];
        for copy in in_force.invalid_copies() {
            write_slot_copy(&pager, c_slot, copy, SlotState::Committed, &base)?;
            recovery.repaired_slot_copies += 1;
        }
        let slot = 1 - c_slot;
        let order = loaded.slots[slot].write_order();
        let (base_free, base_chain) = (loaded.free.clone(), loaded.chain.clone());
        inner.install(loaded);
        // Blocks freed by a commit are reusable once no reader, here or in
        // another process, reads a state older than that commit.
        let oldest = inner.oldest_reader(base.txn)?;
        let avail = FreeSpace::new(base.block_count, inner.reusable(&base_free, oldest)?);
        let txn = base.txn + 1;
        // Step 1: one copy saying pending outranks the other (its
        // transaction is newer) and tells the next writer to clean up after
        // a crash. It gets no sync of its own: sync 2 makes it durable
        // before step 5 writes the other slot copy that could tear, and
        // until then `base`, the newer committed slot, wins on reopen
        // whatever this copy holds (format-spec/commit.md).
        pager.write_header_bytes(
            header::slot_offset(slot, order[0]) as u64,
            &Slot::encode(slot, order[0], SlotState::Pending, &Commit { txn, ..Commit::default() }),
        )?;
        let begun = Begun {
            txn,
            base,
            base_free,
            base_chain,
            slot,
            slot_order: order,
            recovery,
            avail,
            oldest_reader: oldest,
        };
        Ok(WriteTransaction::new(inner, guard, file_lock, begun))
    }

    fn new(
        inner: &'db Arc<Inner>,
        guard: SeatGuard<'db>,
        file_lock: Option<WriterLock<'db>>,
        b: Begun,
    ) -> WriteTransaction<'db> {
        let end = b.avail.end();
        WriteTransaction {
            inner,
            _guard: guard,
            _file_lock: file_lock,
            txn: b.txn,
            base: b.base,
            base_free: b.base_free,
            base_chain: b.base_chain,
            base_reader: None,
            slot: b.slot,
            slot_order: b.slot_order,
            recovery: b.recovery,
            avail: b.avail,
            written: FreeSpace::new(end, []),
            meta: None,
            change_meta: None,
            sums: BTreeMap::new(),
            rewritten: VecDeque::new(),
            taken: None,
            kept: None,
            lod_params: LodParams::default(),
            edits: None,
            change_stats: ChangeStats::default(),
            oldest_reader: b.oldest_reader,
            append_only: false,
            logged: None,
            done: false,
        }
    }

    /// What this transaction repaired before it began (a crash's leftovers).
    pub fn recovery(&self) -> Recovery {
        self.recovery
    }

    /// Sets how the next tree's levels of detail are built (default:
    /// `LodParams::default()`, eps from the scene).
    pub fn set_lod_params(&mut self, params: LodParams) {
        self.lod_params = params;
    }

    /// This transaction's id.
    pub fn id(&self) -> u64 {
        self.txn
    }

    /// The committed state this transaction began on, as a reader: one pin
    /// for all of the transaction's lookups.
    fn base_reader(&mut self) -> Result<Arc<ReadTransaction>, StorageError> {
        if let Some(r) = &self.base_reader {
            return Ok(r.clone());
        }
        let r = Arc::new(self.inner.read_installed()?);
        self.base_reader = Some(r.clone());
        Ok(r)
    }

    /// Writes block `id` of a change commit, noting its checksum for the
    /// meta block's list of written blocks.
    fn put(&mut self, id: u32, block: &mut [u8], t: BlockType) -> Result<u32, StorageError> {
        let sum = self.inner.pager().write(id, block, t, self.txn)?;
        self.sums.insert(id, sum);
        Ok(sum)
    }

    /// Keeps block `b`, just written and verified, for the shared cache
    /// at install; past the cache's capacity the earliest kept goes.
    fn keep_for_cache(&mut self, b: Block) {
        let capacity = self.inner.cache().capacity();
        if capacity == 0 {
            return;
        }
        if self.rewritten.len() >= capacity {
            self.rewritten.pop_front();
        }
        self.rewritten.push_back(Arc::new(b));
    }

    /// The change log of the meta block this commit writes, which lists
    /// `written`: the committed log with this commit's changes, or a new
    /// log for a bulk-loaded tree (format-spec/meta.md, "The change log").
    fn next_log(&mut self, written: &[(u32, u32)]) -> Result<ChangeLog, StorageError> {
        match self.logged.take() {
            Some((log, changes)) => {
                log.after(self.txn, &changes, log_room(self.inner.pager().block_size(), written.len()))
            }
            None => Ok(ChangeLog::starting_at(self.txn)),
        }
    }

    fn allocate(&mut self, count: u32) -> Result<u32, StorageError> {
        let first =
            if self.append_only { self.avail.allocate_at_end(count)? } else { self.avail.allocate(count)? };
        self.written.release(first, count);
        if let Some(t) = self.taken.as_mut() {
            t.push((first, count));
        }
        // Readers of older snapshots no longer reach these blocks: drop any cached copy.
        self.inner.cache().forget(first, count);
        Ok(first)
    }

    /// Builds the MKtree of `scene` with `params` and writes it: geometry,
    /// node blocks with the levels of detail that pay, the key index, meta. Replaces
    /// the tree on commit. Returns the hierarchy that was written.
    pub fn bulk_load(
        &mut self,
        scene: &Scene,
        params: &BuildParams,
        progress: &(dyn Fn(LoadProgress) + Sync),
    ) -> Result<Hierarchy, crate::Error> {
        self.may_write_tree()?;
        check_range(scene, geometry::MAX_COORDINATE)?;
        scene.check_keys()?;
        self.load(scene, params, progress)
    }

    /// [`bulk_load`](Self::bulk_load) of a scene staged on disk: the same
    /// tree and the same blocks as for a [`Scene`] of the same objects,
    /// with only one object's mesh (a few per thread) in memory at a time.
    pub fn bulk_load_staged(
        &mut self,
        staged: &mut StagedScene,
        params: &BuildParams,
        progress: &(dyn Fn(LoadProgress) + Sync),
    ) -> Result<Hierarchy, crate::Error> {
        self.may_write_tree()?;
        staged.flush()?;
        staged.shrink_to_fit();
        staged.check_unique_keys()?;
        self.load(staged, params, progress)
    }

    /// Builds the tree of checked `objects` and writes it.
    fn load(
        &mut self,
        objects: &dyn ObjectSource,
        params: &BuildParams,
        progress: &(dyn Fn(LoadProgress) + Sync),
    ) -> Result<Hierarchy, crate::Error> {
        let started = Instant::now();
        let tree =
            build_owned(objects.object_boxes(), Some(objects.record_lens()), params, &|p: BuildProgress| {
                progress(p.as_stage())
            })?;
        let build_seconds = started.elapsed().as_secs_f64();
        self.write(objects, &tree, params, build_seconds, progress)?;
        Ok(tree)
    }

    /// Writes a tree already built from `scene` with `params` (e.g. once for
    /// several files); `build_seconds` is recorded in the meta block. The tree
    /// must be a valid hierarchy of exactly the scene's objects.
    pub fn write_tree(
        &mut self,
        scene: &Scene,
        tree: &Hierarchy,
        params: &BuildParams,
        build_seconds: f64,
    ) -> Result<(), crate::Error> {
        self.may_write_tree()?;
        check_range(scene, geometry::MAX_COORDINATE)?;
        scene.check_keys()?;
        let boxes = scene.object_boxes();
        let sizes: Vec<u64> = scene.objects().iter().map(|o| geometry::record_len(&o.mesh)).collect();
        tree.validate(&boxes, Some(&sizes), params)?;
        self.write(scene, tree, params, build_seconds, &|_| {})
    }

    fn may_write_tree(&self) -> Result<(), crate::Error> {
        if self.meta.is_some() || self.edits.is_some() {
            return Err(crate::Error::OneTree);
        }
        Ok(())
    }

    /// The transaction's changes; refuses them after a bulk load.
    fn edits(&mut self) -> Result<&mut Edits, crate::Error> {
        if self.meta.is_some() {
            return Err(crate::Error::OneTree);
        }
        Ok(self.edits.get_or_insert_with(Edits::default))
    }

    /// Refuses an object the file could not hold: its geometry's range,
    /// its payload, and its key entry's bytes against a key block's.
    fn check_change(&self, key: &Key, object: &Object) -> Result<(), crate::Error> {
        let id = ObjectId(0);
        source::check_object(id, object)?;
        let len = crate::store::format::keys::entry_len(key, object.payload.len(), object.name.len());
        let capacity = crate::store::format::keys::capacity(self.inner.pager().block_size());
        if len > capacity {
            return Err(KeyError::EntryTooLarge { key: key.clone(), len, capacity }.into());
        }
        Ok(())
    }

    /// The largest integer key, as the transaction has the tree.
    fn largest_int_key(&mut self) -> Result<Option<u64>, crate::Error> {
        let committed = self.base_reader()?.largest_int_key()?;
        let edited =
            self.edits()?.ops.keys().filter_map(|k| if let Key::Int(i) = k { Some(*i) } else { None }).max();
        Ok(committed.max(edited))
    }

    /// Adds `object` to the tree: into the leaf whose box grows least. An
    /// object without a key gets the integer key one past the largest in
    /// the tree. Returns the object's key; a key already in the tree is
    /// [`KeyError::Exists`](crate::scene::KeyError::Exists).
    ///
    /// Changes are applied at `commit`, which writes what they touch: the
    /// changed leaves, the node blocks on their paths, the key index's
    /// paths and the meta block (format-spec/commit.md). A change that
    /// would split or empty a leaf makes the commit write the tree whole.
    pub fn insert(&mut self, mut object: Object) -> Result<Key, crate::Error> {
        self.edits()?;
        let key = match object.key.take() {
            Some(key) => key,
            None => {
                let next = match self.largest_int_key()? {
                    None => 0,
                    Some(i) => i.checked_add(1).ok_or(KeyError::IntegersExhausted)?,
                };
                Key::Int(next)
            }
        };
        self.check_change(&key, &object)?;
        if self.object(&key)?.is_some() {
            return Err(KeyError::Exists { key }.into());
        }
        object.key = Some(key.clone());
        self.edits()?.ops.insert(key.clone(), Change::Put(object));
        Ok(key)
    }

    /// Removes the object of key `key`, returning it; `None` if no object
    /// has that key. A leaf keeps its box until the tree is laid out anew.
    pub fn remove(&mut self, key: &Key) -> Result<Option<Object>, crate::Error> {
        self.edits()?;
        let old = self.object(key)?;
        if old.is_some() {
            self.edits()?.ops.insert(key.clone(), Change::Remove);
        }
        Ok(old)
    }

    /// Replaces the object with `object`'s key by `object`, moved to the
    /// leaf it now fits best; returns the old object. A key not in the tree
    /// is [`KeyError::NotFound`](crate::scene::KeyError::NotFound).
    pub fn update(&mut self, object: Object) -> Result<Object, crate::Error> {
        let key = object.key.clone().ok_or(KeyError::Unnamed)?;
        self.edits()?;
        self.check_change(&key, &object)?;
        let old = self.object(&key)?.ok_or_else(|| KeyError::NotFound { key: key.clone() })?;
        self.edits()?.ops.insert(key, Change::Put(object));
        Ok(old)
    }

    /// Moves the object of key `key` by `by` (mm) without the caller sending
    /// its mesh again: its geometry is read and translated, and it is
    /// written as an update. Returns whether the key has an object.
    pub fn move_by(&mut self, key: &Key, by: crate::geom::Vector) -> Result<bool, crate::Error> {
        let Some(mut object) = self.object(key)? else { return Ok(false) };
        let moved: Vec<crate::geom::Point> = object.mesh.vertices().map(|p| p + by).collect();
        object.mesh = crate::scene::Mesh::from_world(&moved, object.mesh.triangles().to_vec())?;
        object.key = Some(key.clone());
        self.update(object)?;
        Ok(true)
    }

    /// The committed state's (file blocks, free blocks) this transaction began on.
    pub(crate) fn base_space(&self) -> (u32, u32) {
        (self.base.block_count, self.base.free_blocks)
    }

    /// The object of key `key` as this transaction has it, changes included.
    pub fn object(&mut self, key: &Key) -> Result<Option<Object>, crate::Error> {
        if let Some(change) = self.edits()?.ops.get(key) {
            return Ok(match change {
                Change::Put(o) => Some(o.clone()),
                Change::Remove => None,
            });
        }
        Ok(self.base_reader()?.object(key)?)
    }

    /// What the last commit of changes wrote (zero before one).
    pub fn change_stats(&self) -> ChangeStats {
        self.change_stats
    }

    /// Applies the transaction's changes: copy on write when they allow it,
    /// else by writing the changed tree whole.
    fn apply_edits(&mut self, edits: Edits) -> Result<bool, crate::Error> {
        if edits.ops.is_empty() {
            return Ok(false);
        }
        if self.inner.host.is_none() {
            // An attempt that stops short leaves nothing reachable: its blocks go back.
            let end = self.avail.end();
            self.taken = Some(Vec::new());
            let tried = self.commit_in_place(&edits);
            let taken = self.taken.take().unwrap_or_default();
            match tried? {
                Some(stats) => {
                    self.change_stats = stats;
                    return Ok(false);
                }
                None => {
                    self.avail.give_back(&taken, end);
                    self.written.remove_all(&taken);
                    (self.change_meta, self.sums) = (None, BTreeMap::new());
                    self.rewritten.clear();
                }
            }
        }
        self.rewrite_whole(edits)
    }

    /// Lays the tree out anew at commit, as a bulk load of its objects with
    /// the file's build parameters would: what change commits leave behind
    /// (boxes a removal left loose, the subtrees of split leaves, leaves
    /// moved to node blocks of their own, bounds dropped by splits) goes,
    /// and node ids are preorder numbers again. Geometry is copied as
    /// stored; levels of detail are computed again. This transaction's
    /// changes so far are applied first; it takes no more after this.
    /// `mktree optimize` runs it.
    pub fn optimize(&mut self) -> Result<(), crate::Error> {
        if self.meta.is_some() {
            return Err(crate::Error::OneTree);
        }
        let edits = self.edits.take().unwrap_or_default();
        self.change_stats.changes = edits.ops.len() as u64;
        if self.rewrite_whole(edits.clone())? {
            // The changes remove every object: the commit applies them, and
            // leaves no tree to lay out.
            self.edits = Some(edits);
        }
        Ok(())
    }

    /// The tree written whole: the committed objects with `edits` applied,
    /// bulk-loaded with the file's build parameters. `true`: no object is left.
    fn rewrite_whole(&mut self, edits: Edits) -> Result<bool, crate::Error> {
        let snapshot = self.base_reader()?;
        let params = snapshot
            .info()
            .and_then(|i| i.params)
            .unwrap_or_else(|| BuildParams::for_blocks(self.inner.pager().block_size()));
        let mut objects: BTreeMap<Key, Object> = BTreeMap::new();
        for o in snapshot.scene()?.into_objects() {
            let key =
                o.key.clone().ok_or_else(|| StorageError::Invalid("a stored object without a key".into()))?;
            objects.insert(key, o);
        }
        // With no committed tree (its objects all removed), what commits before
        // it changed is not known: the log starts after it.
        let log = snapshot
            .snapshot
            .meta
            .as_ref()
            .map_or_else(|| ChangeLog::starting_at(self.base.txn), |m| m.log.clone());
        drop(snapshot);
        let mut logged = Vec::new();
        for (key, change) in edits.ops {
            match change {
                Change::Remove => {
                    if objects.remove(&key).is_some() {
                        logged.push((ChangeKind::Removed, key));
                    }
                }
                Change::Put(object) => {
                    let kind = match objects.insert(key.clone(), object) {
                        Some(_) => ChangeKind::Updated,
                        None => ChangeKind::Inserted,
                    };
                    logged.push((kind, key));
                }
            }
        }
        // The objects are the committed ones changed as logged: a laid-out
        // tree of them (optimize) changes no other key.
        self.logged = Some((log, logged));
        self.change_stats = ChangeStats { changes: self.change_stats.changes, ..ChangeStats::default() };
        if objects.is_empty() {
            return Ok(true);
        }
        let scene = Scene::new(objects.into_values().collect());
        check_range(&scene, geometry::MAX_COORDINATE)?;
        self.load(&scene, &params, &|_| {})?;
        Ok(false)
    }

    /// Writes a valid tree of `objects` (built here, or checked by
    /// `write_tree`) through the load pipeline, then its meta block.
    fn write(
        &mut self,
        objects: &dyn ObjectSource,
        tree: &Hierarchy,
        params: &BuildParams,
        build_seconds: f64,
        progress: &(dyn Fn(LoadProgress) + Sync),
    ) -> Result<(), crate::Error> {
        let pager = self.inner.pager().clone();
        let (txn, lod_params) = (self.txn, self.lod_params.clone());
        // The meta block first: in an empty file it follows the header, and
        // a remote open's first range holds both (format-spec/remote.md).
        let meta_block = self.allocate(1)?;
        let meta = {
            let allocate = &mut |count: u32| self.allocate(count);
            let load = Load { objects, tree, params, build_seconds, lod_params: &lod_params };
            load.write(Sink { pager: &pager, txn, allocate }, progress)?
        };
        let meta = Meta { log: self.next_log(&[])?, ..meta };
        let mut block = vec![0u8; pager.block_size() as usize];
        meta.encode(&mut block);
        let sum = pager.write(meta_block, &mut block, BlockType::Meta, self.txn)?;
        self.meta = Some((meta_block, sum, meta));
        Ok(())
    }

    /// Makes the transaction durable: writes the free list, syncs, writes the
    /// commit slot, syncs (format-spec/commit.md, steps 3 to 5).
    pub fn commit(self) -> Result<(), crate::Error> {
        self.commit_with_stats().map(|_| ())
    }

    /// [`commit`](Self::commit), returning what the transaction's changes
    /// wrote: blocks written, freed and read, and whether they went in
    /// place (copy on write) or the tree was written whole.
    pub fn commit_with_stats(mut self) -> Result<ChangeStats, crate::Error> {
        let pager = self.inner.pager().clone();
        let mut cleared = false;
        // The committed free list's blocks, when this commit keeps the tree:
        // at the file's end they are cut off once the commit is durable.
        let mut old_chain = Vec::new();
        if let Some(edits) = self.edits.take() {
            self.change_stats.changes = edits.ops.len() as u64;
            cleared = self.apply_edits(edits)?;
        }
        if let Some(host) = self.inner.host.clone() {
            let stats = self.change_stats;
            self.commit_hosted(host.as_ref(), cleared)?;
            return Ok(stats);
        }
        // The meta block: written with the tree, or (a change commit) to
        // be written after the free list.
        let (meta_block, mut meta_checksum, mut meta) = match (self.meta.take(), self.change_meta.take()) {
            (Some((block, sum, meta)), _) => (block, sum, Some(meta)),
            (None, Some((block, meta))) => (block, 0, Some(meta)),
            (None, None) if cleared => (0, 0, None),
            (None, None) => {
                let chain = self.base_chain.clone();
                let mut free = self.base_free.clone();
                let shorter = self.trim_tail(&mut free, self.base.block_count, &[]) < self.base.block_count;
                // A list block above a reusable hole moves down, so that a
                // later commit can cut off the end it held.
                let lowest_hole = self.base_free.iter().find(|r| self.reusable(r)).map(|r| r.first);
                let list_moves = chain.iter().any(|&b| lowest_hole.is_some_and(|h| h < b));
                if !shorter && !list_moves {
                    // Nothing to write: the same state under a new transaction id.
                    let c = Commit { txn: self.txn, ..self.base };
                    self.finish(c, None)?;
                    return Ok(self.change_stats);
                }
                // The same tree, and a shorter file.
                self.keep_base(chain.iter().map(|&b| (b, 1)).collect());
                old_chain = chain;
                let meta = self.inner.lock_state().snapshot.meta.clone();
                (self.base.meta_block, self.base.meta_checksum, meta)
            }
        };
        let unwritten_meta = meta_checksum == 0 && meta_block != 0;
        let FreeList { free, end, head: (next, next_sum), blocks: list_blocks } =
            self.write_free_list(&old_chain)?;
        // A change commit small enough for its meta block to list what it
        // wrote commits with one sync (format-spec/commit.md).
        let mut listed = false;
        if unwritten_meta && let Some(m) = meta.as_mut() {
            listed = self.sums.len() <= written_capacity(pager.block_size());
            if listed {
                m.written = self.sums.iter().map(|(&b, &s)| (b, s)).collect();
            }
            m.log = self.next_log(&m.written)?;
            let mut block = vec![0u8; pager.block_size() as usize];
            m.encode(&mut block);
            meta_checksum = pager.write(meta_block, &mut block, BlockType::Meta, self.txn)?;
        }
        let c = Commit {
            txn: self.txn,
            meta_block,
            meta_checksum,
            block_count: end,
            freelist_block: next,
            freelist_checksum: next_sum,
            free_blocks: free.iter().map(|r| r.count).sum(),
            listed,
        };
        self.finish(c, Some(NewState { meta, free, chain: list_blocks }))?;
        if end < self.avail.end() {
            // After the commit: a crash before this leaves a longer file, which the next writer truncates.
            pager
                .device()
                .set_len(u64::from(end) * u64::from(pager.block_size()))
                .map_err(StorageError::from)?;
        }
        Ok(self.change_stats)
    }

    /// Writes the new free list: everything this transaction did not write
    /// (or keep), past the end it cuts off. Its own blocks come from
    /// `avail`, never from the blocks it frees.
    fn write_free_list(&mut self, old_chain: &[u32]) -> Result<FreeList, StorageError> {
        let pager = self.inner.pager().clone();
        let per = ranges_per_block(pager.block_size());
        let mut list_blocks: Vec<u32> = Vec::new();
        let (free, end) = loop {
            let mut free = match &self.kept {
                Some(freed) => free_keeping(
                    &self.base_free,
                    self.base.block_count,
                    self.avail.end(),
                    &self.written,
                    freed,
                    self.txn,
                ),
                None => label_freed(
                    &FreeSpace::complement(self.avail.end(), &self.written),
                    &self.base_free,
                    self.txn,
                ),
            };
            let end = self.trim_tail(&mut free, self.avail.end(), old_chain);
            let need = free.len().div_ceil(per);
            if need <= list_blocks.len() {
                break (free, end);
            }
            // The list's own blocks change it by a few ranges at most: the
            // next pass mostly finds it fits.
            while list_blocks.len() < need {
                list_blocks.push(self.allocate(1)?);
            }
        };
        let (mut next, mut next_sum) = (0u32, 0u32);
        let chunks: Vec<&[FreeRange]> = free.chunks(per).collect();
        for (j, &id) in list_blocks.iter().enumerate().rev() {
            let fl = FreeListBlock {
                next_block: next,
                next_checksum: next_sum,
                ranges: chunks.get(j).map_or(Vec::new(), |c| c.to_vec()),
            };
            let mut block = vec![0u8; pager.block_size() as usize];
            fl.encode(&mut block);
            next_sum = self.put(id, &mut block, BlockType::FreeList)?;
            next = id;
        }
        Ok(FreeList { free, end, head: (next, next_sum), blocks: list_blocks })
    }

    /// Drops the free ranges at the end of a file of `end` blocks that no
    /// reader can reach (freed by an earlier commit, before the oldest
    /// reader's snapshot), or that only the committed free list (`old_list`)
    /// held, which readers never read; returns the new end.
    fn trim_tail(&self, free: &mut Vec<FreeRange>, mut end: u32, old_list: &[u32]) -> u32 {
        let only_old_list = |r: &FreeRange| (r.first..r.first + r.count).all(|b| old_list.contains(&b));
        while let Some(last) = free.last()
            && last.first + last.count == end
            && (self.reusable(last) || only_old_list(last))
        {
            end = last.first;
            free.pop();
        }
        end
    }

    /// Whether no reader can reach the blocks of `r`: freed by an earlier
    /// commit, before the oldest reader's snapshot.
    fn reusable(&self, r: &FreeRange) -> bool {
        r.freed < self.txn && self.oldest_reader.is_none_or(|o| r.freed <= o)
    }

    /// Keeps the committed tree but for the blocks `freed` (the committed
    /// free list's, which the new list replaces, and what the new tree no
    /// longer reaches).
    fn keep_base(&mut self, freed: Vec<(u32, u32)>) {
        self.kept = Some(freed);
    }

    fn finish(&mut self, c: Commit, new: Option<NewState>) -> Result<(), StorageError> {
        let pager = self.inner.pager();
        // A listed commit's blocks need not be durable before its slot: a
        // reader verifies them against the list, and takes the commit
        // before it if one fails (format-spec/commit.md).
        self.change_stats.syncs = 1;
        if !c.listed {
            pager.sync()?;
            self.change_stats.syncs = 2;
        }
        // Durable once the first copy is: a crash before the second leaves
        // one valid committed copy, which wins (format-spec/commit.md). The
        // first is the copy that holds the pending mark, so that one copy
        // of the slot is in flight at a time; the second needs no sync of
        // its own: this slot is written again only two commits on, after
        // their syncs have flushed it.
        let [first, second] = self.slot_order;
        write_slot_copy(pager, self.slot, first, SlotState::Committed, &c)?;
        pager.write_header_bytes(
            header::slot_offset(self.slot, second) as u64,
            &Slot::encode(self.slot, second, SlotState::Committed, &c),
        )?;
        self.install(c, new);
        Ok(())
    }

    /// Makes `c` (with its meta and free ranges, or the base's) the state readers begin on.
    fn install(&mut self, c: Commit, new: Option<NewState>) {
        self.done = true;
        for b in self.rewritten.drain(..) {
            self.inner.cache().put(b);
        }
        let mut s = self.inner.lock_state();
        let (meta, free) = match new {
            Some(n) => {
                s.chain = n.chain;
                (n.meta, n.free)
            }
            None => (s.snapshot.meta.clone(), s.free.clone()),
        };
        let value = header::SlotRead::Committed(c);
        s.slots[self.slot] = header::SlotPair { copies: [value; 2] };
        s.committed = c;
        s.committed_slot = self.slot;
        s.free = free;
        s.snapshot = Arc::new(Snapshot::of(&c, meta));
    }

    /// Abandons the transaction; the file keeps its committed state.
    pub fn abort(mut self) -> Result<(), StorageError> {
        self.rollback()
    }

    fn rollback(&mut self) -> Result<(), StorageError> {
        self.done = true;
        if let Some(host) = self.inner.host.clone() {
            return host.discard(&self.written.ranges());
        }
        let pager = self.inner.pager();
        // Nothing was torn: the pending slot can be cleared, and appended blocks dropped.
        pager.device().set_len(u64::from(self.base.block_count) * u64::from(pager.block_size()))?;
        pager.sync()?;
        for copy in 0..2 {
            write_slot_copy(pager, self.slot, copy, SlotState::Empty, &Commit::default())?;
        }
        let mut s = self.inner.lock_state();
        s.slots[self.slot] = header::SlotPair { copies: [header::SlotRead::Empty; 2] };
        Ok(())
    }
}

/// Writes one copy of a slot and syncs it, so that a crash tears at most one
/// copy of a slot (format-spec/commit.md).
fn write_slot_copy(
    pager: &crate::store::Pager,
    slot: usize,
    copy: usize,
    state: SlotState,
    c: &Commit,
) -> Result<(), StorageError> {
    pager.write_header_bytes(header::slot_offset(slot, copy) as u64, &Slot::encode(slot, copy, state, c))?;
    pager.sync()
}

impl Drop for WriteTransaction<'_> {
    fn drop(&mut self) {
        if !self.done {
            // Best effort: if it fails, the next open sees the pending slot and recovers.
            let _ = self.rollback();
        }
    }
}

/// A commit's new free list as written.
struct FreeList {
    /// Its ranges.
    free: Vec<FreeRange>,
    /// The file's length in blocks after the commit.
    end: u32,
    /// Its first block and that block's checksum (0, 0: none).
    head: (u32, u32),
    /// Its blocks, head first.
    blocks: Vec<u32>,
}
