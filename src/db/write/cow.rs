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

use std::collections::{BTreeMap, BTreeSet};

// Record and block ids hash with Fx: SipHash's resistance buys nothing here
// and cost a commit on ship 10^6 a tenth of its instructions.
use rustc_hash::{FxHashMap as HashMap, FxHashSet as HashSet};
use std::sync::Arc;

use super::WriteTransaction;
use crate::bulk::{BuildParams, LeafRule};
use crate::db::load::split_info;
use crate::db::lod::bound_rules;
use crate::db::path::PathStep;
use crate::db::source::check_object;
use crate::db::{ReadTransaction, Reads};
use crate::geom::Aabb;
use crate::lod::{self, LodParams, LodPlan, Voxels, bound_grid};
use crate::scene::{Key, KeyError, Object, ObjectId};
use crate::store::format::frame::{BlockType, FRAME_LEN};
use crate::store::format::geometry::{self, Placement};
use crate::store::format::keys::{self, ChildRef, KeyBlock, KeyEntry, TreePath};
use crate::store::format::meta::Meta;
use crate::store::format::node::{
    self, BoundEntry, ChildEntry, NodeView, ObjectEntry, RecordDraft, RecordPart, RecordRef,
};
use crate::store::format::quant::{QuantBox, quantize};
use crate::store::layout;
use crate::store::{Block, StorageError};
use crate::tree::view;

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

/// The most objects below a sibling an emptied leaf merges with: each one's
/// key entry is rewritten, so a larger subtree costs more than it saves.
const MERGE_SUBTREE_OBJECTS: u32 = 64;

/// The keys of the objects below record `offset` of `block`, walking its
/// subtree; a walk that visits more records than a binary tree of
/// [`MERGE_SUBTREE_OBJECTS`] leaves holds is a damaged tree.
fn subtree_keys(
    r: &ReadTransaction,
    block: &Arc<Block>,
    offset: u32,
    reads: &mut Reads,
) -> Result<Vec<Key>, StorageError> {
    let mut stack = vec![(block.clone(), offset)];
    let (mut keys, mut visited) = (Vec::new(), 0u32);
    while let Some((b, o)) = stack.pop() {
        visited += 1;
        if visited > 2 * MERGE_SUBTREE_OBJECTS {
            return Err(StorageError::corrupt(
                b.id(),
                "children",
                "a subtree with more records than its objects allow",
            ));
        }
        match view(&b, o)? {
            NodeView::Leaf(l) => keys.extend(l.keys().map(|(_, k)| k.to_key())),
            NodeView::Internal(n) => {
                for i in 0..2 {
                    let at = n.child_ref(i);
                    stack.push((r.node_block(&b, at, reads)?, at.offset));
                }
            }
        }
    }
    Ok(keys)
}

/// What an emptied leaf took from its parent's subtree.
struct Gone {
    objects: i64,
    geometry_blocks: i64,
}

/// An object added to a leaf: its id, key and the object.
struct Added {
    id: u32,
    object: Object,
}

/// A leaf's changes: the objects it loses and gains.
#[derive(Default)]
struct LeafEdit {
    remove: HashSet<u32>,
    add: Vec<Added>,
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
        let plan = match plan_leaves(&r, &meta, edits, &mut reads)? {
            Ok(p) => p,
            Err(Structural) => return Ok(None),
        };
        let written_before = written_count(&self.written);
        let outcome = self.write_changes(&r, &meta, plan, &mut reads)?;
        // The caller takes back the blocks of an attempt that stops short.
        let Ok((new_meta, freed)) = outcome else { return Ok(None) };
        // The meta block is written last, after the free list, so that it
        // can list every other block the commit wrote.
        let meta_block = self.allocate(1)?;
        self.change_meta = Some((meta_block, new_meta));
        stats.blocks_written = written_count(&self.written) - written_before;
        // The committed tree stays but for what this commit replaced.
        let chain = self.base_chain.clone();
        self.keep_base(&chain);
        let mut gone: Vec<(u32, u32)> = freed.iter().map(|&b| (b, 1)).collect();
        gone.push((self.base.meta_block, 1));
        self.written.remove_all(&gone);
        stats.blocks_freed = gone.len() as u64;
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
        let bs = pager.block_size();
        let m = pager.lod_levels();
        let mut freed: Vec<u32> = Vec::new();
        let mut deltas = Deltas {
            lod_usage: vec![[0; 2]; usize::from(m)],
            next_node: if meta.node_ids == 0 { meta.node_count } else { meta.node_ids },
            rules: if m >= 3 { bound_rules(r) } else { None },
            eps: vec![0.0; usize::from(m)],
            ..Deltas::default()
        };
        let Plan { mut mods, leaves, mut key_changes, next_id } = plan;
        // Leaves: their new records and geometry.
        for (at, edit) in &leaves {
            match self.rewrite_leaf(
                r,
                &mut mods,
                *at,
                edit,
                &mut key_changes,
                reads,
                &mut deltas,
                &mut freed,
            )? {
                Ok(()) => {}
                Err(Structural) => return Ok(Err(Structural)),
            }
        }
        // Internal records, deepest first: boxes, counts, frames.
        let mut order: Vec<(u32, u32)> = mods.keys().copied().collect();
        order.sort_by_key(|k| std::cmp::Reverse(mods[k].depth));
        let mut scene_box = Aabb::from_array(meta.scene_box);
        for at in order {
            if mods[&at].draft.is_some() || mods[&at].gone {
                continue;
            }
            if let Some(grown) = self.rewrite_internal(r, &mut mods, at, reads)? {
                // The root's frame grew: the scene box is its frame.
                scene_box = grown;
            }
        }
        // A root leaf's frame of its own lies in the scene box, which grows to hold it.
        let root_at = (meta.root_block, meta.root_offset);
        if let Some(b) = mods.get(&root_at).and_then(|m| m.required) {
            scene_box = scene_box.union(&b);
        }
        // Node blocks, children before parents; none when the changes
        // cancel out (an object inserted and removed again).
        let root = if mods.is_empty() {
            RecordRef { block: meta.root_block, checksum: meta.root_checksum, offset: meta.root_offset }
        } else {
            match self.rewrite_blocks(&mut mods, root_at, bs, &mut deltas, &mut freed)? {
                Ok(root) => root,
                Err(Structural) => return Ok(Err(Structural)),
            }
        };
        let keys = self.rewrite_keys(r, meta, key_changes, reads, &mut freed)?;
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
        if new.object_count == 0 {
            return Ok(Err(Structural));
        }
        Ok(Ok((new, freed)))
    }
}

/// Every leaf a commit changes, the records on their paths, the key
/// index's changes and the next free object id.
struct Plan {
    mods: HashMap<(u32, u32), Mod>,
    leaves: BTreeMap<(u32, u32), LeafEdit>,
    key_changes: BTreeMap<Key, Option<KeyEntry>>,
    next_id: u32,
}

/// Finds each changed object's leaf (the key index's path for a committed
/// one, the least growth for a new one) and notes the records on the way.
fn plan_leaves(r: &ReadTransaction, meta: &Meta, edits: &Edits, reads: &mut Reads) -> Step<Plan> {
    let mut plan = Plan {
        mods: HashMap::default(),
        leaves: BTreeMap::new(),
        key_changes: BTreeMap::new(),
        next_id: meta.object_ids,
    };
    for (key, change) in &edits.ops {
        let old = r.key_entry(key, reads)?;
        if let Some(e) = &old {
            let steps = r.path_to(e.object_id, e.path, &e.aabb, reads)?;
            let leaf = note_path(&mut plan.mods, &steps);
            plan.leaves.entry(leaf).or_default().remove.insert(e.object_id);
        }
        match change {
            Change::Remove => {
                if old.is_some() {
                    plan.key_changes.insert(key.clone(), None);
                }
            }
            Change::Put(object) => {
                let id = plan.next_id;
                plan.next_id = id
                    .checked_add(1)
                    .ok_or_else(|| StorageError::Invalid("object ids are exhausted".into()))?;
                check_object(ObjectId(id), object)?;
                // The box as the file will hold it: its stored geometry's.
                let aabb = stored_box(object)?;
                let steps = choose_leaf(r, meta, &aabb, reads)?;
                let path = path_of(&steps);
                let leaf = note_path(&mut plan.mods, &steps);
                plan.key_changes.insert(
                    key.clone(),
                    Some(KeyEntry {
                        key: key.clone(),
                        payload: object.payload.clone(),
                        name: object.name.clone(),
                        object_id: id,
                        path,
                        aabb,
                    }),
                );
                let object = Object { key: Some(key.clone()), ..object.clone() };
                plan.leaves.entry(leaf).or_default().add.push(Added { id, object });
            }
        }
    }
    Ok(Ok(plan))
}

