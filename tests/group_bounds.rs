//! Claim (format-spec/group.md): every group bound b(S_n,k) a bulk load
//! stores contains every object of its node's subtree (each triangle meets
//! a set cell, each vertex lies in one) and lies within its error of them
//! (every corner of every set cell is within the cell diagonal of some
//! triangle), an error the reader knows from the node's box before reading
//! the bound; fetching it reads exactly the one block its record predicts;
//! and a change commit leaves no group bound stale (the blocks it rewrites
//! carry none, and `check` passes).

mod common;

use std::collections::{BTreeMap, BTreeSet};

use common::{arb_scene, lod_db};
use mktree::bulk::NodeId;
use mktree::db::{Database, Piece, read_hierarchy};
use mktree::geom::{Point, Vector, distance_point_triangle};
use mktree::lod::{LodParams, Voxels};
use mktree::scene::generate::{GenOptions, Preset, generate_scene};
use mktree::scene::{Key, ObjectId, Scene};
use mktree::store::ReadStats;
use proptest::prelude::*;

/// The objects of node `id`'s subtree.
fn subtree(tree: &mktree::bulk::Hierarchy, id: u32) -> BTreeSet<ObjectId> {
    let mut out = BTreeSet::new();
    let mut stack = vec![NodeId(id)];
    while let Some(n) = stack.pop() {
        match (tree.node(n).and_then(|x| x.children()), tree.node(n).and_then(|x| x.objects())) {
            (Some(c), _) => stack.extend(c),
            (None, Some(o)) => out.extend(o.iter().copied()),
            _ => {}
        }
    }
    out
}

/// Each object's triangles, by id.
type Triangles = BTreeMap<ObjectId, Vec<[Point; 3]>>;

fn triangles_of(scene: &Scene) -> Triangles {
    (0..scene.len())
        .map(|i| (ObjectId(i as u32), scene.objects()[i].mesh.triangle_points().collect()))
        .collect()
}

/// Checks containment and eps of `v` against `objects`.
fn contains_within_eps(all: &Triangles, objects: &BTreeSet<ObjectId>, v: &Voxels, what: &str) {
    let tris: Vec<[Point; 3]> = objects.iter().flat_map(|o| all[o].iter().copied()).collect();
    for t in &tris {
        assert!(v.intersects_triangle(t), "{what}: a triangle misses the bound");
        for p in t {
            assert!(v.contains_point(p), "{what}: a vertex lies outside the bound");
        }
    }
    let eps = v.grid().max_cell_diagonal();
    for cell in v.cell_boxes() {
        for c in cell.corners() {
            let d = tris.iter().map(|t| distance_point_triangle(&c, t)).fold(f64::INFINITY, f64::min);
            assert!(d <= eps * (1.0 + 1e-9), "{what}: a cell corner {d} mm from the objects, eps {eps}");
        }
    }
}

/// Every node's stored group bounds: contained, within eps, one read each.
/// Returns how many were checked.
fn check_groups(db: &Database, all: &Triangles) -> usize {
    let r = db.begin_read().unwrap();
    let m = db.lod_levels();
    let tree = read_hierarchy(&r).unwrap();
    let rule = r.group_rule();
    let mut checked = 0;
    for id in 0..tree.nodes.len() as u32 {
        let objects = subtree(&tree, id);
        for k in 2..m {
            let mut stats = ReadStats::default();
            let level = r.fetch_level(id, k, false, &mut stats).unwrap();
            let [Piece::Group { voxels, level: got, node }] = &level.pieces[..] else { continue };
            assert_eq!((*got, *node), (k, id));
            assert_eq!((level.predicted_reads, stats.total(), stats.group), (1, 1, 1), "node {id} k={k}");
            let rule = rule.as_ref().expect("a file with group bounds has a rule");
            let eps = rule.eps(k, &tree.nodes[id as usize].aabb).unwrap();
            assert_eq!(eps, voxels.grid().max_cell_diagonal(), "the error is known from the box");
            contains_within_eps(all, &objects, voxels, &format!("node {id} k={k}"));
            checked += 1;
        }
    }
    checked
}

