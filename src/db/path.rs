//! The records from the root to the leaf holding an object, found from its
//! key entry's path (format-spec/keys.md): what a lookup of a mesh reads,
//! and what a change commit rewrites (format-spec/commit.md).

use std::sync::Arc;

use super::{ReadTransaction, Reads};
use crate::geom::Aabb;
use crate::store::format::frame::BlockType;
use crate::store::format::keys::TreePath;
use crate::store::format::node::{NodeView, RecordRef};
use crate::store::{Block, StorageError};
use crate::tree::view;

/// One record on a path from the root.
#[derive(Debug, Clone)]
pub(crate) struct PathStep {
    /// The node block holding the record.
    pub block: Arc<Block>,
    pub offset: u32,
    /// The frame the record's entries are quantized in.
    pub frame: Aabb,
    /// The child taken to the next step (internal records).
    pub child: Option<usize>,
}

impl ReadTransaction {
    /// The records from the root to the leaf holding object `id`: down
    /// `path`, then, below its end (a path cut at 64 levels, or one that a
    /// later split left at an ancestor of the leaf), through every child
    /// whose box holds `aabb` (the object's exact box) until a leaf holds
    /// the object. A path that leads elsewhere is corruption: a key entry's
    /// path leads to the object's leaf or to an ancestor of it.
    pub(crate) fn path_to(
        &self,
        id: u32,
        path: TreePath,
        aabb: &Aabb,
        reads: &mut Reads,
    ) -> Result<Vec<PathStep>, StorageError> {
        let m = self
            .snapshot
            .meta
            .as_ref()
            .ok_or_else(|| StorageError::Invalid("the file holds no tree".into()))?;
        let root = self.root().ok_or_else(|| StorageError::Invalid("the file holds no tree".into()))?;
        let block = self.block(root.block, BlockType::Node, root.checksum, reads)?;
        let mut steps: Vec<PathStep> = Vec::new();
        // Records still to try below the path: (depth, block, offset, bound).
        let mut pending: Vec<(usize, Arc<Block>, u32, Aabb)> = vec![(0, block, root.offset, root.aabb)];
        // A walk that visits more records than the tree has loops.
        let mut budget = u64::from(m.node_count) + 1;
        while let Some((depth, block, offset, bound)) = pending.pop() {
            budget = budget.checked_sub(1).ok_or_else(|| {
                StorageError::corrupt(
                    block.id(),
                    "child_block",
                    "more records than the tree holds: the links loop",
                )
            })?;
            steps.truncate(depth);
            let record = view(&block, offset)?;
            if let Some(own) = record.own_frame()
                && !bound.contains(&own)
            {
                return Err(StorageError::corrupt(
                    block.id(),
                    "frame",
                    "a record's frame leaves its parent's box",
                ));
            }
            let frame = record.frame(bound);
            match record {
                NodeView::Leaf(leaf) => {
                    let holds = (0..leaf.len()).any(|i| leaf.object(i).is_some_and(|o| o.object_id == id));
                    steps.push(PathStep { block, offset, frame, child: None });
                    if holds {
                        children_taken(&mut steps)?;
                        return Ok(steps);
                    }
                    if depth < usize::from(path.len) {
                        break;
                    }
                }
                NodeView::Internal(n) => {
                    let chosen: Vec<usize> = match path.step(depth) {
                        Some(c) => vec![c],
                        // Below the path: every child that may hold the object, the first tried first.
                        None => (0..2)
                            .rev()
                            .filter(|&c| n.child_box(c, &frame).is_some_and(|q| q.outer.contains(aabb)))
                            .collect(),
                    };
                    steps.push(PathStep { block: block.clone(), offset, frame, child: None });
                    for c in chosen {
                        let q = n.child_box(c, &frame).ok_or_else(|| {
                            StorageError::corrupt(block.id(), "child_box", "a child box is backwards")
                        })?;
                        let at: RecordRef = n.child_ref(c);
                        let child_block = self.node_block(&block, at, reads)?;
                        pending.push((depth + 1, child_block, at.offset, q.outer));
                    }
                }
            }
        }
        Err(StorageError::corrupt(
            m.keys_block,
            "path",
            format!("the key index's path for object {id} does not lead to it"),
        ))
    }
}

/// Sets the child each step takes to the next, found from the next
/// record's place.
fn children_taken(steps: &mut [PathStep]) -> Result<(), StorageError> {
    for i in 0..steps.len().saturating_sub(1) {
        let (head, tail) = steps.split_at_mut(i + 1);
        let (here, next) = (&mut head[i], &tail[0]);
        let NodeView::Internal(n) = view(&here.block, here.offset)? else {
            return Err(StorageError::corrupt(here.block.id(), "path", "a leaf before the path's end"));
        };
        let taken = (0..2).find(|&c| {
            let at = n.child_ref(c);
            let block = if at.block == 0 { here.block.id() } else { at.block };
            block == next.block.id() && at.offset == next.offset
        });
        here.child = Some(
            taken.ok_or_else(|| StorageError::corrupt(here.block.id(), "path", "a step that is no child"))?,
        );
    }
    Ok(())
}
