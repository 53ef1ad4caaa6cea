//! An emptied leaf merged with its sibling (format-spec/commit.md,
//! "Merges"): the parent's record becomes the sibling's, and the key
//! entries of the sibling's objects lead to the parent.

use std::collections::BTreeMap;
use std::sync::Arc;

use rustc_hash::FxHashMap as HashMap;

use super::{Deltas, Mod, Step, Structural};
use crate::db::write::WriteTransaction;
use crate::db::{ReadTransaction, Reads};
use crate::geom::Aabb;
use crate::scene::Key;
use crate::store::format::keys::KeyEntry;
use crate::store::format::node::{NodeView, RecordDraft, RecordRef};
use crate::store::{Block, StorageError};
use crate::tree::view;

/// The most objects below a sibling an emptied leaf merges with: each one's
/// key entry is rewritten, so a larger subtree costs more than it saves.
const MERGE_SUBTREE_OBJECTS: u32 = 64;

/// What an emptied leaf took from its parent's subtree.
pub(super) struct Gone {
    pub(super) objects: i64,
    pub(super) geometry_blocks: i64,
}

impl WriteTransaction<'_> {
    /// Merges emptied leaf `at` with its sibling, when the sibling is a
    /// record the commit does not otherwise change, a leaf or a subtree of
    /// at most [`MERGE_SUBTREE_OBJECTS`] objects (format-spec/commit.md,
    /// "Merges"): the parent's record becomes the sibling's, with the
    /// sibling's frame as its own, and the sibling's objects' key entries
    /// lead to the parent. Any other empty leaf needs the tree written whole.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn merge_with_sibling(
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
        if names_a_shared_block(&sib_block, &record, sib.offset, &parent_block)? {
            return Ok(Err(Structural));
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
        let draft = lifted_draft(&record, node_id, sib_frame, &sib_block, &parent_block);
        for (place, parent_entry) in [(at, (parent_at, c)), (sib_at, (parent_at, 1 - c))] {
            let md = mods.entry(place).or_insert_with(|| {
                Mod::new(sib_block.clone(), place.1, sib_frame, Some(parent_entry), parent_depth + 1)
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
}

/// Whether sibling `record` (record `offset` of `block`) names from its own
/// block a child block that another record of its block names too. Such a
/// child block is named from the parent's block `parent` after the merge,
/// which a block named from two blocks cannot be: a block has one parent
/// block (format-spec/node.md, "Packing").
fn names_a_shared_block(
    block: &Block,
    record: &NodeView,
    offset: u32,
    parent: &Block,
) -> Result<bool, StorageError> {
    let NodeView::Internal(s) = record else { return Ok(false) };
    if block.id() == parent.id() {
        return Ok(false);
    }
    for i in 0..2 {
        let named = s.child_ref(i).block;
        if named == 0 {
            continue;
        }
        for &o in block.records.iter().filter(|&&o| o != offset) {
            if let NodeView::Internal(other) = view(block, o)?
                && (0..2).any(|j| other.child_ref(j).block == named)
            {
                return Ok(true);
            }
        }
    }
    Ok(false)
}

/// Sibling `record` (of block `sib_block`) drafted as the record in its
/// parent's place: the parent's node id `node_id` and the sibling's frame
/// `frame` as its own.
fn lifted_draft(
    record: &NodeView,
    node_id: u32,
    frame: Aabb,
    sib_block: &Block,
    parent_block: &Block,
) -> RecordDraft {
    let mut draft = record.to_draft();
    match &mut draft {
        RecordDraft::Leaf { node_id: id, frame: f, .. } => (*id, *f) = (node_id, Some(frame)),
        RecordDraft::Internal { node_id: id, frame: f, children, .. } => {
            (*id, *f) = (node_id, Some(frame));
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
    draft
}

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
