//! The hard cases give valid trees with every method and every tie-break:
//! an object bigger than a page (a leaf by itself), identical boxes, all
//! objects at one point, one object, two objects, a flat scene (zero
//! extent on an axis), a line of boxes (zero extent on two axes), R = 0,
//! R = 0.5 and `mem_page` = 1; and a tree as deep as it has objects does
//! not overflow the stack.

use mktree::bulk::{BuildParams, Hierarchy, LeafRule, LookAhead, Method, TieBreak, build};
use mktree::geom::Aabb;
use mktree::scene::ObjectId;

fn b(a: [f64; 6]) -> Aabb {
    Aabb::from_array(a)
}

/// A small irregular scene: `n` boxes whose corners follow a fixed
/// quadratic residue pattern.
fn scattered(n: usize) -> Vec<Aabb> {
    (0..n)
        .map(|i| {
            let f = |k: usize| ((i * i * 7 + i * k * 13 + k) % 97) as f64;
            b([f(1), f(2), f(3), f(1) + f(4) % 9.0, f(2) + f(5) % 7.0, f(3) + f(6) % 5.0])
        })
        .collect()
}

/// Every method (LAA at look-ahead 0, 2 and max) and tie-break over `base`.
fn variants(base: &BuildParams) -> Vec<BuildParams> {
    let mut out = Vec::new();
    for method in Method::ALL {
        for tie_break in TieBreak::ALL {
            let looks: &[LookAhead] = match method {
                Method::Laa => &[LookAhead::Levels(0), LookAhead::Levels(2), LookAhead::Max],
                _ => &[LookAhead::Levels(2)],
            };
            for &look_ahead in looks {
                out.push(BuildParams { method, tie_break, look_ahead, ..base.clone() });
            }
        }
    }
    out
}

/// Builds and validates with every variant of `base`; returns the trees.
fn build_all(boxes: &[Aabb], sizes: Option<&[u64]>, base: &BuildParams) -> Vec<(BuildParams, Hierarchy)> {
    variants(base)
        .into_iter()
        .map(|p| {
            let tree = build(boxes, sizes, &p, &|_| {}).unwrap_or_else(|e| panic!("{p:?}: {e}"));
            tree.validate(boxes, sizes, &p).unwrap_or_else(|e| panic!("{p:?}: {e}"));
            (p, tree)
        })
        .collect()
}

fn objects(mem_page: u32) -> BuildParams {
    BuildParams { leaf: LeafRule::Objects(mem_page), ..BuildParams::paper() }
}

#[test]
fn an_object_bigger_than_a_page_is_a_leaf_by_itself() {
    let boxes = scattered(40);
    let mut sizes = vec![100u64; 40];
    sizes[17] = 5_000;
    let base = BuildParams { leaf: LeafRule::Bytes { capacity: 1_000 }, ..BuildParams::paper() };
    for (p, tree) in build_all(&boxes, Some(&sizes), &base) {
        let leaf = tree.leaves().find(|(_, o)| o.contains(&ObjectId(17))).unwrap().1;
        assert_eq!(leaf, [ObjectId(17)], "{p:?}");
    }
}

#[test]
fn identical_boxes_give_valid_trees() {
    let boxes = vec![b([1.0, 2.0, 3.0, 4.0, 5.0, 6.0]); 50];
    for (p, tree) in build_all(&boxes, None, &objects(4)) {
        assert!(tree.leaves().all(|(_, o)| o.len() <= 4), "{p:?}");
    }
}

#[test]
fn objects_all_at_one_point_give_valid_trees() {
    let boxes = vec![b([1.0, 2.0, 3.0, 1.0, 2.0, 3.0]); 33];
    for (p, tree) in build_all(&boxes, None, &objects(2)) {
        assert!(tree.nodes.iter().filter_map(|n| n.split()).all(|s| s.overlap == 0.0), "{p:?}");
    }
}

#[test]
fn one_object_is_a_single_leaf() {
    let boxes = [b([0.0, 0.0, 0.0, 1.0, 1.0, 1.0])];
    for (p, tree) in build_all(&boxes, None, &objects(1)) {
        assert_eq!(tree.nodes.len(), 1, "{p:?}");
        assert_eq!(tree.depth(), 1);
    }
}

#[test]
fn two_objects_over_a_one_object_page_give_a_root_and_two_leaves() {
    let boxes = [b([0.0, 0.0, 0.0, 2.0, 1.0, 1.0]), b([1.0, 0.0, 0.0, 3.0, 1.0, 1.0])];
    for (p, tree) in build_all(&boxes, None, &objects(1)) {
        assert_eq!(tree.nodes.len(), 3, "{p:?}");
        assert_eq!(tree.leaves().count(), 2);
    }
    for (p, tree) in build_all(&boxes, None, &objects(2)) {
        assert_eq!(tree.nodes.len(), 1, "{p:?}");
    }
}

#[test]
fn a_flat_scene_gives_valid_trees() {
    let boxes: Vec<Aabb> =
        scattered(60).iter().map(|a| b([a.min.x, a.min.y, 0.0, a.max.x, a.max.y, 0.0])).collect();
    build_all(&boxes, None, &objects(3));
}

#[test]
fn a_line_of_boxes_gives_valid_trees() {
    let boxes: Vec<Aabb> =
        (0..45).map(|i| b([f64::from(i % 11), 0.0, 0.0, f64::from(i % 11) + 2.0, 0.0, 0.0])).collect();
    build_all(&boxes, None, &objects(3));
}

#[test]
fn rate_zero_and_rate_one_half_give_valid_trees() {
    let boxes = scattered(70);
    for rate in [0.0, 0.5] {
        build_all(&boxes, None, &BuildParams { rate, ..objects(3) });
    }
    // R = 0.5 cuts every node of MOA, LAA, median and Hilbert into halves;
    // the SAH family (and refine, which may keep its cuts) ignores R.
    for (p, tree) in build_all(&boxes, None, &BuildParams { rate: 0.5, ..objects(1) }) {
        if matches!(p.method, Method::Sah | Method::Vsah | Method::Refine) {
            continue;
        }
        assert_eq!(tree.depth(), 8, "{p:?}");
    }
}

#[test]
fn a_one_object_page_puts_every_object_in_its_own_leaf() {
    let boxes = scattered(50);
    for (p, tree) in build_all(&boxes, None, &objects(1)) {
        assert_eq!(tree.leaves().count(), 50, "{p:?}");
        assert!(tree.leaves().all(|(_, o)| o.len() == 1));
    }
}

#[test]
fn a_tree_as_deep_as_its_object_count_does_not_overflow_the_stack() {
    // Disjoint boxes along x: with R = 0 the paper's first-found rule cuts
    // one object off at every level, 4000 levels on a 2 MiB test thread.
    // (The walk that grows it also grows LAA's trials.)
    let boxes: Vec<Aabb> =
        (0..4000).map(|i| b([f64::from(i) * 2.0, 0.0, 0.0, f64::from(i) * 2.0 + 1.0, 1.0, 1.0])).collect();
    let p = BuildParams { method: Method::Moa, rate: 0.0, ..objects(1) };
    let tree = build(&boxes, None, &p, &|_| {}).unwrap();
    tree.validate(&boxes, None, &p).unwrap();
    assert_eq!(tree.depth(), 4000);
}
