//! A change commit that writes what it touches (format-spec/commit.md,
//! "Change commits"): the changed leaves' records and geometry spans, the
//! node blocks holding them and, block by block, their parent blocks up to
//! the root's; the changed key index paths; the meta block. Everything else
//! is shared with the committed tree, and what the new tree no longer
//! reaches goes to the free list under this commit's id.
//!
//! A change finds its object's leaf through the key index's path and an
//! insert its leaf by the least growth of a box, reading one path from the
//! root each; nothing is held per object of the tree. A box that grows
//! past its parent's frame rewrites its parent's record with a frame
//! grown to hold it, and gives the sibling, whose own frame does not
//! change, a frame of its own (format-spec/node.md, "Quantized boxes"), so
//! no subtree is rewritten below the path. A box that shrinks stays as it
//! was: boxes stay conservative, and `compact` lays the tree out anew.
//!
//! A leaf past twice its bulk load's capacity, or whose record would not
//! fit a node block, splits in place into the subtree a bulk load of its
//! objects builds; a leaf a change empties merges with its sibling leaf
//! (format-spec/commit.md, "Splits", "Merges"). An emptied leaf beside a
//! subtree or a changed leaf is committed by writing the changed tree
//! whole, as every commit did before format version 6.
//!
//! This file holds the entry (`commit_in_place`), what
//! its steps share, and the new meta block's fields. The steps, in order:
//! `plan.rs` finds the changed leaves and the records on their paths;
//! `leaf.rs` rewrites each leaf, which `split.rs` splits and `merge.rs`
//! merges with its sibling; `internal.rs` rewrites the records above;
//! `blocks.rs` writes the node blocks holding them; `keys.rs` the key index.

mod blocks;
mod internal;
mod keys;
mod leaf;
mod merge;
mod plan;
mod split;

use std::collections::BTreeMap;
use std::sync::Arc;

use super::WriteTransaction;
use crate::db::lod::bound_rules;
use crate::db::{ReadTransaction, Reads};
use crate::geom::Aabb;
use crate::lod::{LodParams, LodPlan};
use crate::scene::{Key, Object};
use crate::store::format::meta::Meta;
use crate::store::format::node::{RecordDraft, RecordRef};
use crate::store::{Block, StorageError};
use crate::tree::Owner;
use keys::NewKeys;
use plan::{Plan, plan_leaves};

/// A change to one key, as the transaction last asked for it.
#[derive(Debug, Clone)]
pub(crate) enum Change {
    /// Store this object under its key (an insert, or an update of the
    /// committed object).
    Put(Object),
    /// Remove the committed object of the key.
    Remove,
}

/// The transaction's changes by key, applied at commit.
#[derive(Debug, Clone, Default)]
pub(crate) struct Edits {
    pub ops: BTreeMap<Key, Change>,
}

/// What a change commit wrote, for its caller and the benchmarks.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct ChangeStats {
    /// Objects inserted, updated and removed.
    pub changes: u64,
    /// Blocks written: node, geometry, key index and the meta block.
    pub blocks_written: u64,
    /// Blocks of the committed tree the new one no longer reaches.
    pub blocks_freed: u64,
    /// Blocks read to find the changed objects and rewrite their paths.
    pub blocks_read: u64,
    /// Whether the changes were written in place (copy on write); `false`:
    /// the tree was written whole.
    pub in_place: bool,
    /// Syncs the commit made: 1 when its meta block lists every block it
    /// wrote, else 2 (format-spec/commit.md); 0 for a tree in redb, whose
    /// commit syncs as redb does.
    pub syncs: u64,
}

/// A record on a changed path, and what it becomes.
struct Mod {
    block: Arc<Block>,
    offset: u32,
    /// The record's frame before the change.
    frame: Aabb,
    /// Its parent record and the child index it is there.
    parent: Option<((u32, u32), usize)>,
    depth: usize,
    /// The new record, once made.
    draft: Option<RecordDraft>,
    /// `Some(b)`: the parent's entry must hold `b` (quantized anew);
    /// `None`: the parent's entry stays as it is.
    required: Option<Aabb>,
    /// Objects and geometry blocks the subtree gains (or loses).
    objects: i64,
    geometry_blocks: i64,
    /// Node blocks the subtree gains below the record (a split's).
    node_blocks: i64,
    /// The record leaves the tree (a merge's).
    gone: bool,
    /// A sibling a merge moved into its parent's place: the record that
    /// is its children's parent now.
    merged_into: Option<(u32, u32)>,
}

impl Mod {
    /// Record `offset` of `block`, of frame `frame`, as found: nothing of
    /// it changed yet.
    fn new(
        block: Arc<Block>,
        offset: u32,
        frame: Aabb,
        parent: Option<((u32, u32), usize)>,
        depth: usize,
    ) -> Self {
        Mod {
            block,
            offset,
            frame,
            parent,
            depth,
            draft: None,
            required: None,
            objects: 0,
            geometry_blocks: 0,
            node_blocks: 0,
            gone: false,
            merged_into: None,
        }
    }
}