#[test]
fn tanker1s_group_bounds_hold_their_objects_within_eps_and_cost_one_read() {
    let scene = generate_scene(&GenOptions { preset: Preset::Tanker1, objects: None, seed: 2 }).unwrap();
    let db = lod_db(&scene, 4, 16384, 10, LodParams::default());
    let checked = check_groups(&db, &triangles_of(&scene));
    let r = db.begin_read().unwrap();
    let summary = r.group_summary().unwrap();
    assert_eq!(checked as u64, summary.levels.iter().map(|l| l.stored).sum::<u64>());
    assert!(summary.levels[0].stored == summary.nodes, "every node has a level-2 bound: {summary:?}");
    assert!(summary.levels[0].root_faces.is_some_and(|f| f > 6), "{summary:?}");
    // The root's bound is coarser than its objects' boxes (tanker1: 222 boxes, 1,332 faces).
    assert!(summary.levels[0].root_faces.unwrap() < 1332);
}

#[test]
fn without_group_bounds_a_level_is_gathered_from_the_subtree() {
    let scene = generate_scene(&GenOptions { preset: Preset::Tanker1, objects: None, seed: 2 }).unwrap();
    let db = lod_db(&scene, 4, 16384, 10, LodParams { group_bounds: false, ..LodParams::default() });
    assert_eq!(check_groups(&db, &triangles_of(&scene)), 0);
    let r = db.begin_read().unwrap();
    assert_eq!(r.group_summary().unwrap().blocks, 0);
    let level = r.fetch_level(0, 2, false, &mut ReadStats::default()).unwrap();
    assert!(level.pieces.iter().all(|p| !matches!(p, Piece::Group { .. })));
}

#[test]
fn a_change_commit_leaves_no_stale_group_bound() {
    let scene = generate_scene(&GenOptions { preset: Preset::Tanker2, objects: Some(600), seed: 1 }).unwrap();
    let db = lod_db(&scene, 4, 4096, 8, LodParams::default());
    let before = db.begin_read().unwrap().group_summary().unwrap();
    assert!(before.blocks > 1, "{before:?}");
    let mut w = db.begin_write().unwrap();
    w.move_by(&Key::Int(5), Vector::new(3000.0, 0.0, 0.0)).unwrap();
    assert!(w.commit_with_stats().unwrap().in_place);
    let report = mktree::db::check(&db).unwrap();
    assert!(report.ok(), "{:?}", report.faults);
    let after = db.begin_read().unwrap().group_summary().unwrap();
    assert!(after.blocks < before.blocks, "the rewritten blocks' group blocks went: {before:?} -> {after:?}");
    // What is left still holds its objects, as the file now stores them
    // (an updated object may take a new id).
    let r = db.begin_read().unwrap();
    let mut stored = Triangles::new();
    for piece in r.fetch_level(0, 4, true, &mut ReadStats::default()).unwrap().pieces {
        let Piece::Objects(objects) = piece else { panic!("level M holds objects") };
        for (id, mesh) in objects {
            stored.entry(id).or_default().extend(mesh.triangle_points());
        }
    }
    drop(r);
    assert!(check_groups(&db, &stored) > 0, "the blocks the commit left keep their group bounds");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(16))]
    #[test]
    fn group_bounds_of_random_scenes_hold_their_objects_within_eps(
        scene in arb_scene(40),
        cap in 1u32..5,
        m in 3u8..6,
        bs in prop::sample::select(vec![1024u32, 4096]),
    ) {
        let lods = LodParams { cuberille_bits: 64, ..LodParams::default() };
        let db = lod_db(&scene, m, bs, cap, lods);
        check_groups(&db, &triangles_of(&scene));
        prop_assert!(mktree::db::check(&db).unwrap().ok());
    }
}
