//! The built tree, MKT(S) of §1.3: a binary hierarchy whose node n holds
//! R(S_n), the exact union of its objects' boxes; internal (grey) nodes
//! record the split that divided S_n, leaves list their objects.
//!
//! Nodes are stored in preorder: the root is node 0 and a node's left
//! subtree comes before its right one, so ids are stable for a given input
//! and options. It serialises as `{"nodes": [...]}`, each node as `id`,
//! `level`, `aabb` `[x0,y0,z0,x1,y1,z1]`, `children` (`[a, b]` or null),
//! `objects` (leaves) and `split` (internal nodes).

use serde::Serialize;
use serde::ser::{SerializeStruct, Serializer};

use crate::geom::{Aabb, Axis};
use crate::scene::ObjectId;

/// A node's index in [`Hierarchy::nodes`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
#[serde(transparent)]
pub struct NodeId(pub u32);

impl NodeId {
    /// The root: node 0.
    pub const ROOT: NodeId = NodeId(0);

    /// The id as an index into [`Hierarchy::nodes`].
    pub fn index(self) -> usize {
        self.0 as usize
    }
}

impl std::fmt::Display for NodeId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        self.0.fmt(f)
    }
}

/// Which coordinate of the objects' boxes a split sorted them by.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Order {
    /// The lower coordinate (Xmin, Ymin, Zmin in §3.1).
    Min,
    /// The upper coordinate (Xmax, Ymax, Zmax).
    Max,
    /// The box centre: the median, Hilbert and SAH reference methods.
    Center,
}

/// How an internal node was divided.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Split {
    /// The cut axis (w of `wDivideList`).
    pub axis: Axis,
    /// The coordinate the objects were sorted by.
    pub order: Order,
    /// The overlap the paper reports (its tables' ovMin/ovMax): `gap`
    /// clamped at zero, so always >= 0.
    pub overlap: f64,
    /// The raw value, negative for a gap between the children. MOA and
    /// LAA: MOA2's `max(upper over the first part) - min(lower over the
    /// second part)` along `axis`, which is at least the length of the
    /// children's intersection. Reference methods: the signed length of
    /// that intersection (Definition 1.2.3), negative by the distance
    /// between the children. Either is <= 0 exactly when the children's
    /// projections on `axis` do not overlap.
    // Paper §3.1: MOA2's value exceeds the xOverlap of Definition 1.2.3
    // when one child's projection holds the other's; we keep MOA2's
    // formula, the one its pseudo-code minimises.
    pub gap: f64,
}

impl Split {
    /// The gap this split records between children of boxes `left` and
    /// `right`: MOA2's value for cuts in a sorted order, the signed
    /// intersection for cuts by box centre (see [`Split::gap`]).
    pub fn gap_between(&self, left: &Aabb, right: &Aabb) -> f64 {
        let i = self.axis.index();
        match self.order {
            Order::Min | Order::Max => left.max[i] - right.min[i],
            Order::Center => signed_intersection(left, right, self.axis),
        }
    }
}

/// A leaf or an internal node.
#[derive(Debug, Clone, PartialEq)]
pub enum NodeKind {
    /// A grey node with two children (left, right).
    Internal {
        /// Left and right child.
        children: [NodeId; 2],
        /// How the node was divided.
        split: Split,
    },
    /// A leaf: its objects, in increasing id order.
    Leaf {
        /// The objects S_n.
        objects: Vec<ObjectId>,
    },
}

/// One node n of the tree.
#[derive(Debug, Clone, PartialEq)]
pub struct Node {
    /// R(S_n): the exact union of the boxes of the node's objects.
    pub aabb: Aabb,
    /// Tree level: 0 at the root, parent's + 1 below.
    pub level: u32,
    /// Leaf or internal.
    pub kind: NodeKind,
}

impl Node {
    /// The split, for an internal node.
    pub fn split(&self) -> Option<&Split> {
        match &self.kind {
            NodeKind::Internal { split, .. } => Some(split),
            NodeKind::Leaf { .. } => None,
        }
    }

    /// The children, for an internal node.
    pub fn children(&self) -> Option<[NodeId; 2]> {
        match &self.kind {
            NodeKind::Internal { children, .. } => Some(*children),
            NodeKind::Leaf { .. } => None,
        }
    }

    /// The objects, for a leaf.
    pub fn objects(&self) -> Option<&[ObjectId]> {
        match &self.kind {
            NodeKind::Leaf { objects } => Some(objects),
            NodeKind::Internal { .. } => None,
        }
    }
}

/// A built hierarchy: nodes in preorder, root first.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Hierarchy {
    /// Every node; `nodes[id.index()]` is node `id`.
    pub nodes: Vec<Node>,
}

impl Hierarchy {
    /// The root node (none for an empty hierarchy, which `build` never returns).
    pub fn root(&self) -> Option<&Node> {
        self.nodes.first()
    }

    /// Node `id`, if there is one.
    pub fn node(&self, id: NodeId) -> Option<&Node> {
        self.nodes.get(id.index())
    }

