//! The reports reproduce the paper's tables on a scene worked by hand:
//! the per-level rows of Tables 2-38 (N. leaves, ovMin, ovMinRel, ovMax,
//! none for a level of leaves only), the totals of Tables 39-44
//! (ovAccumulated, N_g, ovAverage), and their JSON keys; and the tree
//! serialises in the dump format.

use mktree::bulk::{BuildParams, LeafRule, Method, Report, TieBreak, TreeShape, build};
use mktree::geom::Aabb;
use serde_json::json;

/// Four boxes along x, each overlapping the next by 1: [0,3] [2,5] [4,7]
/// [6,9], all [0,10] on y and z. Every x cut overlaps by 1, every y or z
/// cut by 10.
fn chain() -> Vec<Aabb> {
    (0..4)
        .map(|i| Aabb::from_array([2.0 * f64::from(i), 0.0, 0.0, 2.0 * f64::from(i) + 3.0, 10.0, 10.0]))
        .collect()
}

fn moa(tie_break: TieBreak) -> BuildParams {
    BuildParams {
        method: Method::Moa,
        rate: 0.0,
        leaf: LeafRule::Objects(1),
        tie_break,
        ..BuildParams::paper()
    }
}

#[test]
fn first_found_peels_the_chain_and_the_tables_show_it() {
    // The first cut of least overlap is always after the first object:
    // {0}|{1,2,3}, then {1}|{2,3}, then {2}|{3}. Extents on x: 9, 7, 5.
    let boxes = chain();
    let tree = build(&boxes, None, &moa(TieBreak::FirstFound), &|_| {}).unwrap();
    let report = Report::of(&tree);
    assert_eq!(
        serde_json::to_value(&report).unwrap(),
        json!({
            "levels": [
                {"level": 0, "leaves": 0, "ov_min": 1.0, "ov_min_rel": 1.0 / 9.0, "ov_max": 1.0},
                {"level": 1, "leaves": 1, "ov_min": 1.0, "ov_min_rel": 1.0 / 7.0, "ov_max": 1.0},
                {"level": 2, "leaves": 1, "ov_min": 1.0, "ov_min_rel": 1.0 / 5.0, "ov_max": 1.0},
                {"level": 3, "leaves": 2, "ov_min": null, "ov_min_rel": null, "ov_max": null},
            ],
            "ov_accumulated": 3.0,
            "grey_nodes": 3,
            "ov_average": 1.0,
            "depth": 4,
            "leaves": 4,
            "objects": 4,
        })
    );
    let shape = TreeShape::of(&tree).unwrap();
    assert_eq!((shape.min_leaf_level, shape.max_leaf_level, shape.max_leaf_objects), (1, 3, 1));
    assert_eq!(shape.mean_leaf_level, 2.25);
}

#[test]
fn most_balanced_halves_the_chain() {
    let tree = build(&chain(), None, &moa(TieBreak::MostBalanced), &|_| {}).unwrap();
    let report = Report::of(&tree);
    assert_eq!(report.depth, 3);
    assert_eq!(report.levels[1].leaves, 0);
    assert_eq!((report.levels[2].leaves, report.grey_nodes, report.ov_accumulated), (4, 3, 3.0));
}

#[test]
fn a_single_leaf_has_no_grey_nodes_and_a_zero_average() {
    let tree = build(&chain(), None, &BuildParams::paper(), &|_| {}).unwrap();
    let report = Report::of(&tree);
    assert_eq!((report.grey_nodes, report.ov_average, report.depth, report.leaves), (0, 0.0, 1, 1));
    assert_eq!(report.levels[0].ov_min, None);
}

#[test]
fn the_tree_serialises_in_the_dump_format() {
    let tree = build(&chain(), None, &moa(TieBreak::FirstFound), &|_| {}).unwrap();
    let dump = serde_json::to_value(&tree).unwrap();
    assert_eq!(
        dump["nodes"][0],
        json!({
            "id": 0, "level": 0, "aabb": [0.0, 0.0, 0.0, 9.0, 10.0, 10.0],
            "children": [1, 2], "objects": null,
            "split": {"axis": "x", "order": "min", "overlap": 1.0, "gap": 1.0},
        })
    );
    assert_eq!(
        dump["nodes"][1],
        json!({"id": 1, "level": 1, "aabb": [0.0, 0.0, 0.0, 3.0, 10.0, 10.0], "children": null, "objects": [0], "split": null})
    );
    assert_eq!(dump["nodes"].as_array().unwrap().len(), 7);
}
