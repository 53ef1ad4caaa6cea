//! rstar as a reference line: the object boxes bulk-loaded (OMT) into an
//! R-tree in memory, and what a box query tests in it. Not a peer on disk:
//! it has no pages, so it counts the nodes whose box it tests instead.
//!
//! With rstar's default parameters (nodes of up to 6) its 3D bulk load
//! cuts every axis in at least 2 slabs, so inner nodes get 8 children and
//! a last group of 7 or 8 objects becomes 8 parents of one leaf each (on
//! tanker2, all 3,900 leaves): "leaves tested" then equals the answers,
//! and those one-leaf parents are counted among the nodes tested.

use std::cell::Cell;

use mktree::geom::Aabb;
use rstar::{AABB, Envelope, RTree, RTreeObject, SelectionFunction};

/// An object's box in the tree.
struct Entry {
    id: u32,
    envelope: AABB<[f64; 3]>,
}

impl RTreeObject for Entry {
    type Envelope = AABB<[f64; 3]>;

    fn envelope(&self) -> AABB<[f64; 3]> {
        self.envelope
    }
}

/// The object boxes in an rstar R-tree.
pub struct RstarPeer {
    tree: RTree<Entry>,
}

/// What one box query tested in the tree.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Tested {
    /// Sorted ids of the objects whose box meets the query.
    pub objects: Vec<u32>,
    /// Inner nodes whose box was tested (the root included).
    pub nodes: u64,
    /// Object boxes tested.
    pub leaves: u64,
}

/// A box query that counts its tests.
struct Counting<'a> {
    query: AABB<[f64; 3]>,
    nodes: &'a Cell<u64>,
    leaves: &'a Cell<u64>,
}

impl SelectionFunction<Entry> for Counting<'_> {
    fn should_unpack_parent(&self, envelope: &AABB<[f64; 3]>) -> bool {
        self.nodes.set(self.nodes.get() + 1);
        self.query.intersects(envelope)
    }

    fn should_unpack_leaf(&self, leaf: &Entry) -> bool {
        self.leaves.set(self.leaves.get() + 1);
        self.query.intersects(&leaf.envelope)
    }
}

impl RstarPeer {
    /// Bulk-loads `boxes` (object i has box i), rounded outward to f32 as
    /// the other peers store them, so all three filters test the same boxes.
    pub fn load(boxes: &[Aabb]) -> RstarPeer {
        let entries = (0u32..)
            .zip(boxes)
            .map(|(id, b)| {
                let (lo, hi) = b.to_f32_outward();
                Entry { id, envelope: AABB::from_corners(lo.map(f64::from), hi.map(f64::from)) }
            })
            .collect();
        RstarPeer { tree: RTree::bulk_load(entries) }
    }

    /// The objects whose box meets the closed box `query`, and the tests it took.
    pub fn query(&self, query: &Aabb) -> Tested {
        let (nodes, leaves) = (Cell::new(0), Cell::new(0));
        let q = AABB::from_corners(query.min.into(), query.max.into());
        let select = Counting { query: q, nodes: &nodes, leaves: &leaves };
        let mut objects: Vec<u32> = self.tree.locate_with_selection_function(select).map(|e| e.id).collect();
        objects.sort_unstable();
        Tested { objects, nodes: nodes.get(), leaves: leaves.get() }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_query_finds_the_boxes_it_meets_and_counts_what_it_tested() {
        let boxes: Vec<Aabb> = (0..200)
            .map(|i| {
                let x = f64::from(i % 20) * 10.0;
                let y = f64::from(i / 20) * 10.0;
                Aabb::from_array([x, y, 0.0, x + 5.0, y + 5.0, 5.0])
            })
            .collect();
        let peer = RstarPeer::load(&boxes);
        let q = Aabb::from_array([12.0, 12.0, 1.0, 35.0, 15.0, 2.0]);
        let t = peer.query(&q);
        let want: Vec<u32> = (0..200).filter(|&i| boxes[i as usize].intersects(&q)).collect();
        assert_eq!(t.objects, want);
        assert!(t.leaves >= want.len() as u64 && t.leaves < 200, "pruned: {} leaves tested", t.leaves);
        assert!(t.nodes >= 1);
        // Everything: every node and leaf is tested.
        let all = peer.query(&Aabb::from_array([-1.0, -1.0, -1.0, 1e3, 1e3, 1e3]));
        assert_eq!((all.objects.len(), all.leaves), (200, 200));
        let miss = peer.query(&Aabb::from_array([1e4, 1e4, 1e4, 1e5, 1e5, 1e5]));
        assert_eq!((miss.objects.len(), miss.nodes, miss.leaves), (0, 1, 0));
    }
}