    /// Every leaf with its objects, in preorder (left to right).
    pub fn leaves(&self) -> impl Iterator<Item = (NodeId, &[ObjectId])> + '_ {
        self.nodes.iter().enumerate().filter_map(|(i, n)| n.objects().map(|o| (node_id(i), o)))
    }

    /// Number of levels: the deepest level + 1 (the paper's "deep",
    /// §3.1.1: levels 0..13 make a depth of 14); 0 when empty.
    pub fn depth(&self) -> u32 {
        self.nodes.iter().map(|n| n.level + 1).max().unwrap_or(0)
    }

    /// The subtree of `top` in preorder, following the children it records
    /// (a node, its left subtree, then its right one): each node with its
    /// id and its depth below `top`.
    pub fn subtree(&self, top: NodeId) -> Preorder<'_, fn(&Node) -> bool> {
        self.subtree_where(top, |_| true)
    }

    /// [`Hierarchy::subtree`] entering only the nodes `enter` accepts: a
    /// node it refuses is not yielded and its subtree is skipped (a box
    /// query enters the nodes whose box meets it).
    pub fn subtree_where<F: FnMut(&Node) -> bool>(&self, top: NodeId, enter: F) -> Preorder<'_, F> {
        Preorder { tree: self, stack: vec![(top, 0)], enter }
    }
}

/// The preorder walk of [`Hierarchy::subtree_where`]. It follows the ids a
/// node records and skips ids with no node; it ends when children ids lead
/// down to larger ids, as in every hierarchy `validate` passes (which checks
/// that with this walk, stopping at the first id out of order).
#[derive(Debug, Clone)]
pub struct Preorder<'a, F> {
    tree: &'a Hierarchy,
    /// Nodes to visit, the next on top, with their depth below the top.
    stack: Vec<(NodeId, u32)>,
    enter: F,
}

impl<'a, F: FnMut(&Node) -> bool> Iterator for Preorder<'a, F> {
    type Item = (NodeId, u32, &'a Node);

    fn next(&mut self) -> Option<Self::Item> {
        while let Some((id, depth)) = self.stack.pop() {
            let Some(node) = self.tree.node(id) else { continue };
            if !(self.enter)(node) {
                continue;
            }
            if let Some([left, right]) = node.children() {
                self.stack.push((right, depth + 1));
                self.stack.push((left, depth + 1));
            }
            return Some((id, depth, node));
        }
        None
    }
}

/// The id of the node at `index`. A build takes at most 2^31 objects, so
/// its fewer than 2^32 nodes all have a u32 id.
pub(crate) fn node_id(index: usize) -> NodeId {
    debug_assert!(u32::try_from(index).is_ok());
    NodeId(index as u32)
}

/// One node as the dump format shows it.
#[derive(Serialize)]
struct NodeRecord<'a> {
    id: NodeId,
    level: u32,
    aabb: [f64; 6],
    children: Option<[NodeId; 2]>,
    objects: Option<&'a [ObjectId]>,
    split: Option<&'a Split>,
}

/// The node list as a sequence of [`NodeRecord`]s.
struct Records<'a>(&'a [Node]);

impl Serialize for Records<'_> {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.collect_seq(self.0.iter().enumerate().map(|(i, n)| NodeRecord {
            id: node_id(i),
            level: n.level,
            aabb: n.aabb.to_array(),
            children: n.children(),
            objects: n.objects(),
            split: n.split(),
        }))
    }
}

impl Serialize for Hierarchy {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let mut s = serializer.serialize_struct("Hierarchy", 1)?;
        s.serialize_field("nodes", &Records(&self.nodes))?;
        s.end()
    }
}

/// The length of the intersection of the two boxes' projections on `axis`,
/// negative by the distance between them when they are apart.
pub(crate) fn signed_intersection(a: &Aabb, b: &Aabb, axis: Axis) -> f64 {
    let i = axis.index();
    a.max[i].min(b.max[i]) - a.min[i].max(b.min[i])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::Axis;

    fn leaf(level: u32, x: f64, object: u32) -> Node {
        let aabb = Aabb::from_array([x, 0.0, 0.0, x + 1.0, 1.0, 1.0]);
        Node { aabb, level, kind: NodeKind::Leaf { objects: vec![ObjectId(object)] } }
    }

    fn internal(level: u32, x: [f64; 2], children: [u32; 2]) -> Node {
        let split = Split { axis: Axis::X, order: Order::Min, overlap: 0.0, gap: -1.0 };
        let aabb = Aabb::from_array([x[0], 0.0, 0.0, x[1], 1.0, 1.0]);
        Node { aabb, level, kind: NodeKind::Internal { children: children.map(NodeId), split } }
    }

    /// 0 over (1 over leaves 2, 3) and leaf 4, in preorder.
    fn tree() -> Hierarchy {
        Hierarchy {
            nodes: vec![
                internal(0, [0.0, 5.0], [1, 4]),
                internal(1, [0.0, 3.0], [2, 3]),
                leaf(2, 0.0, 0),
                leaf(2, 2.0, 1),
                leaf(1, 4.0, 2),
            ],
        }
    }

    #[test]
    fn a_subtree_is_walked_in_preorder_with_depths_below_its_top() {
        let t = tree();
        let walk = |top| t.subtree(NodeId(top)).map(|(id, depth, _)| (id.0, depth)).collect::<Vec<_>>();
        assert_eq!(walk(0), [(0, 0), (1, 1), (2, 2), (3, 2), (4, 1)]);
        assert_eq!(walk(1), [(1, 0), (2, 1), (3, 1)]);
        assert_eq!(walk(4), [(4, 0)]);
        assert!(walk(9).is_empty());
    }

    #[test]
    fn a_refused_node_is_skipped_with_its_subtree() {
        let t = tree();
        let query = Aabb::from_array([2.5, 0.0, 0.0, 4.5, 1.0, 1.0]);
        let met: Vec<u32> =
            t.subtree_where(NodeId::ROOT, |n| n.aabb.intersects(&query)).map(|(id, _, _)| id.0).collect();
        assert_eq!(met, [0, 1, 3, 4]);
        assert_eq!(t.subtree_where(NodeId::ROOT, |n| n.level == 0).count(), 1);
    }
}