/// Counts the meta block keeps, changed by the commit.
#[derive(Default)]
struct Deltas {
    objects: i64,
    node_blocks: i64,
    node_bytes: i64,
    geometry_blocks: i64,
    geometry_bytes: i64,
    triangles: i64,
    vertices: i64,
    lod_usage: Vec<[i64; 2]>,
    /// Nodes and leaves splits add.
    nodes: i64,
    leaves: i64,
    /// The deepest level a split reaches.
    depth: u32,
    /// The next node id; whether a split took one.
    next_node: u32,
    new_ids: bool,
    /// The rules changed leaves draw their entries' bounds by (none below M = 3).
    rules: Option<(LodPlan, LodParams)>,
    /// Per level k - 1: the widest cell diagonal of a bound drawn, which
    /// eps_k must cover.
    eps: Vec<f64>,
}

impl Deltas {
    /// No change yet to `meta`'s counts, in a file of `m` levels of detail.
    fn new(r: &ReadTransaction, meta: &Meta, m: u8) -> Self {
        Deltas {
            lod_usage: vec![[0; 2]; usize::from(m)],
            next_node: if meta.node_ids == 0 { meta.node_count } else { meta.node_ids },
            rules: if m >= 3 { bound_rules(r) } else { None },
            eps: vec![0.0; usize::from(m)],
            ..Deltas::default()
        }
    }

    /// A bound of level `level` and `len` bytes that goes.
    fn drop_bound(&mut self, level: u8, len: usize) {
        if let Some(u) = usize::from(level).checked_sub(1).and_then(|k| self.lod_usage.get_mut(k)) {
            u[0] -= len as i64;
            u[1] -= 1;
        }
    }

    /// A bound of level `level`, `len` bytes and cells of diagonal `diag`, drawn.
    fn add_bound(&mut self, level: u8, len: usize, diag: f64) {
        let k = usize::from(level).saturating_sub(1);
        if let Some(u) = self.lod_usage.get_mut(k) {
            u[0] += len as i64;
            u[1] += 1;
        }
        if let Some(e) = self.eps.get_mut(k) {
            *e = e.max(diag);
        }
    }

    /// The bounds a leaf record drops and draws, as `leaf_draft` gives them.
    fn count_bounds(&mut self, dropped: Vec<(u8, usize)>, drawn: Vec<(u8, usize, f64)>) {
        for (level, len) in dropped {
            self.drop_bound(level, len);
        }
        for (level, len, diag) in drawn {
            self.add_bound(level, len, diag);
        }
    }

    /// An id for a new node (format-spec/meta.md, `node_ids`).
    fn next_node_id(&mut self) -> Result<u32, StorageError> {
        let id = self.next_node;
        self.next_node =
            id.checked_add(1).ok_or_else(|| StorageError::Invalid("node ids are exhausted".into()))?;
        self.new_ids = true;
        Ok(id)
    }
}

/// A change that needs the tree written whole (see the module's header).
struct Structural;

type Step<T> = Result<Result<T, Structural>, crate::Error>;

/// Blocks in a set of ranges.
fn written_count(w: &crate::store::alloc::FreeSpace) -> u64 {
    w.ranges().iter().map(|&(_, n)| u64::from(n)).sum()
}

fn apply(x: u64, d: i64) -> Result<u64, StorageError> {
    x.checked_add_signed(d)
        .ok_or_else(|| StorageError::Invalid("a count of the meta block went out of range".into()))
}