/// The box of `object`'s geometry as a file stores it (f64 anchor, f32
/// offsets): what a reader computes from the record.
fn stored_box(object: &Object) -> Result<Aabb, StorageError> {
    let mut record = Vec::new();
    geometry::encode_object(ObjectId(0), &object.mesh, &mut record);
    Ok(geometry::decode_object(0, &record)?.1.aabb())
}

/// The path bits of `steps` from the root.
fn path_of(steps: &[PathStep]) -> TreePath {
    steps.iter().filter_map(|s| s.child).fold(TreePath::default(), |p, c| p.child(c))
}

/// Notes each record of `steps` as changed; returns the leaf's place.
fn note_path(mods: &mut HashMap<(u32, u32), Mod>, steps: &[PathStep]) -> (u32, u32) {
    let mut parent: Option<((u32, u32), usize)> = None;
    let mut at = (0, 0);
    for (depth, s) in steps.iter().enumerate() {
        at = (s.block.id(), s.offset);
        mods.entry(at).or_insert_with(|| Mod {
            block: s.block.clone(),
            offset: s.offset,
            frame: s.frame,
            parent,
            depth,
            draft: None,
            required: None,
            objects: 0,
            geometry_blocks: 0,
            node_blocks: 0,
            gone: false,
            merged_into: None,
        });
        parent = s.child.map(|c| (at, c));
    }
    at
}

/// The leaf a new object of box `aabb` goes to: from the root, the child
/// whose box holds it (the smaller when both do), else the one whose box
/// grows least (R-tree's choice of subtree).
fn choose_leaf(
    r: &ReadTransaction,
    meta: &Meta,
    aabb: &Aabb,
    reads: &mut Reads,
) -> Result<Vec<PathStep>, StorageError> {
    let root = r.root().ok_or_else(|| StorageError::Invalid("the file holds no tree".into()))?;
    let mut block = r.block(root.block, BlockType::Node, root.checksum, reads)?;
    let (mut offset, mut bound) = (root.offset, root.aabb);
    let mut steps = Vec::new();
    for _ in 0..=meta.depth {
        let record = view(&block, offset)?;
        let frame = record.frame(bound);
        match record {
            NodeView::Leaf(_) => {
                steps.push(PathStep { block, offset, frame, child: None });
                return Ok(steps);
            }
            NodeView::Internal(n) => {
                let boxes = [0, 1].map(|c| n.child_box(c, &frame).map(|q| q.outer));
                let cost = |c: usize| -> (bool, f64, f64) {
                    let b = boxes[c].unwrap_or(Aabb::EMPTY);
                    let grown = b.union(aabb);
                    (!b.contains(aabb), grown.volume() - b.volume(), b.volume())
                };
                let c = if cost(1).partial_cmp(&cost(0)) == Some(std::cmp::Ordering::Less) { 1 } else { 0 };
                let next = boxes[c].ok_or_else(|| {
                    StorageError::corrupt(block.id(), "child_box", "a child box is backwards")
                })?;
                let at = n.child_ref(c);
                let child = r.node_block(&block, at, reads)?;
                steps.push(PathStep { block, offset, frame, child: Some(c) });
                (block, offset, bound) = (child, at.offset, next);
            }
        }
    }
    Err(StorageError::corrupt(meta.root_block, "depth", "a path longer than the tree is deep"))
}

/// A leaf's entry as the commit rewrites it: its object, its record, its
/// box as stored, and its bounds.
#[derive(Clone)]
struct NewEntry {
    id: u32,
    record: Vec<u8>,
    /// The box of the entry's triangles, from its record.
    aabb: Aabb,
    /// The entry's box as the old leaf held it, for a kept entry.
    old_q: Option<[u16; 6]>,
    bounds: Vec<BoundEntry>,
}

