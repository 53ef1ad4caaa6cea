//! The stored tree read back as a [`Hierarchy`], so `stats` and `dump`
//! report a file exactly as they report a tree built in memory (boxes are the
//! stored quantized boxes, which contain the true ones; overlaps the stored
//! f32 values).

use std::collections::HashMap;
use std::sync::Arc;

use super::{ReadTransaction, Reads, view, walk_everything};
use crate::bulk::{Hierarchy, Node, NodeId, NodeKind, Order, Split};
use crate::geom::Aabb;
use crate::query::Visitor;
use crate::scene::ObjectId;
use crate::store::format::node::NodeView;
use crate::store::{Block, StorageError};

/// A record's (block, offset).
type At = (u32, u32);

#[derive(Default)]
struct Collect {
    /// Each node in preorder, with its children's records when internal.
    nodes: Vec<(Node, Option<[At; 2]>)>,
    at: HashMap<(u32, u32), u32>,
    depth: HashMap<(u32, u32), u32>,
    /// Per node: its block, and its record's bytes without a frame of its own.
    stored: Vec<(u32, usize)>,
}

impl Visitor for Collect {
    fn node(&mut self, block: &Arc<Block>, offset: u32, frame: &Aabb) -> Result<(), StorageError> {
        let level = self.depth.get(&(block.id(), offset)).copied().unwrap_or(0);
        self.at.insert((block.id(), offset), self.nodes.len() as u32);
        let record = view(block, offset)?;
        self.stored.push((block.id(), record.len_without_frame()));
        let (kind, kids) = match record {
            NodeView::Internal(n) => {
                let s = n.split();
                let kids = [0, 1].map(|i| {
                    let r = n.child_ref(i);
                    (if r.block == 0 { block.id() } else { r.block }, r.offset)
                });
                for k in kids {
                    self.depth.insert(k, level + 1);
                }
                let split = Split {
                    axis: s.axis,
                    order: [Order::Min, Order::Max, Order::Center][usize::from(s.order.min(2))],
                    overlap: s.overlap.into(),
                    gap: s.gap.into(),
                };
                (NodeKind::Internal { children: [NodeId(u32::MAX); 2], split }, Some(kids))
            }
            NodeView::Leaf(l) => {
                let mut objects: Vec<ObjectId> =
                    (0..l.len()).filter_map(|i| l.object(i)).map(|o| ObjectId(o.object_id)).collect();
                objects.sort_unstable();
                // The parts of an object larger than a block share its id.
                objects.dedup();
                (NodeKind::Leaf { objects }, None)
            }
        };
        self.nodes.push((Node { aabb: *frame, level, kind }, kids));
        Ok(())
    }
}

/// Every node of the snapshot's tree, in preorder, with each leaf's objects
/// (this reads every node block, no geometry).
pub fn read_hierarchy(txn: &ReadTransaction) -> Result<Hierarchy, StorageError> {
    Ok(read_layout(txn)?.tree)
}

/// Every node of the snapshot's tree (as [`read_hierarchy`] gives it) with
/// the node block holding its record: what counts the node blocks on the
/// paths to a query's answer, the part of its reads no traversal avoids.
#[cfg(feature = "internals")]
pub fn read_hierarchy_blocks(txn: &ReadTransaction) -> Result<(Hierarchy, Vec<u32>), StorageError> {
    let stored = read_layout(txn)?;
    Ok((stored.tree, stored.blocks))
}

/// The stored tree with where its records lie.
pub(crate) struct StoredLayout {
    /// The tree, in preorder.
    pub tree: Hierarchy,
    /// Per node: the node block holding its record.
    pub blocks: Vec<u32>,
    /// Per node: its record's bytes, without a frame of its own.
    pub sizes: Vec<usize>,
}

/// The snapshot's tree (see [`read_hierarchy`]) with the block and size of
/// every record.
pub(crate) fn read_layout(txn: &ReadTransaction) -> Result<StoredLayout, StorageError> {
    let Some(root) = txn.root() else {
        return Ok(StoredLayout {
            tree: Hierarchy { nodes: Vec::new() },
            blocks: Vec::new(),
            sizes: Vec::new(),
        });
    };
    let mut c = Collect::default();
    walk_everything(txn, root, &mut Reads::new(None), &mut c)?;
    let Collect { nodes, at, stored, .. } = c;
    let tree = Hierarchy {
        nodes: nodes
            .into_iter()
            .map(|(mut node, kids)| {
                if let (NodeKind::Internal { children, .. }, Some(kids)) = (&mut node.kind, kids) {
                    *children = kids.map(|k| NodeId(at.get(&k).copied().unwrap_or(u32::MAX)));
                }
                node
            })
            .collect(),
    };
    let (blocks, sizes) = stored.into_iter().unzip();
    Ok(StoredLayout { tree, blocks, sizes })
}
