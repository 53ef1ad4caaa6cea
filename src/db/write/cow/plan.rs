//! A change commit's plan (format-spec/commit.md, "Change commits"): the
//! leaf each changed object leaves or goes to, found by one path from the
//! root each, and the records on those paths, which the commit rewrites.

use std::collections::BTreeMap;

// Record and block ids hash with Fx, here and in the commit's other steps:
// SipHash's resistance buys nothing here and cost a commit on ship 10^6 a
// tenth of its instructions.
use rustc_hash::FxHashMap as HashMap;

use super::leaf::{Added, LeafEdit};
use super::{Change, Edits, Mod, Step};
use crate::db::path::PathStep;
use crate::db::source::check_object;
use crate::db::{ReadTransaction, Reads};
use crate::geom::Aabb;
use crate::scene::{Key, Object, ObjectId};
use crate::store::StorageError;
use crate::store::format::change_log::ChangeKind;
use crate::store::format::frame::BlockType;
use crate::store::format::geometry;
use crate::store::format::keys::{KeyEntry, TreePath};
use crate::store::format::meta::Meta;
use crate::store::format::node::NodeView;
use crate::tree::view;

/// Every leaf a commit changes, the records on their paths, the key
/// index's changes and the next free object id.
pub(super) struct Plan {
    pub(super) mods: HashMap<(u32, u32), Mod>,
    pub(super) leaves: BTreeMap<(u32, u32), LeafEdit>,
    pub(super) key_changes: BTreeMap<Key, Option<KeyEntry>>,
    pub(super) next_id: u32,
    /// How each key changed, in key order: the commit's change log record.
    pub(super) logged: Vec<(ChangeKind, Key)>,
}

/// Finds each changed object's leaf (the key index's path for a committed
/// one, the least growth for a new one) and notes the records on the way.
pub(super) fn plan_leaves(r: &ReadTransaction, meta: &Meta, edits: &Edits, reads: &mut Reads) -> Step<Plan> {
    let mut plan = Plan {
        mods: HashMap::default(),
        leaves: BTreeMap::new(),
        key_changes: BTreeMap::new(),
        next_id: meta.object_ids,
        logged: Vec::new(),
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
                    plan.logged.push((ChangeKind::Removed, key.clone()));
                }
            }
            Change::Put(object) => {
                let kind = if old.is_some() { ChangeKind::Updated } else { ChangeKind::Inserted };
                plan.logged.push((kind, key.clone()));
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
        mods.entry(at).or_insert_with(|| Mod::new(s.block.clone(), s.offset, s.frame, parent, depth));
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