impl WriteTransaction<'_> {
    /// The new record and geometry of leaf `at` with `edit` applied.
    #[allow(clippy::too_many_arguments)]
    fn rewrite_leaf(
        &mut self,
        r: &ReadTransaction,
        mods: &mut HashMap<(u32, u32), Mod>,
        at: (u32, u32),
        edit: &LeafEdit,
        key_changes: &mut BTreeMap<Key, Option<KeyEntry>>,
        reads: &mut Reads,
        deltas: &mut Deltas,
        freed: &mut Vec<u32>,
    ) -> Step<()> {
        let pager = self.inner.pager().clone();
        let bs = pager.block_size();
        let p = geometry::payload(bs);
        let md = &mods[&at];
        let (block, frame) = (md.block.clone(), md.frame);
        let NodeView::Leaf(leaf) = view(&block, md.offset)? else {
            return Err(StorageError::corrupt(block.id(), "path", "a path ends at no leaf").into());
        };
        let (first_block, sums) = leaf.geometry();
        let sums: Vec<u32> = sums.collect();
        let old_frame = view(&block, md.offset)?.own_frame();
        let mut keys = leaf.keys().map(|(_, k)| k.to_key());
        let mut entries: Vec<NewEntry> = Vec::new();
        let mut kept_keys: Vec<Key> = Vec::new();
        let mut removed_objects = 0i64;
        let mut last_id = None;
        for i in 0..leaf.len() {
            let o = leaf
                .object(i)
                .ok_or_else(|| StorageError::corrupt(block.id(), "objects", "an entry is missing"))?;
            let first_of_object = last_id != Some(o.object_id);
            last_id = Some(o.object_id);
            let key = if first_of_object { keys.next() } else { None };
            let (_, mesh) = r.read_object(block.id(), &leaf, i, reads)?;
            let record_len = geometry::record_len(&mesh) as i64;
            if edit.remove.contains(&o.object_id) {
                deltas.geometry_bytes -= record_len;
                deltas.triangles -= mesh.triangle_count() as i64;
                deltas.vertices -= mesh.vertex_count() as i64;
                if first_of_object {
                    removed_objects += 1;
                }
                for b in leaf.bounds().filter(|b| usize::from(b.target) == i) {
                    let k = usize::from(b.level) - 1;
                    if let Some(u) = deltas.lod_usage.get_mut(k) {
                        u[0] -= b.blob.len() as i64;
                        u[1] -= 1;
                    }
                }
                continue;
            }
            if let Some(k) = key {
                kept_keys.push(k);
            }
            let mut record = Vec::new();
            geometry::encode_object(ObjectId(o.object_id), &mesh, &mut record);
            let bounds = leaf
                .bounds()
                .filter(|b| usize::from(b.target) == i)
                .map(|b| BoundEntry { target: 0, level: b.level, blob: b.blob.to_vec() })
                .collect();
            entries.push(NewEntry {
                id: o.object_id,
                record,
                aabb: mesh.aabb(),
                old_q: Some(o.qbox),
                bounds,
            });
        }
        let mut keys = kept_keys;
        for a in &edit.add {
            let pieces = if geometry::record_len(&a.object.mesh) <= p {
                vec![a.object.mesh.clone()]
            } else {
                geometry::parts(&a.object.mesh, p, p)
            };
            for mesh in pieces {
                let mut record = Vec::new();
                geometry::encode_object(ObjectId(a.id), &mesh, &mut record);
                let stored = geometry::decode_object(0, &record)?.1;
                deltas.geometry_bytes += record.len() as i64;
                deltas.triangles += stored.triangle_count() as i64;
                deltas.vertices += stored.vertex_count() as i64;
                entries.push(NewEntry {
                    id: a.id,
                    record,
                    aabb: stored.aabb(),
                    old_q: None,
                    bounds: Vec::new(),
                });
            }
            keys.push(
                a.object
                    .key
                    .clone()
                    .ok_or_else(|| StorageError::Invalid("an object without a key".into()))?,
            );
        }
        if entries.is_empty() {
            freed.extend((0..sums.len() as u32).map(|j| first_block + j));
            deltas.geometry_blocks -= sums.len() as i64;
            deltas.objects -= removed_objects;
            let gone = Gone { objects: removed_objects, geometry_blocks: sums.len() as i64 };
            return self.merge_with_sibling(r, mods, at, gone, key_changes, reads, deltas);
        }
        // The frame stays when what is added lies in it; else it grows, and
        // every entry is quantized anew in the leaf's own frame (their
        // bounds, drawn on the grid around the old boxes, go).
        let added = entries.iter().filter(|e| e.old_q.is_none()).fold(Aabb::EMPTY, |b, e| b.union(&e.aabb));
        let (new_frame, requantize) = if added.is_empty() || frame.contains(&added) {
            (old_frame, false)
        } else {
            (Some(frame.union(&added)), true)
        };
        let quant_frame = new_frame.unwrap_or(frame);
        let node_id = view(&block, mods[&at].offset)?.node_id();
        let objects_held = keys.len() as u64;
        let (mut draft, dropped, drawn) = leaf_draft(
            &entries,
            keys.clone(),
            node_id,
            new_frame,
            &quant_frame,
            requantize,
            deltas.rules.as_ref(),
            bs,
        )?;
        // A leaf grows to twice its bulk load's capacity at most (its reads
        // with it), and its record must fit a node block; past either, it
        // splits as its file's method splits (format-spec/commit.md, "Splits").
        let RecordDraft::Leaf { end, .. } = &draft else {
            return Err(StorageError::Invalid("a leaf drafted as an internal record".into()).into());
        };
        let params = r.info().and_then(|i| i.params);
        let over = match params.as_ref().map(|p| p.leaf) {
            Some(crate::bulk::LeafRule::Objects(n)) => objects_held > 2 * u64::from(n),
            Some(crate::bulk::LeafRule::Bytes { capacity }) => *end > 2 * capacity.max(p),
            None => end.div_ceil(p) > 4,
        };
        let (span, node_blocks) = if (over || draft.encoded_len() > node::capacity(bs)) && objects_held > 1 {
            let Some(params) = params else { return Ok(Err(Structural)) };
            let split = SplitLeaf { params: &params, frame: quant_frame, own_frame: new_frame, node_id };
            let Ok(sub) = self.split_leaf(split, entries, keys, deltas)? else { return Ok(Err(Structural)) };
            let depth = mods[&at].depth as u32 + sub.levels;
            deltas.depth = deltas.depth.max(depth);
            draft = sub.root;
            (sub.geometry_blocks, sub.node_blocks)
        } else {
            if draft.encoded_len() > node::capacity(bs) {
                return Ok(Err(Structural));
            }
            for (level, len) in dropped {
                deltas.drop_bound(level, len);
            }
            for (level, len, diag) in drawn {
                deltas.add_bound(level, len, diag);
            }
            (self.write_span(&entries, &mut draft)?, 0)
        };
        freed.extend((0..sums.len() as u32).map(|j| first_block + j));
        deltas.geometry_blocks += span as i64 - sums.len() as i64;
        let md =
            mods.get_mut(&at).ok_or_else(|| StorageError::Invalid("a changed leaf is not noted".into()))?;
        md.required = if requantize { new_frame } else { None };
        md.objects = edit.add.len() as i64 - removed_objects;
        md.geometry_blocks = span as i64 - sums.len() as i64;
        md.node_blocks = i64::from(node_blocks);
        md.draft = Some(draft);
        deltas.objects += md.objects;
        Ok(Ok(()))
    }

    /// Merges emptied leaf `at` with its sibling, when the sibling is a
    /// record the commit does not otherwise change, a leaf or a subtree of
    /// at most [`MERGE_SUBTREE_OBJECTS`] objects (format-spec/commit.md,
    /// "Merges"): the parent's record becomes the sibling's, with the
    /// sibling's frame as its own, and the sibling's objects' key entries
    /// lead to the parent. Any other empty leaf needs the tree written whole.
    #[allow(clippy::too_many_arguments)]
    fn merge_with_sibling(
        &mut self,
        r: &ReadTransaction,
        mods: &mut HashMap<(u32, u32), Mod>,
        at: (u32, u32),
        gone: Gone,
        key_changes: &mut BTreeMap<Key, Option<KeyEntry>>,
        reads: &mut Reads,
        deltas: &mut Deltas,
    ) -> Step<()> {
        let Some((parent_at, c)) = mods[&at].parent else { return Ok(Err(Structural)) };
        let parent = &mods[&parent_at];
        let (parent_block, parent_frame, parent_depth) = (parent.block.clone(), parent.frame, parent.depth);
        let NodeView::Internal(n) = view(&parent_block, parent.offset)? else {
            return Err(
                StorageError::corrupt(parent_block.id(), "path", "a leaf above a changed record").into()
            );
        };
        let node_id = view(&parent_block, parent.offset)?.node_id();
        let sib = n.child_ref(1 - c);
        let sib_at = (if sib.block == 0 { parent_block.id() } else { sib.block }, sib.offset);
        if mods.contains_key(&sib_at) {
            return Ok(Err(Structural));
        }
        let sib_block = r.node_block(&parent_block, sib, reads)?;
        let record = view(&sib_block, sib.offset)?;
        if matches!(record, NodeView::Internal(_)) && record.object_count() > MERGE_SUBTREE_OBJECTS {
            return Ok(Err(Structural));
        }
        // A child block the sibling names from its own block is named from
        // the parent's block after the merge: only if no other record of the
        // sibling's block names it too, since a block has one parent block
        // (format-spec/node.md, "Packing").
        if let NodeView::Internal(s) = &record
            && sib_block.id() != parent_block.id()
        {
            for i in 0..2 {
                let named = s.child_ref(i).block;
                if named == 0 {
                    continue;
                }
                for &o in sib_block.records.iter().filter(|&&o| o != sib.offset) {
                    if let NodeView::Internal(other) = view(&sib_block, o)?
                        && (0..2).any(|j| other.child_ref(j).block == named)
                    {
                        return Ok(Err(Structural));
                    }
                }
            }
        }
        let q = n
            .child_box(1 - c, &parent_frame)
            .ok_or_else(|| StorageError::corrupt(parent_block.id(), "child_box", "backwards"))?;
        let sib_frame = record.frame(q.outer);
        // The sibling's objects' paths ran through it: they end at the parent now.
        for key in subtree_keys(r, &sib_block, sib.offset, reads)? {
            let Some(mut e) = r.key_entry(&key, reads)? else {
                return Err(StorageError::corrupt(
                    sib_block.id(),
                    "keys",
                    format!("key {key} is not in the key index"),
                )
                .into());
            };
            if usize::from(e.path.len) > parent_depth {
                e.path = e.path.truncated(parent_depth);
                key_changes.insert(key, Some(e));
            }
        }
        let mut draft = record.to_draft();
        match &mut draft {
            RecordDraft::Leaf { node_id: id, frame, .. } => (*id, *frame) = (node_id, Some(sib_frame)),
            RecordDraft::Internal { node_id: id, frame, children, .. } => {
                (*id, *frame) = (node_id, Some(sib_frame));
                // Its children in its own block are named from the parent's
                // block now: by that block, which is written anew below, and
                // which reaching them now reads.
                if sib_block.id() != parent_block.id() {
                    for ch in children.iter_mut().filter(|ch| ch.at.block == 0) {
                        ch.at = RecordRef {
                            block: sib_block.id(),
                            checksum: sib_block.checksum,
                            offset: ch.at.offset,
                        };
                        ch.node_blocks = ch.node_blocks.saturating_add(1);
                    }
                }
            }
        }
        for (place, parent_entry) in [(at, (parent_at, c)), (sib_at, (parent_at, 1 - c))] {
            let md = mods.entry(place).or_insert_with(|| Mod {
                block: sib_block.clone(),
                offset: place.1,
                frame: sib_frame,
                parent: Some(parent_entry),
                depth: parent_depth + 1,
                draft: None,
                required: None,
                objects: 0,
                geometry_blocks: 0,
                node_blocks: 0,
                gone: false,
                merged_into: None,
            });
            (md.gone, md.draft) = (true, None);
            md.merged_into = (place == sib_at).then_some(parent_at);
        }
        let md = mods
            .get_mut(&parent_at)
            .ok_or_else(|| StorageError::Invalid("a changed record vanished".into()))?;
        // The frame its entries are quantized in is the sibling's now (what a
        // parent growing around it must give it as its own).
        (md.draft, md.frame) = (Some(draft), sib_frame);
        md.objects = -gone.objects;
        md.geometry_blocks = -gone.geometry_blocks;
        deltas.nodes -= 2;
        deltas.leaves -= 1;
        deltas.new_ids = true;
        Ok(Ok(()))
    }

    /// Writes the geometry records of `entries` at the positions `draft`
    /// (a leaf) gives them, in a span of blocks of their own, and sets the
    /// draft's span; returns its blocks.
    fn write_span(&mut self, entries: &[NewEntry], draft: &mut RecordDraft) -> Result<u64, StorageError> {
        let RecordDraft::Leaf { first_block, checksums, objects, end, .. } = draft else {
            return Err(StorageError::Invalid("a span for an internal record".into()));
        };
        let pager = self.inner.pager().clone();
        let bs = pager.block_size();
        let p = geometry::payload(bs);
        let span = end.div_ceil(p);
        let first = self.allocate(u32::try_from(span).map_err(|_| StorageError::FileTooLarge)?)?;
        checksums.clear();
        let mut blockbuf = vec![0u8; bs as usize];
        for (e, o) in entries.iter().zip(objects.iter()) {
            // Records were placed on this stream; lay each one's bytes.
            let mut at = o.position;
            let mut rest = &e.record[..];
            while !rest.is_empty() {
                let b = at / p;
                while checksums.len() as u64 != b {
                    let id = first + checksums.len() as u32;
                    checksums.push(self.put(id, &mut blockbuf, BlockType::Geometry)?);
                    blockbuf.fill(0);
                }
                let off = (at % p) as usize;
                let take = rest.len().min(p as usize - off);
                blockbuf[FRAME_LEN + off..FRAME_LEN + off + take].copy_from_slice(&rest[..take]);
                rest = &rest[take..];
                at += take as u64;
            }
        }
        while (checksums.len() as u64) < span {
            let id = first + checksums.len() as u32;
            checksums.push(self.put(id, &mut blockbuf, BlockType::Geometry)?);
            blockbuf.fill(0);
        }
        *first_block = first;
        Ok(span)
    }

    /// The new record of internal node `at`, whose changed children are
    /// made: their boxes, object counts and geometry counts; a frame of its
    /// own when a child's box no longer fits its frame (and one for the
    /// unchanged sibling then). Returns the root's new frame when the root's grew.
    fn rewrite_internal(
        &mut self,
        r: &ReadTransaction,
        mods: &mut HashMap<(u32, u32), Mod>,
        at: (u32, u32),
        reads: &mut Reads,
    ) -> Result<Option<Aabb>, crate::Error> {
        let md = &mods[&at];
        let (block, frame, is_root) = (md.block.clone(), md.frame, md.parent.is_none());
        let record = view(&block, md.offset)?;
        let NodeView::Internal(n) = record else {
            return Err(StorageError::corrupt(block.id(), "path", "a leaf above a changed record").into());
        };
        let RecordDraft::Internal { node_id, object_count, split, mut children, frame: own } =
            record.to_draft()
        else {
            return Err(StorageError::Invalid("an internal record drafted as a leaf".into()).into());
        };
        // Each child's place, and whether it changed.
        let places: [(u32, u32); 2] = [0, 1].map(|c| {
            let a = n.child_ref(c);
            (if a.block == 0 { block.id() } else { a.block }, a.offset)
        });
        let mut need = Aabb::EMPTY;
        let (mut objects, mut geometry, mut node_blocks) = (0i64, 0i64, 0i64);
        for (c, place) in places.iter().enumerate() {
            if let Some(child) = mods.get(place).filter(|x| x.parent.map(|p| p.0) == Some(at)) {
                if let Some(b) = child.required {
                    need = need.union(&b);
                }
                objects += child.objects;
                geometry += child.geometry_blocks;
                node_blocks += child.node_blocks;
                children[c].geometry_blocks =
                    apply(u64::from(children[c].geometry_blocks), child.geometry_blocks)?
                        .try_into()
                        .map_err(|_| StorageError::FileTooLarge)?;
                children[c].node_blocks = apply(u64::from(children[c].node_blocks), child.node_blocks)?
                    .try_into()
                    .map_err(|_| StorageError::FileTooLarge)?;
            }
        }
        let grows = !need.is_empty() && !frame.contains(&need);
        let new_frame = if grows { frame.union(&need) } else { frame };
        for (c, place) in places.iter().enumerate() {
            let changed = mods.get(place).is_some_and(|x| x.parent.map(|p| p.0) == Some(at));
            if changed {
                let child = &mods[place];
                match child.required {
                    Some(b) => children[c].qbox = quantize(&new_frame, &b),
                    None if grows => {
                        // The child keeps its frame as its own; the entry is quantized anew.
                        let old = child.frame;
                        let child = mods
                            .get_mut(place)
                            .ok_or_else(|| StorageError::Invalid("a child vanished".into()))?;
                        set_own_frame(child.draft.as_mut(), old);
                        children[c].qbox = quantize(&new_frame, &old);
                    }
                    None => {}
                }
            } else if grows {
                // An unchanged sibling: its entry is quantized anew around
                // its frame, which it keeps (its own, or the one it had).
                let q = n
                    .child_box(c, &frame)
                    .ok_or_else(|| StorageError::corrupt(block.id(), "child_box", "backwards"))?;
                let sib_block = r.node_block(&block, n.child_ref(c), reads)?;
                let sib = view(&sib_block, place.1)?;
                let sib_frame = sib.frame(q.outer);
                if sib.own_frame().is_none() {
                    let mut draft = sib.to_draft();
                    set_own_frame(Some(&mut draft), sib_frame);
                    mods.insert(
                        *place,
                        Mod {
                            block: sib_block,
                            offset: place.1,
                            frame: sib_frame,
                            parent: Some((at, c)),
                            depth: mods[&at].depth + 1,
                            draft: Some(draft),
                            required: None,
                            objects: 0,
                            geometry_blocks: 0,
                            node_blocks: 0,
                            gone: false,
                            merged_into: None,
                        },
                    );
                }
                children[c].qbox = quantize(&new_frame, &sib_frame);
            }
        }
        let object_count = u32::try_from(apply(u64::from(object_count), objects)?)
            .map_err(|_| StorageError::FileTooLarge)?;
        let (own, required, root_frame) = match (grows, is_root) {
            (false, _) => (own, None, None),
            // The root's frame is the scene box, which grows with it.
            (true, true) => (None, None, Some(new_frame)),
            (true, false) => (Some(new_frame), Some(new_frame), None),
        };
        let md =
            mods.get_mut(&at).ok_or_else(|| StorageError::Invalid("a changed record vanished".into()))?;
        md.draft = Some(RecordDraft::Internal { node_id, object_count, split, children, frame: own });
        md.required = required;
        md.objects = objects;
        md.geometry_blocks = geometry;
        md.node_blocks = node_blocks;
        Ok(root_frame)
    }

    /// Writes every node block holding a changed record, children's blocks
    /// before their parent's (one parent block each, format-spec/node.md,
    /// "Packing"); returns where the root went.
    fn rewrite_blocks(
        &mut self,
        mods: &mut HashMap<(u32, u32), Mod>,
        root_at: (u32, u32),
        bs: u32,
        deltas: &mut Deltas,
        freed: &mut Vec<u32>,
    ) -> Step<RecordRef> {
        let capacity = node::capacity(bs);
        // Each changed block, its parent block, and its old bytes.
        let mut blocks: HashMap<u32, Arc<Block>> = HashMap::default();
        let mut parent_block: HashMap<u32, u32> = HashMap::default();
        for md in mods.values() {
            blocks.insert(md.block.id(), md.block.clone());
            if let Some((p, _)) = md.parent
                && p.0 != md.block.id()
            {
                parent_block.insert(md.block.id(), p.0);
            }
        }
        // Children blocks first: deeper blocks (more parent blocks above) first.
        let depth = |mut b: u32| {
            let mut d = 0;
            while let Some(&p) = parent_block.get(&b) {
                b = p;
                d += 1;
                if d > blocks.len() {
                    break;
                }
            }
            d
        };
        let mut order: Vec<u32> = blocks.keys().copied().collect();
        order.sort_by_key(|&b| (std::cmp::Reverse(depth(b)), b));
        let mut relocated: HashMap<(u32, u32), RecordRef> = HashMap::default();
        // Node blocks records outside the changed paths gain below them (leaves moved out).
        let mut extra: HashMap<(u32, u32), [u32; 2]> = HashMap::default();
        for b in order {
            let old = blocks[&b].clone();
            // The block's records, as they will be written: changed ones and
            // internal ones (whose child offsets may move) as drafts, the
            // unchanged leaves as their stored bytes.
            let mut drafts: Vec<(u32, Rec)> = Vec::with_capacity(old.records.len());
            for &o in &old.records {
                if mods.get(&(b, o)).is_some_and(|x| x.gone) {
                    continue;
                }
                let d = match mods.get(&(b, o)).and_then(|x| x.draft.clone()) {
                    Some(d) => Rec::Draft(d),
                    None => match view(&old, o)? {
                        v @ NodeView::Leaf(_) => Rec::Stored(
                            v.stored_bytes(old.bytes(), o)
                                .map_err(|d| StorageError::corrupt(b, "record", d))?,
                        ),
                        v @ NodeView::Internal(_) => {
                            let mut d = v.to_draft();
                            if let (Some(more), RecordDraft::Internal { children, .. }) =
                                (extra.get(&(b, o)), &mut d)
                            {
                                for (c, m) in children.iter_mut().zip(more) {
                                    c.node_blocks = c.node_blocks.saturating_add(*m);
                                }
                            }
                            Rec::Draft(d)
                        }
                    },
                };
                drafts.push((o, d));
            }
            // A block that no longer holds its records (a leaf grew, records
            // took frames of their own) moves its largest leaves out, to new
            // blocks they share: a leaf has no children, so no other block's
            // parent block changes.
            let mut moved: Vec<u32> = Vec::new();
            let mut total: usize = drafts.iter().map(|(_, d)| d.part().encoded_len()).sum();
            while total > capacity {
                let candidate = drafts
                    .iter()
                    .filter(|(o, d)| d.is_leaf() && !moved.contains(o))
                    .max_by_key(|(_, d)| d.part().encoded_len())
                    .map(|(o, d)| (*o, d.part().encoded_len()));
                let Some((o, len)) = candidate else { return Ok(Err(Structural)) };
                moved.push(o);
                total -= len;
                // Every entry above it now reaches one more node block.
                let mut at = (b, o);
                while let Some((p, c)) = match mods.get(&at) {
                    Some(x) => x.parent,
                    None if at == root_at => None,
                    None => Some(parent_record(&blocks, &parent_block, at)?),
                } {
                    // A child of a merged sibling counts under the record in its parent's place.
                    let p = mods.get(&p).and_then(|x| x.merged_into).unwrap_or(p);
                    if let Some(RecordDraft::Internal { children, .. }) =
                        mods.get_mut(&p).and_then(|x| x.draft.as_mut())
                    {
                        children[c].node_blocks = children[c].node_blocks.saturating_add(1);
                    } else if p.0 == b {
                        if let Some((_, Rec::Draft(RecordDraft::Internal { children, .. }))) =
                            drafts.iter_mut().find(|(x, _)| *x == p.1)
                        {
                            children[c].node_blocks = children[c].node_blocks.saturating_add(1);
                        }
                    } else {
                        extra.entry(p).or_insert([0; 2])[c] += 1;
                    }
                    at = p;
                }
            }
            // The counts above changed drafts of this block too: take them again.
            for (o, d) in &mut drafts {
                if let Some(x) = mods.get(&(b, *o)).and_then(|x| x.draft.clone()) {
                    *d = Rec::Draft(x);
                }
            }
            // The moved leaves whose parents stay in this block share new
            // blocks, first fit, so that each new block is named from this
            // one only ([node.md], "Packing"); a leaf named from another
            // block moves alone. The counts above took one block per leaf,
            // which stays an upper bound.
            let named_here = |o: u32| {
                drafts.iter().any(|(_, d)| match d {
                    Rec::Draft(RecordDraft::Internal { children, .. }) => {
                        children.iter().any(|c| c.at.offset == o && (c.at.block == 0 || c.at.block == b))
                    }
                    _ => false,
                })
            };
            let mut bins: Vec<(usize, Vec<u32>)> = Vec::new();
            for &o in &moved {
                let Some((_, d)) = drafts.iter().find(|(x, _)| *x == o) else { continue };
                let len = d.part().encoded_len();
                let shared = named_here(o);
                match bins.iter_mut().find(|(used, records)| {
                    shared && used + len <= capacity && records.iter().all(|&r| named_here(r))
                }) {
                    Some((used, records)) => {
                        *used += len;
                        records.push(o);
                    }
                    None => bins.push((len, vec![o])),
                }
            }
            for (used, records) in &bins {
                let parts: Vec<RecordPart> = records
                    .iter()
                    .filter_map(|o| drafts.iter().find(|(x, _)| x == o))
                    .map(|(_, d)| d.part())
                    .collect();
                let id = self.allocate(1)?;
                let mut bytes = vec![0u8; bs as usize];
                let offsets = node::encode_block_parts(&parts, &mut bytes).map_err(StorageError::Invalid)?;
                let checksum = self.put(id, &mut bytes, BlockType::Node)?;
                deltas.node_bytes += *used as i64;
                deltas.node_blocks += 1;
                for (&o, offset) in records.iter().zip(offsets) {
                    relocated.insert((b, o), RecordRef { block: id, checksum, offset });
                }
            }
            drafts.retain(|(o, _)| !moved.contains(o));
            // New offsets, then every reference: within the block, to moved
            // records, and to the children's rewritten blocks.
            let mut new_offset: HashMap<u32, u32> = HashMap::default();
            let mut at = node::RECORDS_START as u32;
            for (o, d) in &drafts {
                new_offset.insert(*o, at);
                at += d.part().encoded_len() as u32;
            }
            for (_, d) in &mut drafts {
                if let Rec::Draft(RecordDraft::Internal { children, .. }) = d {
                    for c in children.iter_mut() {
                        let target =
                            if c.at.block == 0 { (b, c.at.offset) } else { (c.at.block, c.at.offset) };
                        if let Some(r) = relocated.get(&target) {
                            c.at = *r;
                        } else if c.at.block == 0 {
                            let o = new_offset.get(&c.at.offset).ok_or_else(|| {
                                StorageError::corrupt(
                                    b,
                                    "child_offset",
                                    "a child that is no record of its block",
                                )
                            })?;
                            c.at = RecordRef { block: 0, checksum: 0, offset: *o };
                        }
                    }
                }
            }
            let records: Vec<RecordPart> = drafts.iter().map(|(_, d)| d.part()).collect();
            freed.push(b);
            // Its group bounds go with it: the subtrees below a rewritten
            // block changed, and the block written anew names no group block.
            if let Some((g, _)) = node::group_ref(old.bytes()) {
                freed.push(g);
            }
            if records.is_empty() {
                // Its records left the tree with a merge, and no record names the block.
                deltas.node_blocks -= 1;
                deltas.node_bytes -= old_used(&old);
                continue;
            }
            let id = self.allocate(1)?;
            let mut bytes = vec![0u8; bs as usize];
            node::encode_block_parts(&records, &mut bytes).map_err(StorageError::Invalid)?;
            let checksum = self.put(id, &mut bytes, BlockType::Node)?;
            let used = records.iter().map(RecordPart::encoded_len).sum::<usize>() as i64;
            deltas.node_bytes += used - old_used(&old);
            for (o, _) in &drafts {
                relocated.insert((b, *o), RecordRef { block: id, checksum, offset: new_offset[o] });
            }
        }
        let root = relocated
            .get(&root_at)
            .copied()
            .ok_or_else(|| StorageError::Invalid("the root's block was not rewritten".into()))?;
        Ok(Ok(root))
    }
}

