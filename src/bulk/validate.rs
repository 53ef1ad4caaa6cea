//! `Hierarchy::validate`: checks a hierarchy against its input and options,
//! naming the first node at fault. The properties are those of MKT(S) in
//! §1.3: every object in exactly one leaf, R(S_n) exact at every node,
//! leaves within the page (`InPage`), plus the preorder layout and the
//! split records (see [`Split`]).

use super::driver::check_input;
use super::{BuildError, BuildParams, Hierarchy, Method, NodeId, NodeKind, Order, Split};
use crate::geom::{Aabb, Axis};
use crate::scene::{Mesh, ObjectId, Scene};

/// Refuses `scene` when an object's anchor or a vertex, used or not, has a
/// coordinate beyond ±`limit` mm, naming the first object and axis at fault.
/// A file holds coordinates within
/// `MAX_COORDINATE` (2^53 mm)
/// (format-spec/geometry.md, "Coordinate range"), and its writer checks
/// against that; within it, f32 also holds every offset and split value.
pub fn check_range(scene: &Scene, limit: f64) -> Result<(), BuildError> {
    for (j, object) in scene.objects().iter().enumerate() {
        check_object_range(ObjectId(j as u32), &object.mesh, limit)?;
    }
    Ok(())
}

/// [`check_range`] for one object's mesh, reported as object `object`.
pub(crate) fn check_object_range(object: ObjectId, mesh: &Mesh, limit: f64) -> Result<(), BuildError> {
    // Every vertex lies between the anchor and this corner.
    let high = mesh.vertices().fold(mesh.anchor(), |corner, v| corner.sup(&v));
    for corner in [mesh.anchor(), high] {
        for axis in Axis::ALL {
            let coordinate = corner[axis.index()];
            if coordinate.abs() > limit {
                return Err(BuildError::OutOfRange { object, axis, coordinate, limit });
            }
        }
    }
    Ok(())
}

/// Why a hierarchy is not a valid tree of its input.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum HierarchyError {
    /// The options or input themselves are refused.
    #[error(transparent)]
    Input(#[from] BuildError),
    /// There is no node.
    #[error("the hierarchy has no nodes")]
    Empty,
    /// An internal node names a child that does not exist.
    #[error("node {node}: child {child} does not exist")]
    MissingChild {
        /// The parent.
        node: NodeId,
        /// The missing child.
        child: NodeId,
    },
    /// Nodes are not in preorder (root 0, left subtree before right).
    #[error("node {node} is where preorder puts node {expected}")]
    NotPreorder {
        /// The node found.
        node: NodeId,
        /// The node preorder expects there.
        expected: NodeId,
    },
    /// A node is not reachable from the root.
    #[error("node {node} is not reachable from the root")]
    Unreachable {
        /// The node.
        node: NodeId,
    },
    /// A node's level is not its parent's + 1 (0 at the root).
    #[error("node {node} has level {found}, expected {expected}")]
    WrongLevel {
        /// The node.
        node: NodeId,
        /// Its level.
        found: u32,
        /// The level its depth gives.
        expected: u32,
    },
    /// A leaf lists no object.
    #[error("leaf {node} has no objects")]
    EmptyLeaf {
        /// The leaf.
        node: NodeId,
    },
    /// A leaf lists an id beyond the input.
    #[error("leaf {node} lists object {object}, which is not in the input")]
    UnknownObject {
        /// The leaf.
        node: NodeId,
        /// The id.
        object: ObjectId,
    },
    /// An object is in two leaves (or twice in one).
    #[error("object {object} is in leaf {first} and in leaf {second}")]
    RepeatedObject {
        /// The object.
        object: ObjectId,
        /// The first leaf that lists it.
        first: NodeId,
        /// The second.
        second: NodeId,
    },
    /// An object is in no leaf.
    #[error("object {object} is in no leaf")]
    MissingObject {
        /// The object.
        object: ObjectId,
    },
    /// A node's box is not the exact union of its objects' boxes.
    #[error("node {node}: box {found:?} is not the union of its objects' boxes, {expected:?}")]
    InexactBox {
        /// The node.
        node: NodeId,
        /// Its box.
        found: Aabb,
        /// The union.
        expected: Aabb,
    },
    /// A leaf of several objects does not fit the page.
    #[error("leaf {node} measures {measure} (objects or bytes), over the page's {limit}")]
    OverCapacity {
        /// The leaf.
        node: NodeId,
        /// Its object count or total bytes.
        measure: u64,
        /// The leaf rule's limit.
        limit: u64,
    },
    /// A split record does not match its children's boxes.
    #[error("node {node}: split {found:?} does not match its children, which give gap {expected_gap}")]
    SplitMismatch {
        /// The node.
        node: NodeId,
        /// Its record.
        found: Split,
        /// The raw value the children's boxes give.
        expected_gap: f64,
    },
}

