//! `Hierarchy::validate` accepts what `build` makes and refuses a damaged
//! tree with an error naming the node at fault: an object in two leaves or
//! in none, a wrong box, a wrong level, children out of preorder, an
//! overfull leaf, a split record that does not match its children.

use mktree::bulk::{BuildParams, Hierarchy, HierarchyError, LeafRule, Method, NodeId, NodeKind, build};
use mktree::geom::Aabb;
use mktree::scene::ObjectId;

fn scene() -> Vec<Aabb> {
    (0..40)
        .map(|i| {
            let x = f64::from((i * 17) % 40);
            Aabb::from_array([x, f64::from(i % 3), 0.0, x + 1.5, f64::from(i % 3) + 1.0, 1.0])
        })
        .collect()
}

fn params(method: Method) -> BuildParams {
    BuildParams { method, leaf: LeafRule::Objects(4), ..BuildParams::paper() }
}

fn tree(boxes: &[Aabb], method: Method) -> Hierarchy {
    build(boxes, None, &params(method), &|_| {}).unwrap()
}

fn leaf_objects(tree: &mut Hierarchy, id: usize) -> &mut Vec<ObjectId> {
    match &mut tree.nodes[id].kind {
        NodeKind::Leaf { objects } => objects,
        NodeKind::Internal { .. } => panic!("node {id} is not a leaf"),
    }
}

fn leaf_ids(tree: &Hierarchy) -> Vec<usize> {
    tree.leaves().map(|(id, _)| id.index()).collect()
}

#[test]
fn built_trees_are_accepted() {
    let boxes = scene();
    for method in Method::ALL {
        assert_eq!(tree(&boxes, method).validate(&boxes, None, &params(method)), Ok(()));
    }
}

#[test]
fn an_object_in_two_leaves_is_named_with_both() {
    let boxes = scene();
    let mut t = tree(&boxes, Method::Moa);
    let leaves = leaf_ids(&t);
    let (first, last) = (leaves[0], leaves[leaves.len() - 1]);
    let moved = leaf_objects(&mut t, last)[0];
    leaf_objects(&mut t, first).push(moved);
    let err = t.validate(&boxes, None, &params(Method::Moa)).unwrap_err();
    assert_eq!(
        err,
        HierarchyError::RepeatedObject {
            object: moved,
            first: NodeId(first as u32),
            second: NodeId(last as u32)
        }
    );
}

#[test]
fn an_object_in_no_leaf_is_named() {
    // Identical boxes: dropping an object leaves every box exact.
    let boxes = vec![Aabb::from_array([0.0, 0.0, 0.0, 1.0, 1.0, 1.0]); 12];
    let mut t = tree(&boxes, Method::Moa);
    let leaf = leaf_ids(&t)[1];
    let dropped = leaf_objects(&mut t, leaf).remove(0);
    let err = t.validate(&boxes, None, &params(Method::Moa)).unwrap_err();
    assert_eq!(err, HierarchyError::MissingObject { object: dropped });
}

#[test]
fn a_wrong_box_is_named() {
    let boxes = scene();
    let mut t = tree(&boxes, Method::Sah);
    t.nodes[2].aabb = t.nodes[2].aabb.grown(0.5);
    let err = t.validate(&boxes, None, &params(Method::Sah)).unwrap_err();
    assert!(matches!(err, HierarchyError::InexactBox { node: NodeId(2), .. }), "{err}");
}

#[test]
fn a_wrong_level_is_named() {
    let boxes = scene();
    let mut t = tree(&boxes, Method::Median);
    t.nodes[1].level = 5;
    let err = t.validate(&boxes, None, &params(Method::Median)).unwrap_err();
    assert_eq!(err, HierarchyError::WrongLevel { node: NodeId(1), found: 5, expected: 1 });
}

#[test]
fn swapped_children_break_preorder() {
    let boxes = scene();
    let mut t = tree(&boxes, Method::Hilbert);
    if let NodeKind::Internal { children, .. } = &mut t.nodes[0].kind {
        children.swap(0, 1);
    }
    let err = t.validate(&boxes, None, &params(Method::Hilbert)).unwrap_err();
    assert!(matches!(err, HierarchyError::NotPreorder { expected: NodeId(1), .. }), "{err}");
}

#[test]
fn an_overfull_leaf_is_named() {
    let boxes = scene();
    let t = tree(&boxes, Method::Moa);
    let smaller = BuildParams { leaf: LeafRule::Objects(2), ..params(Method::Moa) };
    let err = t.validate(&boxes, None, &smaller).unwrap_err();
    // The sweep runs from the last node back: the last overfull leaf is named.
    let (node, objects) = t.leaves().filter(|(_, o)| o.len() > 2).last().unwrap();
    assert_eq!(err, HierarchyError::OverCapacity { node, measure: objects.len() as u64, limit: 2 });
}

#[test]
fn a_split_record_that_does_not_match_its_children_is_named() {
    let boxes = scene();
    for method in [Method::Laa, Method::Sah] {
        let mut t = tree(&boxes, method);
        if let NodeKind::Internal { split, .. } = &mut t.nodes[0].kind {
            split.gap -= 1.0;
        }
        let err = t.validate(&boxes, None, &params(method)).unwrap_err();
        assert!(matches!(err, HierarchyError::SplitMismatch { node: NodeId(0), .. }), "{method}: {err}");
    }
}