/// A record of a node block being rewritten: a draft, or an unchanged
/// leaf's stored bytes (in the old block, which the caller holds).
enum Rec<'a> {
    Draft(RecordDraft),
    Stored(&'a [u8]),
}

impl Rec<'_> {
    fn part(&self) -> RecordPart<'_> {
        match self {
            Rec::Draft(d) => RecordPart::Draft(d),
            Rec::Stored(b) => RecordPart::StoredLeaf(b),
        }
    }

    fn is_leaf(&self) -> bool {
        matches!(self, Rec::Stored(_) | Rec::Draft(RecordDraft::Leaf { .. }))
    }
}

/// A drafted leaf record, the bounds it drops as (level, bytes) and those
/// it draws as (level, bytes, cell diagonal).
type LeafDraft = (RecordDraft, Vec<(u8, usize)>, Vec<(u8, usize, f64)>);

/// A leaf record of `entries` (each object's parts adjacent; `keys` one per
/// object), quantized in `frame`, its span not yet written; the bounds it
/// drops as (level, bytes); and those it draws as (level, bytes, cell
/// diagonal). A kept entry keeps its bounds unless `requantize`; then
/// they are drawn anew at the same levels on the grid around the entry's
/// new box (a bound is drawn on the grid around its entry's box as the
/// record holds it). A new entry gets a bound at each level most of the
/// leaf's kept entries have one: where the read model found bounds paid
/// for these objects' neighbours (format-spec/commit.md, "Levels of detail").
#[allow(clippy::too_many_arguments)]
fn leaf_draft(
    entries: &[NewEntry],
    keys: Vec<Key>,
    node_id: u32,
    own_frame: Option<Aabb>,
    frame: &Aabb,
    requantize: bool,
    rules: Option<&(LodPlan, LodParams)>,
    bs: u32,
) -> Result<LeafDraft, StorageError> {
    let mut placement = Placement::new(bs);
    let mut objects = Vec::with_capacity(entries.len());
    let mut bounds = Vec::new();
    let mut dropped = Vec::new();
    let mut drawn = Vec::new();
    let kept = entries.iter().filter(|e| e.old_q.is_some()).count();
    let mut held = [0usize; 16];
    for b in entries.iter().filter(|e| e.old_q.is_some()).flat_map(|e| &e.bounds) {
        if let Some(n) = held.get_mut(usize::from(b.level)) {
            *n += 1;
        }
    }
    let usual: Vec<u8> = (0..held.len() as u8).filter(|&k| 2 * held[usize::from(k)] > kept).collect();
    for (j, e) in entries.iter().enumerate() {
        let position = placement.place(e.record.len() as u64);
        let qbox = match (requantize, e.old_q) {
            (false, Some(q)) => q,
            _ => quantize(frame, &e.aabb),
        };
        objects.push(ObjectEntry { object_id: e.id, qbox, position });
        let target =
            u16::try_from(j).map_err(|_| StorageError::Invalid("a leaf of too many entries".into()))?;
        if !requantize && e.old_q.is_some() {
            bounds.extend(e.bounds.iter().map(|b| BoundEntry {
                target,
                level: b.level,
                blob: b.blob.clone(),
            }));
            continue;
        }
        dropped.extend(e.bounds.iter().map(|b| (b.level, b.blob.len())));
        let levels: Vec<u8> =
            if e.old_q.is_some() { e.bounds.iter().map(|b| b.level).collect() } else { usual.clone() };
        let Some((plan, params)) = rules.filter(|_| !levels.is_empty()) else { continue };
        let Some(outer) = QuantBox::decode(frame, qbox).map(|q| q.outer) else { continue };
        let mesh = geometry::decode_object(0, &e.record)?.1;
        for level in levels {
            let grid = bound_grid(plan, params, level, &outer)
                .map_err(|err| StorageError::Invalid(format!("a bound's grid: {err}")))?
                .filter(|g| g.cells() <= u64::from(u16::MAX));
            let Some(grid) = grid else { continue };
            let voxels = Voxels::of_surfaces(grid, [&mesh]);
            let blob = lod::encode(&voxels);
            if blob.len() <= node::MAX_BOUND_BYTES {
                drawn.push((level, blob.len(), voxels.grid().max_cell_diagonal()));
                bounds.push(BoundEntry { target, level, blob });
            }
        }
    }
    let end = placement.end();
    let span =
        usize::try_from(end.div_ceil(geometry::payload(bs))).map_err(|_| StorageError::FileTooLarge)?;
    let draft = RecordDraft::Leaf {
        node_id,
        frame: own_frame,
        first_block: 0,
        checksums: vec![0; span],
        objects,
        end,
        bounds,
        keys,
    };
    Ok((draft, dropped, drawn))
}