impl Hierarchy {
    /// Checks this hierarchy as a build of `boxes` (and `sizes`) with
    /// `params`: preorder layout and levels, every object in exactly one
    /// leaf, every node's box the exact union of its objects' boxes, every
    /// leaf of two or more objects within the page, and every split record
    /// consistent with its children (see [`Split::gap`]).
    pub fn validate(
        &self,
        boxes: &[Aabb],
        sizes: Option<&[u64]>,
        params: &BuildParams,
    ) -> Result<(), HierarchyError> {
        let leaf = check_input(boxes, sizes, params)?;
        self.check_layout()?;
        let mut owner: Vec<Option<NodeId>> = vec![None; boxes.len()];
        // Children come after their parent: a reverse sweep sees them first.
        let mut exact = vec![Aabb::EMPTY; self.nodes.len()];
        for (i, node) in self.nodes.iter().enumerate().rev() {
            let id = NodeId(i as u32);
            let union = match &node.kind {
                NodeKind::Leaf { objects } => {
                    if objects.is_empty() {
                        return Err(HierarchyError::EmptyLeaf { node: id });
                    }
                    let mut union = Aabb::EMPTY;
                    for &object in objects {
                        let slot = owner
                            .get_mut(object.index())
                            .ok_or(HierarchyError::UnknownObject { node: id, object })?;
                        if let Some(first) = slot.replace(id) {
                            // The sweep runs backwards: `first` is the later leaf.
                            return Err(HierarchyError::RepeatedObject { object, first: id, second: first });
                        }
                        union = union.union(&boxes[object.index()]);
                    }
                    let ids: Vec<u32> = objects.iter().map(|o| o.0).collect();
                    if !leaf.fits(&ids) {
                        let (measure, limit) = (leaf.measure(&ids), leaf.limit());
                        return Err(HierarchyError::OverCapacity { node: id, measure, limit });
                    }
                    union
                }
                NodeKind::Internal { children: [a, b], split } => {
                    let (left, right) = (&exact[a.index()], &exact[b.index()]);
                    check_split(id, split, left, right, params.method)?;
                    left.union(right)
                }
            };
            if union != node.aabb {
                return Err(HierarchyError::InexactBox { node: id, found: node.aabb, expected: union });
            }
            exact[i] = union;
        }
        match owner.iter().position(Option::is_none) {
            Some(j) => Err(HierarchyError::MissingObject { object: ObjectId(j as u32) }),
            None => Ok(()),
        }
    }

    /// Preorder ids and levels; every node reached once from the root.
    pub(crate) fn check_layout(&self) -> Result<(), HierarchyError> {
        if self.nodes.is_empty() {
            return Err(HierarchyError::Empty);
        }
        // (node, its level): preorder visits exactly ids 0, 1, 2, ...
        let mut next = 0usize;
        for (id, level, node) in self.subtree(NodeId::ROOT) {
            let expected = NodeId(next as u32);
            if id != expected {
                return Err(HierarchyError::NotPreorder { node: id, expected });
            }
            if node.level != level {
                return Err(HierarchyError::WrongLevel { node: id, found: node.level, expected: level });
            }
            next += 1;
            // Checked before the walk goes on, which would skip a missing child.
            if let Some(&child) = node.children().iter().flatten().find(|c| c.index() >= self.nodes.len()) {
                return Err(HierarchyError::MissingChild { node: id, child });
            }
        }
        if next < self.nodes.len() {
            return Err(HierarchyError::Unreachable { node: NodeId(next as u32) });
        }
        Ok(())
    }
}

/// The split record of node `id` against its children's exact boxes.
fn check_split(
    id: NodeId,
    split: &Split,
    left: &Aabb,
    right: &Aabb,
    method: Method,
) -> Result<(), HierarchyError> {
    // MOA2's value for cuts in a sorted order; the signed intersection for
    // cuts by box centre. `refine` keeps cuts of both kinds.
    let moa_cut = split.order != Order::Center;
    let order_fits = match method {
        Method::Moa | Method::Laa => moa_cut,
        Method::Refine => true,
        Method::Median | Method::Hilbert | Method::Sah | Method::Vsah => !moa_cut,
    };
    let expected_gap = split.gap_between(left, right);
    let clamped = if expected_gap > 0.0 { expected_gap } else { 0.0 };
    if order_fits && split.gap == expected_gap && split.overlap == clamped {
        Ok(())
    } else {
        Err(HierarchyError::SplitMismatch { node: id, found: *split, expected_gap })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::Point;
    use crate::scene::{Mesh, Object};

    fn scene(objects: &[&[[f64; 3]]]) -> Scene {
        let object = |points: &&[[f64; 3]]| {
            let points: Vec<Point> = points.iter().map(|&p| p.into()).collect();
            Object::new("o", Mesh::from_world(&points, vec![[0, 1, 2]]).unwrap())
        };
        Scene::new(objects.iter().map(object).collect())
    }

    #[test]
    fn every_vertex_and_anchor_is_checked_against_the_limit() {
        let inside: &[[f64; 3]] = &[[-10.0, 0.0, 0.0], [10.0, 0.0, 0.0], [0.0, 10.0, 0.0]];
        assert_eq!(check_range(&scene(&[inside]), 10.0), Ok(()));
        assert_eq!(check_range(&Scene::default(), 10.0), Ok(()));
        let out: &[[f64; 3]] = &[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, -11.0]];
        let expected =
            BuildError::OutOfRange { object: ObjectId(1), axis: Axis::Z, coordinate: -11.0, limit: 10.0 };
        assert_eq!(check_range(&scene(&[inside, out]), 10.0), Err(expected));
        // A vertex no triangle uses is stored too.
        let points = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 12.0, 0.0]].map(Point::from);
        let unused = Mesh::from_world(&points, vec![[0, 1, 2]]).unwrap();
        let e = check_range(&Scene::new(vec![Object::new("u", unused)]), 10.0).unwrap_err();
        assert!(matches!(e, BuildError::OutOfRange { axis: Axis::Y, coordinate: 12.0, .. }), "{e}");
    }
}
