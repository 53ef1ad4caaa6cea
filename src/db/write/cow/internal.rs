//! The internal records on the changed paths rewritten, deepest first
//! (format-spec/commit.md, "Change commits"): their children's boxes,
//! object counts and block counts, and a frame grown to hold a child's
//! grown box, which the unchanged sibling keeps as its own
//! (format-spec/node.md, "Quantized boxes").

use rustc_hash::FxHashMap as HashMap;

use super::{Mod, apply};
use crate::db::write::WriteTransaction;
use crate::db::{ReadTransaction, Reads};
use crate::geom::Aabb;
use crate::store::StorageError;
use crate::store::format::meta::Meta;
use crate::store::format::node::{ChildEntry, NodeView, RecordDraft};
use crate::store::format::quant::quantize;
use crate::tree::view;

impl WriteTransaction<'_> {
    /// Rewrites every internal record of `mods` the changes do not make
    /// otherwise (a split's or a merge's), deepest first; returns the
    /// scene box, grown with the root's frame.
    pub(super) fn rewrite_internals(
        &mut self,
        r: &ReadTransaction,
        mods: &mut HashMap<(u32, u32), Mod>,
        meta: &Meta,
        reads: &mut Reads,
    ) -> Result<Aabb, crate::Error> {
        let mut order: Vec<(u32, u32)> = mods.keys().copied().collect();
        order.sort_by_key(|k| std::cmp::Reverse(mods[k].depth));
        let mut scene_box = Aabb::from_array(meta.scene_box);
        for at in order {
            if mods[&at].draft.is_some() || mods[&at].gone {
                continue;
            }
            if let Some(grown) = self.rewrite_internal(r, mods, at, reads)? {
                // The root's frame grew: the scene box is its frame.
                scene_box = grown;
            }
        }
        // A root leaf's frame of its own lies in the scene box, which grows to hold it.
        if let Some(b) = mods.get(&(meta.root_block, meta.root_offset)).and_then(|m| m.required) {
            scene_box = scene_box.union(&b);
        }
        Ok(scene_box)
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
        let gains = count_changed_children(mods, at, &places, &mut children)?;
        let grows = !gains.need.is_empty() && !frame.contains(&gains.need);
        let new_frame = if grows { frame.union(&gains.need) } else { frame };
        for (c, place) in places.iter().enumerate() {
            if let Some(child) = changed_child(mods, *place, at) {
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
                    let depth = mods[&at].depth + 1;
                    let sib = Mod::new(sib_block, place.1, sib_frame, Some((at, c)), depth);
                    mods.insert(*place, Mod { draft: Some(draft), ..sib });
                }
                children[c].qbox = quantize(&new_frame, &sib_frame);
            }
        }
        let object_count = u32::try_from(apply(u64::from(object_count), gains.objects)?)
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
        md.objects = gains.objects;
        md.geometry_blocks = gains.geometry_blocks;
        md.node_blocks = gains.node_blocks;
        Ok(root_frame)
    }
}

/// What an internal record's changed children bring it.
struct Gains {
    /// The box its frame must hold.
    need: Aabb,
    /// Objects, geometry blocks and node blocks its subtree gains.
    objects: i64,
    geometry_blocks: i64,
    node_blocks: i64,
}

/// The record at `place` when it is a changed child of record `at` (and
/// not a record moved there by a merge).
fn changed_child(mods: &HashMap<(u32, u32), Mod>, place: (u32, u32), at: (u32, u32)) -> Option<&Mod> {
    mods.get(&place).filter(|x| x.parent.map(|p| p.0) == Some(at))
}

/// What the changed children of record `at`, whose children lie at
/// `places`, bring it; their entries in `children` count their blocks.
fn count_changed_children(
    mods: &HashMap<(u32, u32), Mod>,
    at: (u32, u32),
    places: &[(u32, u32); 2],
    children: &mut [ChildEntry; 2],
) -> Result<Gains, StorageError> {
    let mut gains = Gains { need: Aabb::EMPTY, objects: 0, geometry_blocks: 0, node_blocks: 0 };
    for (c, place) in places.iter().enumerate() {
        let Some(child) = changed_child(mods, *place, at) else { continue };
        if let Some(b) = child.required {
            gains.need = gains.need.union(&b);
        }
        gains.objects += child.objects;
        gains.geometry_blocks += child.geometry_blocks;
        gains.node_blocks += child.node_blocks;
        children[c].geometry_blocks = apply(u64::from(children[c].geometry_blocks), child.geometry_blocks)?
            .try_into()
            .map_err(|_| StorageError::FileTooLarge)?;
        children[c].node_blocks = apply(u64::from(children[c].node_blocks), child.node_blocks)?
            .try_into()
            .map_err(|_| StorageError::FileTooLarge)?;
    }
    Ok(gains)
}

/// Gives a drafted record the frame `frame` as its own.
fn set_own_frame(draft: Option<&mut RecordDraft>, frame: Aabb) {
    match draft {
        Some(RecordDraft::Internal { frame: f, .. } | RecordDraft::Leaf { frame: f, .. }) => *f = Some(frame),
        None => {}
    }
}