/// What a leaf split needs besides its entries.
struct SplitLeaf<'a> {
    /// The file's build: its method and leaf rule.
    params: &'a BuildParams,
    /// The frame the subtree's root quantizes its children's boxes in.
    frame: Aabb,
    /// The root's own frame, if it has one.
    own_frame: Option<Aabb>,
    /// The leaf's id, which the subtree's root keeps.
    node_id: u32,
}

/// A leaf split in place: the subtree's root record, which takes the
/// leaf's place, and what was written below it.
struct SubTree {
    root: RecordDraft,
    /// Node blocks written below the root's record.
    node_blocks: u32,
    /// Geometry blocks of its leaves.
    geometry_blocks: u64,
    /// Levels below the root.
    levels: u32,
}

impl WriteTransaction<'_> {
    /// Splits a leaf of `entries` as a bulk load of its objects with the
    /// file's parameters would (format-spec/commit.md, "Splits"): writes
    /// the new leaves' spans and every record below the subtree's root in
    /// new node blocks, each named from one parent block; the root, which
    /// takes the leaf's place and id, is returned. The entries' bounds go
    /// (they are drawn around boxes quantized in the old leaf's frame).
    fn split_leaf(
        &mut self,
        split: SplitLeaf,
        entries: Vec<NewEntry>,
        keys: Vec<Key>,
        deltas: &mut Deltas,
    ) -> Step<SubTree> {
        let pager = self.inner.pager().clone();
        let bs = pager.block_size();
        let capacity = node::capacity(bs);
        // Each object's entries: its parts are adjacent.
        let mut runs: Vec<std::ops::Range<usize>> = Vec::new();
        for (j, e) in entries.iter().enumerate() {
            match runs.last_mut() {
                Some(r) if entries[r.start].id == e.id => r.end = j + 1,
                _ => runs.push(j..j + 1),
            }
        }
        if runs.len() != keys.len() {
            return Err(StorageError::Invalid("a leaf's keys do not match its objects".into()).into());
        }
        if runs.len() < 2 {
            return Ok(Err(Structural));
        }
        let boxes: Vec<Aabb> = runs
            .iter()
            .map(|r| entries[r.clone()].iter().fold(Aabb::EMPTY, |b, e| b.union(&e.aabb)))
            .collect();
        let sizes: Vec<u64> =
            runs.iter().map(|r| entries[r.clone()].iter().map(|e| e.record.len() as u64).sum()).collect();
        let by_bytes = matches!(split.params.leaf, LeafRule::Bytes { .. });
        let mut tree = crate::bulk::build(&boxes, by_bytes.then_some(&sizes[..]), split.params, &|_| {})?;
        if tree.nodes.len() == 1 {
            // Within the file's rule, but not within a node block: halves.
            let half = u32::try_from(runs.len().div_ceil(2)).map_err(|_| StorageError::FileTooLarge)?;
            let params = BuildParams { leaf: LeafRule::Objects(half), ..split.params.clone() };
            tree = crate::bulk::build(&boxes, None, &params, &|_| {})?;
        }
        let n = tree.nodes.len();
        let kids = |i: usize| tree.nodes[i].children().map(|c| c.map(|c| c.index()));
        // Frames, parents before children (preorder): each child's box
        // quantized in its parent's frame, as a reader decodes it.
        let mut frames = vec![split.frame; n];
        let mut qboxes = vec![[0u16; 6]; n];
        for i in 0..n {
            for c in kids(i).into_iter().flatten() {
                let q = quantize(&frames[i], &tree.nodes[c].aabb);
                frames[c] = QuantBox::decode(&frames[i], q)
                    .ok_or_else(|| StorageError::Invalid("a child box is backwards".into()))?
                    .outer;
                qboxes[c] = q;
            }
        }
        let mut ids = vec![split.node_id; n];
        for id in ids.iter_mut().skip(1) {
            *id = deltas.next_node_id()?;
        }
        // Leaves: their records and spans; then internal records, children first.
        let mut drafts: Vec<Option<RecordDraft>> = vec![None; n];
        let mut objects_below = vec![0u32; n];
        let mut geometry_below = vec![0u64; n];
        for (i, node) in tree.nodes.iter().enumerate() {
            let Some(objects) = node.objects() else { continue };
            let mut sub = Vec::new();
            let mut sub_keys = Vec::with_capacity(objects.len());
            for o in objects {
                let run = runs
                    .get(o.index())
                    .ok_or_else(|| StorageError::Invalid("a split lost an object".into()))?;
                sub.extend(entries[run.clone()].iter().cloned());
                sub_keys.push(keys[o.index()].clone());
            }
            let (mut d, dropped, drawn) =
                leaf_draft(&sub, sub_keys, ids[i], None, &frames[i], true, deltas.rules.as_ref(), bs)?;
            for (level, len) in dropped {
                deltas.drop_bound(level, len);
            }
            for (level, len, diag) in drawn {
                deltas.add_bound(level, len, diag);
            }
            if d.encoded_len() > capacity {
                return Ok(Err(Structural));
            }
            geometry_below[i] = self.write_span(&sub, &mut d)?;
            objects_below[i] = objects.len() as u32;
            drafts[i] = Some(d);
        }
        for i in (0..n).rev() {
            let Some([a, b]) = kids(i) else { continue };
            objects_below[i] = objects_below[a] + objects_below[b];
            geometry_below[i] = geometry_below[a] + geometry_below[b];
            let s =
                tree.nodes[i].split().ok_or_else(|| StorageError::Invalid("a node with no split".into()))?;
            let child = |c: usize| -> Result<ChildEntry, StorageError> {
                Ok(ChildEntry {
                    qbox: qboxes[c],
                    at: RecordRef { block: 0, checksum: 0, offset: 0 },
                    node_blocks: 0,
                    geometry_blocks: u32::try_from(geometry_below[c])
                        .map_err(|_| StorageError::FileTooLarge)?,
                })
            };
            drafts[i] = Some(RecordDraft::Internal {
                node_id: ids[i],
                object_count: objects_below[i],
                split: split_info(s),
                children: [child(a)?, child(b)?],
                frame: if i == 0 { split.own_frame } else { None },
            });
        }
        let mut drafts: Vec<RecordDraft> = drafts
            .into_iter()
            .collect::<Option<_>>()
            .ok_or_else(|| StorageError::Invalid("a split node with no record".into()))?;
        // The root stays in the leaf's block, alone in its piece; the rest
        // is packed as a bulk load packs (store/layout.rs).
        let mut sizes: Vec<usize> = drafts.iter().map(RecordDraft::encoded_len).collect();
        sizes[0] = capacity;
        let packing = layout::pack(&sizes, kids, capacity, capacity);
        let root_block = packing.place[0].0 as usize;
        if packing.blocks[root_block].len() != 1 {
            return Err(StorageError::Invalid("a split's root shares its piece".into()).into());
        }
        // Each node's blocks in its subtree, for its parent's entry.
        let mut below: Vec<BTreeSet<u32>> = vec![BTreeSet::new(); n];
        for i in (0..n).rev() {
            let mut set = BTreeSet::from([packing.place[i].0]);
            for c in kids(i).into_iter().flatten() {
                set.extend(below[c].iter().copied());
            }
            below[i] = set;
        }
        // Blocks whose records lie deeper first: a block's children blocks before it.
        let mut order: Vec<usize> = (0..packing.blocks.len()).filter(|&b| b != root_block).collect();
        let min_level = |b: usize| packing.blocks[b].iter().map(|&i| tree.nodes[i as usize].level).min();
        order.sort_by_key(|&b| std::cmp::Reverse(min_level(b)));
        let mut refs: Vec<Option<RecordRef>> = vec![None; n];
        for b in order.iter().copied().chain([root_block]) {
            let nodes: Vec<usize> = packing.blocks[b].iter().map(|&i| i as usize).collect();
            let mut offset = HashMap::default();
            let mut at = node::RECORDS_START as u32;
            for &i in &nodes {
                offset.insert(i, at);
                at += drafts[i].encoded_len() as u32;
            }
            for &i in &nodes {
                let Some(cs) = kids(i) else { continue };
                let RecordDraft::Internal { children, .. } = &mut drafts[i] else { continue };
                for (entry, c) in children.iter_mut().zip(cs) {
                    let (cb, _) = packing.place[c];
                    entry.at = if cb as usize == b {
                        RecordRef { block: 0, checksum: 0, offset: offset[&c] }
                    } else {
                        refs[c].ok_or_else(|| StorageError::Invalid("a child block is not written".into()))?
                    };
                    entry.node_blocks = below[c].iter().filter(|&&x| x as usize != b).count() as u32;
                }
            }
            if b == root_block {
                break;
            }
            let records: Vec<RecordDraft> = nodes.iter().map(|&i| drafts[i].clone()).collect();
            let id = self.allocate(1)?;
            let mut bytes = vec![0u8; bs as usize];
            node::encode_block(&records, &mut bytes).map_err(StorageError::Invalid)?;
            let checksum = self.put(id, &mut bytes, BlockType::Node)?;
            for &i in &nodes {
                refs[i] = Some(RecordRef { block: id, checksum, offset: offset[&i] });
            }
            deltas.node_bytes += records.iter().map(RecordDraft::encoded_len).sum::<usize>() as i64;
        }
        let leaves = tree.leaves().count() as i64;
        deltas.nodes += n as i64 - 1;
        deltas.leaves += leaves - 1;
        deltas.node_blocks += order.len() as i64;
        Ok(Ok(SubTree {
            root: drafts.swap_remove(0),
            node_blocks: order.len() as u32,
            geometry_blocks: geometry_below[0],
            levels: tree.depth().saturating_sub(1),
        }))
    }
}