impl WriteTransaction<'_> {
    /// Writes `edits` copy on write. `Ok(None)`: a change needs the tree
    /// written whole, and nothing was written.
    pub(super) fn commit_in_place(&mut self, edits: &Edits) -> Result<Option<ChangeStats>, crate::Error> {
        let r = self.base_reader()?;
        let Some(meta) = r.snapshot.meta.clone() else { return Ok(None) };
        // Through the shared cache: the lookups of the changes read the same paths.
        let mut reads = Reads::new(Some(r.cache()));
        let mut stats =
            ChangeStats { changes: edits.ops.len() as u64, in_place: true, ..ChangeStats::default() };
        let mut plan = match plan_leaves(&r, &meta, edits, &mut reads)? {
            Ok(p) => p,
            Err(Structural) => return Ok(None),
        };
        let logged = std::mem::take(&mut plan.logged);
        let written_before = written_count(&self.written);
        let outcome = self.write_changes(&r, &meta, plan, &mut reads)?;
        // The caller takes back the blocks of an attempt that stops short.
        let Ok((new_meta, freed)) = outcome else { return Ok(None) };
        // The meta block is written last, after the free list, so that it
        // can list every other block the commit wrote.
        let meta_block = self.allocate(1)?;
        self.logged = Some((meta.log.clone(), logged));
        self.change_meta = Some((meta_block, new_meta));
        stats.blocks_written = written_count(&self.written) - written_before;
        // The committed tree stays but for what this commit replaced, and
        // the committed free list, which the new one replaces.
        let mut gone: Vec<(u32, u32)> = freed.iter().map(|&b| (b, 1)).collect();
        gone.push((self.base.meta_block, 1));
        stats.blocks_freed = gone.len() as u64;
        gone.extend(self.base_chain.iter().map(|&b| (b, 1)));
        self.keep_base(gone);
        stats.blocks_read = reads.stats.total();
        Ok(Some(stats))
    }

    /// Writes the changed leaves, their paths and the key index; returns the
    /// new meta block's fields and the blocks the new tree no longer reaches.
    fn write_changes(
        &mut self,
        r: &ReadTransaction,
        meta: &Meta,
        plan: Plan,
        reads: &mut Reads,
    ) -> Step<(Meta, Vec<u32>)> {
        let pager = self.inner.pager().clone();
        let mut freed: Vec<u32> = Vec::new();
        let mut deltas = Deltas::new(r, meta, pager.lod_levels());
        let Plan { mut mods, leaves, mut key_changes, next_id, logged: _ } = plan;
        // Leaves: their new records and geometry.
        for (at, edit) in &leaves {
            let leaf =
                self.rewrite_leaf(r, &mut mods, *at, edit, &mut key_changes, reads, &mut deltas, &mut freed)?;
            if let Err(Structural) = leaf {
                return Ok(Err(Structural));
            }
        }
        let scene_box = self.rewrite_internals(r, &mut mods, meta, reads)?;
        // Node blocks, children before parents; none when the changes
        // cancel out (an object inserted and removed again).
        let root = if mods.is_empty() {
            RecordRef { block: meta.root_block, checksum: meta.root_checksum, offset: meta.root_offset }
        } else {
            let root_at = (meta.root_block, meta.root_offset);
            match self.rewrite_blocks(&mut mods, root_at, pager.block_size(), &mut deltas, &mut freed)? {
                Ok(root) => root,
                Err(Structural) => return Ok(Err(Structural)),
            }
        };
        let keys = self.rewrite_keys(r, meta, key_changes, reads, &mut freed)?;
        let new = new_meta(meta, &deltas, root, scene_box, &keys, next_id)?;
        if new.object_count == 0 {
            return Ok(Err(Structural));
        }
        Ok(Ok((new, freed)))
    }
}

/// The meta block's fields after a change commit: `meta`'s, with the new
/// root, scene box, key index and next object id, and its counts changed
/// by `deltas`.
fn new_meta(
    meta: &Meta,
    deltas: &Deltas,
    root: RecordRef,
    scene_box: Aabb,
    keys: &NewKeys,
    next_id: u32,
) -> Result<Meta, StorageError> {
    let mut new = meta.clone();
    (new.root_block, new.root_checksum, new.root_offset) = (root.block, root.checksum, root.offset);
    new.scene_box = scene_box.to_array();
    new.object_count = u32::try_from(apply(u64::from(meta.object_count), deltas.objects)?)
        .map_err(|_| StorageError::Invalid("more objects than ids".into()))?;
    new.object_ids = next_id;
    new.node_count = u32::try_from(apply(u64::from(meta.node_count), deltas.nodes)?)
        .map_err(|_| StorageError::FileTooLarge)?;
    new.leaf_count = u32::try_from(apply(u64::from(meta.leaf_count), deltas.leaves)?)
        .map_err(|_| StorageError::FileTooLarge)?;
    // After a merge, a bound: no deeper than a split took it, nor than its leaves allow.
    new.depth = meta.depth.max(deltas.depth).min(new.leaf_count.saturating_sub(1));
    if deltas.new_ids {
        new.node_ids = deltas.next_node;
    }
    new.node_blocks = u32::try_from(apply(u64::from(meta.node_blocks), deltas.node_blocks)?)
        .map_err(|_| StorageError::FileTooLarge)?;
    new.node_bytes = apply(meta.node_bytes, deltas.node_bytes)?;
    new.geometry_blocks = apply(meta.geometry_blocks, deltas.geometry_blocks)?;
    new.geometry_bytes = apply(meta.geometry_bytes, deltas.geometry_bytes)?;
    new.triangle_count = apply(meta.triangle_count, deltas.triangles)?;
    new.vertex_count = apply(meta.vertex_count, deltas.vertices)?;
    for (u, d) in new.lods.usage.iter_mut().zip(&deltas.lod_usage) {
        u[0] = apply(u[0], d[0])?;
        u[1] = apply(u[1], d[1])?;
    }
    // eps_k still bounds every stored bound's cells (format-spec/lod.md).
    for (row, &e) in new.lod_table.iter_mut().zip(&deltas.eps) {
        row[0] = row[0].max(e);
    }
    (new.keys_block, new.keys_checksum, new.keys_height, new.keys_blocks) =
        (keys.block, keys.checksum, keys.height, keys.blocks);
    Ok(new)
}