/// The record naming record `at` (not the root) as its child, and which
/// child: in `at`'s block, or in that block's parent block.
fn parent_record(
    blocks: &HashMap<u32, Arc<Block>>,
    parent_block: &HashMap<u32, u32>,
    at: (u32, u32),
) -> Result<((u32, u32), usize), StorageError> {
    let same = blocks.get(&at.0).map(|b| (b, RecordRef { block: 0, checksum: 0, offset: at.1 }));
    let above = parent_block
        .get(&at.0)
        .and_then(|p| blocks.get(p))
        .map(|b| (b, RecordRef { block: at.0, checksum: 0, offset: at.1 }));
    for (block, want) in same.into_iter().chain(above) {
        for &o in &block.records {
            if let NodeView::Internal(n) = view(block, o)? {
                for c in 0..2 {
                    let r = n.child_ref(c);
                    if (r.block, r.offset) == (want.block, want.offset) {
                        return Ok(((block.id(), o), c));
                    }
                }
            }
        }
    }
    Err(StorageError::corrupt(at.0, "child_block", format!("no record names record {} of the block", at.1)))
}

/// Bytes of the records of node block `block`.
fn old_used(block: &Block) -> i64 {
    node::used_bytes(&block.bytes) as i64
}

/// Gives a drafted record the frame `frame` as its own.
fn set_own_frame(draft: Option<&mut RecordDraft>, frame: Aabb) {
    match draft {
        Some(RecordDraft::Internal { frame: f, .. } | RecordDraft::Leaf { frame: f, .. }) => *f = Some(frame),
        None => {}
    }
}

/// The key index as a change commit leaves it.
struct NewKeys {
    block: u32,
    checksum: u32,
    height: u32,
    blocks: u32,
}

/// A key block's replacement after changes: the blocks (with their least
/// keys) that stand where it stood, at its level; none when it emptied.
type Replacement = Vec<ChildRef>;

impl WriteTransaction<'_> {
    /// Applies `changes` (a key's new entry, or `None` to drop it) to the
    /// key index copy on write: the leaves they fall in and the branches
    /// above them are written anew; a leaf that fills splits, and one that
    /// empties goes (a branch may be left with one child: format-spec/keys.md).
    fn rewrite_keys(
        &mut self,
        r: &ReadTransaction,
        meta: &Meta,
        changes: BTreeMap<Key, Option<KeyEntry>>,
        reads: &mut Reads,
        freed: &mut Vec<u32>,
    ) -> Result<NewKeys, crate::Error> {
        let mut blocks = i64::from(meta.keys_blocks);
        if changes.is_empty() {
            return Ok(NewKeys {
                block: meta.keys_block,
                checksum: meta.keys_checksum,
                height: meta.keys_height,
                blocks: meta.keys_blocks,
            });
        }
        let changes: Vec<(Key, Option<KeyEntry>)> = changes.into_iter().collect();
        let root = ChildRef { first_key: Key::Int(0), block: meta.keys_block, checksum: meta.keys_checksum };
        let mut level =
            self.update_key_block(r, &root, meta.keys_height, &changes, reads, freed, &mut blocks)?;
        let mut height = meta.keys_height;
        if level.is_empty() {
            return Err(StorageError::Invalid("a change commit emptied the key index".into()).into());
        }
        // Levels above the old root while more than one block stands there.
        while level.len() > 1 {
            level = self.write_branches(&level, &mut blocks)?;
            height += 1;
        }
        let top = &level[0];
        Ok(NewKeys {
            block: top.block,
            checksum: top.checksum,
            height,
            blocks: u32::try_from(blocks)
                .map_err(|_| StorageError::Invalid("a key index of fewer than no blocks".into()))?,
        })
    }

    /// The replacement of key block `at` (`height` levels: 1 a leaf) with
    /// `changes` (all within its key range) applied.
    #[allow(clippy::too_many_arguments)]
    fn update_key_block(
        &mut self,
        r: &ReadTransaction,
        at: &ChildRef,
        height: u32,
        changes: &[(Key, Option<KeyEntry>)],
        reads: &mut Reads,
        freed: &mut Vec<u32>,
        blocks: &mut i64,
    ) -> Result<Replacement, crate::Error> {
        freed.push(at.block);
        *blocks -= 1;
        if height == 1 {
            return self.update_key_leaf(r, at, changes, reads, blocks);
        }
        match r.key_block(at.block, at.checksum, false, reads)? {
            KeyBlock::Leaf(_) => {
                Err(StorageError::corrupt(at.block, "keys_height", "a leaf above the leaves' level").into())
            }
            KeyBlock::Branch(children) => {
                // Each child's share of the changes, in key order.
                let mut next: Vec<ChildRef> = Vec::new();
                let mut i = 0;
                for (c, child) in children.iter().enumerate() {
                    let upper = children.get(c + 1).map(|n| &n.first_key);
                    let start = i;
                    while i < changes.len() && upper.is_none_or(|u| changes[i].0 < *u) {
                        i += 1;
                    }
                    // The least key below the first child is this block's own.
                    let least = if c == 0 { at.first_key.clone() } else { child.first_key.clone() };
                    if start == i {
                        next.push(ChildRef { first_key: least, ..child.clone() });
                        continue;
                    }
                    let child = ChildRef { first_key: least, ..child.clone() };
                    next.extend(self.update_key_block(
                        r,
                        &child,
                        height - 1,
                        &changes[start..i],
                        reads,
                        freed,
                        blocks,
                    )?);
                }
                if next.is_empty() {
                    return Ok(Vec::new());
                }
                self.write_branches(&next, blocks).map_err(Into::into)
            }
        }
    }

    /// The replacement of key leaf `at` with `changes` applied: the entries
    /// it keeps are copied as they lie, and only the changed ones encoded.
    fn update_key_leaf(
        &mut self,
        r: &ReadTransaction,
        at: &ChildRef,
        changes: &[(Key, Option<KeyEntry>)],
        reads: &mut Reads,
        blocks: &mut i64,
    ) -> Result<Replacement, crate::Error> {
        let pager = self.inner.pager().clone();
        let capacity = keys::capacity(pager.block_size());
        let leaf = r.block(at.block, BlockType::KeyLeaf, at.checksum, reads)?;
        let old = keys::leaf_entries(leaf.id(), &leaf.bytes, &leaf.records)?;
        // Both in key order: merge, the change winning on an equal key.
        let mut encoded: Vec<(Vec<u8>, u32, &Key)> = Vec::new();
        let mut order: Vec<(Option<usize>, usize)> = Vec::with_capacity(old.len() + changes.len());
        let (mut i, mut j) = (0, 0);
        while i < old.len() || j < changes.len() {
            let next_old = old.get(i).map(|(k, _)| *k);
            let next_change = changes.get(j);
            let take_old = match (next_old, next_change) {
                (Some(k), Some((c, _))) => k.cmp(&c.as_ref()),
                (Some(_), None) => std::cmp::Ordering::Less,
                (None, _) => std::cmp::Ordering::Greater,
            };
            if take_old.is_lt() {
                order.push((None, i));
                i += 1;
                continue;
            }
            if take_old.is_eq() {
                i += 1;
            }
            if let Some((key, Some(e))) = next_change {
                let bytes = keys::encode_entry(e).map_err(StorageError::Invalid)?;
                order.push((Some(encoded.len()), 0));
                encoded.push((bytes, e.object_id, key));
            }
            j += 1;
        }
        if order.is_empty() {
            // A leaf its removals empty goes; its branch drops it.
            return Ok(Vec::new());
        }
        let parts: Vec<&[u8]> =
            order.iter().map(|&(new, at)| new.map_or(old[at].1, |n| encoded[n].0.as_slice())).collect();
        if let Some((bytes, object, _)) = encoded.iter().find(|(b, ..)| b.len() > capacity) {
            return Err(KeyError::PayloadTooLong { object: ObjectId(*object), len: bytes.len() }.into());
        }
        let sizes: Vec<usize> = parts.iter().map(|p| p.len()).collect();
        let mut out = Vec::new();
        for group in keys::pack(&sizes, capacity) {
            let first_key = match order[group.start] {
                (None, at) => old[at].0.to_key(),
                (Some(n), _) => encoded[n].2.clone(),
            };
            let mut block = vec![0u8; pager.block_size() as usize];
            keys::encode_leaf_bytes(&parts[group], &mut block).map_err(StorageError::Invalid)?;
            let id = self.allocate(1)?;
            let checksum = self.put(id, &mut block, BlockType::KeyLeaf)?;
            *blocks += 1;
            out.push(ChildRef { first_key, block: id, checksum });
        }
        Ok(out)
    }

    /// Branch blocks over `children` (in key order), packed as a bulk load
    /// packs them.
    fn write_branches(
        &mut self,
        children: &[ChildRef],
        blocks: &mut i64,
    ) -> Result<Vec<ChildRef>, StorageError> {
        let pager = self.inner.pager().clone();
        let capacity = keys::capacity(pager.block_size());
        let sizes: Vec<usize> =
            children.iter().enumerate().map(|(i, c)| keys::child_len(&c.first_key, i == 0)).collect();
        let mut out = Vec::new();
        for group in keys::pack(&sizes, capacity) {
            let part = &children[group];
            let mut block = vec![0u8; pager.block_size() as usize];
            keys::encode_branch(part, &mut block).map_err(StorageError::Invalid)?;
            let id = self.allocate(1)?;
            let checksum = self.put(id, &mut block, BlockType::KeyBranch)?;
            *blocks += 1;
            out.push(ChildRef { first_key: part[0].first_key.clone(), block: id, checksum });
        }
        Ok(out)
    }
}
