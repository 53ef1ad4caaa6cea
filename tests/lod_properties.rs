//! Claims about the levels of detail a file stores (issue 5), through the
//! public API: `check` finds no fault (containment, nesting, eps, predicted
//! reads) on random scenes for every M; every bound contains its objects'
//! surface points; b(S_n,k+1) lies in b(S_n,k); and `check` does catch a
//! bound that misses part of its object.

mod common;

use common::{arb_scene, box_mesh, grid_scene, triangle};
use mktree::build::{BuildParams, LeafRule, Method};
use mktree::db::{CreateOptions, Database, Piece, check};
use mktree::geom::Point;
use mktree::lod::LodParams;
use mktree::scene::{Object, Scene};
use mktree::store::ReadStats;
use proptest::prelude::*;

fn build(scene: &Scene, m: u8, bs: u32, cap: u32, lod: LodParams) -> Database {
    let db = Database::create_on(
        std::sync::Arc::new(mktree::store::device::MemDevice::new()),
        CreateOptions { block_size: bs, lod_levels: m },
    )
    .unwrap();
    let mut w = db.begin_write().unwrap();
    w.set_lod_params(lod);
    let params = BuildParams { method: Method::Moa, leaf: LeafRule::Objects(cap), ..BuildParams::default() };
    w.bulk_load(scene, &params, &|_| {}).unwrap();
    w.commit().unwrap();
    db
}

/// Every vertex of every object lies in every level's bound of every node
/// on its path, read back through `fetch_level`.
fn vertices_inside_every_level(db: &Database, scene: &Scene) {
    let r = db.begin_read().unwrap();
    let m = db.lod_levels();
    let nodes = common::all_nodes(&r);
    for (at, rec) in &nodes {
        // The node's objects, from level M.
        let exact = r.fetch_level(*at, m, true, &mut ReadStats::default()).unwrap();
        let points: Vec<Point> = exact
            .pieces
            .iter()
            .flat_map(|p| match p {
                Piece::Objects(o) => {
                    o.iter().flat_map(|(id, _)| scene.objects()[id.index()].mesh.vertices()).collect()
                }
                _ => Vec::new(),
            })
            .collect();
        for k in 1..m {
            for objects in [false, true] {
                let level = r.fetch_level(*at, k, objects, &mut ReadStats::default()).unwrap();
                for p in &points {
                    let inside = level.pieces.iter().any(|piece| match piece {
                        Piece::Box { aabb, .. } => aabb.contains_point(p),
                        Piece::ObjectBoxes(b) => b.iter().any(|(_, a)| a.contains_point(p)),
                        Piece::Voxels { voxels, .. } => voxels.contains_point(p),
                        Piece::ObjectVoxels(v) => v.iter().any(|(_, v)| v.contains_point(p)),
                        Piece::Objects(_) => true,
                    });
                    assert!(inside, "node {} level {k} objects={objects}: {p:?} outside", rec.node_id);
                }
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(20))]
    #[test]
    fn random_scenes_check_clean_at_every_m(
        scene in arb_scene(40),
        m in 1u8..7,
        cap in 1u32..6,
        bs in prop::sample::select(vec![1024u32, 4096]),
        keep in any::<bool>(),
    ) {
        let db = build(&scene, m, bs, cap, LodParams { keep_identity: keep, ..LodParams::default() });
        let report = check(&db).unwrap();
        prop_assert!(report.ok(), "{:?}", report.faults);
        vertices_inside_every_level(&db, &scene);
    }
}

#[test]
fn user_eps_levels_nest_and_check_clean() {
    let scene = grid_scene(120);
    for eps in [vec![80.0, 40.0, 10.0], vec![30.0, 30.0, 30.0]] {
        let db = build(&scene, 6, 4096, 8, LodParams { eps: Some(eps.clone()), ..LodParams::default() });
        let report = check(&db).unwrap();
        assert!(report.ok(), "eps {eps:?}: {:?}", report.faults);
        let info = db.begin_read().unwrap().lod_info().unwrap();
        for (k, e) in eps.iter().enumerate() {
            assert!(
                info.eps[k + 2] <= *e * (1.0 + 1e-6),
                "level {} eps {} above the asked {e}",
                k + 3,
                info.eps[k + 2]
            );
        }
    }
}

#[test]
fn bad_eps_is_a_typed_error_not_a_panic() {
    let scene = grid_scene(10);
    let db = Database::create_on(
        std::sync::Arc::new(mktree::store::device::MemDevice::new()),
        CreateOptions { block_size: 4096, lod_levels: 5 },
    )
    .unwrap();
    for eps in [vec![1.0], vec![1.0, 2.0], vec![-1.0, -2.0], vec![f64::NAN, 1.0]] {
        let mut w = db.begin_write().unwrap();
        w.set_lod_params(LodParams { eps: Some(eps.clone()), ..LodParams::default() });
        let err = w.bulk_load(&scene, &BuildParams::default(), &|_| {}).unwrap_err();
        assert!(err.to_string().contains("eps"), "{eps:?}: {err}");
    }
}

#[test]
fn a_closed_box_is_filled_and_a_level_buying_nothing_is_not_stored_twice() {
    // A single closed box: every voxel level of it is a box, as few faces as
    // its 12 triangles or fewer; the per-object bound points to the group's.
    let scene = Scene::new(vec![Object::new("box", box_mesh([0.0; 3], [100.0, 100.0, 100.0]))]);
    let db = build(&scene, 5, 4096, 4, LodParams::default());
    assert!(check(&db).unwrap().ok());
    let r = db.begin_read().unwrap();
    let root = r.root().unwrap();
    let centre = Point::new(50.0, 50.0, 50.0);
    for k in 2..5 {
        let level = r.fetch_level(root, k, false, &mut ReadStats::default()).unwrap();
        let inside = level.pieces.iter().any(|p| match p {
            Piece::Voxels { voxels, .. } => voxels.contains_point(&centre),
            Piece::Objects(_) => true,
            _ => false,
        });
        assert!(inside, "level {k}: the interior of a closed box is part of its bound");
    }
}

#[test]
fn thin_plates_get_bounds_with_fewer_faces_than_long_triangle_strips() {
    // A plate of many triangles: the voxel levels need far fewer faces.
    let mut tris = Vec::new();
    for i in 0..200 {
        let x = i as f64 * 5.0;
        tris.push(triangle([x, 0.0, 0.0], [x + 5.0, 0.0, 0.0], [x, 50.0, 1.0]));
    }
    let scene =
        Scene::new(tris.into_iter().enumerate().map(|(i, m)| Object::new(format!("t{i}"), m)).collect());
    let db = build(&scene, 4, 4096, 50, LodParams::default());
    let report = check(&db).unwrap();
    assert!(report.ok(), "{:?}", report.faults);
    let r = db.begin_read().unwrap();
    let level2 = r.fetch_level(r.root().unwrap(), 2, false, &mut ReadStats::default()).unwrap();
    assert!(level2.faces() < 200, "the cuberille of 200 triangles has {} faces", level2.faces());
}

#[test]
fn check_catches_a_bound_that_misses_its_object() {
    use mktree::store::format::frame::{BlockType, seal};
    use mktree::store::format::header::{Commit, Slot, SlotRead, SlotState, slot_offset};
    // The golden file (M = 3): the second LOD block holds a leaf's cuberille.
    let mut f = std::fs::read(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/golden/tiny-v2.mkt")).unwrap();
    let bs = 1024;
    let block = |i: usize| i * bs..(i + 1) * bs;
    let all = |f: &[u8], t: BlockType| -> Vec<usize> {
        (1..f.len() / bs).filter(|&i| f[i * bs + 4] == t as u8).collect()
    };
    let (lod, node, meta) =
        (all(&f, BlockType::Lod)[1], all(&f, BlockType::Node)[0], all(&f, BlockType::Meta)[0]);
    // The first blob: length word at 24, the voxel blob after it, its bitmap at 68: clear every cell.
    let len = u32::from_le_bytes(f[lod * bs + 24..lod * bs + 28].try_into().unwrap()) as usize;
    f[lod * bs + 28 + 68..lod * bs + 28 + len].fill(0);
    let lod_sum = seal(lod as u32, &mut f[block(lod)], BlockType::Lod, 2);
    // Entries naming that block carry its checksum: records of 120 + 32 * 3 bytes from offset 24.
    let count = u16::from_le_bytes([f[node * bs + 16], f[node * bs + 17]]) as usize;
    for r in 0..count {
        for e in 0..6 {
            let at = node * bs + 24 + r * 216 + 120 + 16 * e;
            if f[at] == 1 && u32::from_le_bytes(f[at + 4..at + 8].try_into().unwrap()) == lod as u32 {
                f[at + 12..at + 16].copy_from_slice(&lod_sum.to_le_bytes());
            }
        }
    }
    let node_sum = seal(node as u32, &mut f[block(node)], BlockType::Node, 2);
    f[meta * bs + 20..meta * bs + 24].copy_from_slice(&node_sum.to_le_bytes());
    let meta_sum = seal(meta as u32, &mut f[block(meta)], BlockType::Meta, 2);
    let SlotRead::Committed(c) = Slot::decode(1, &f[slot_offset(1)..slot_offset(1) + 256]) else {
        panic!("slot 1")
    };
    let c = Commit { meta_checksum: meta_sum, ..c };
    f[slot_offset(1)..slot_offset(1) + 256].copy_from_slice(&Slot::encode(1, SlotState::Committed, &c));
    let db = Database::open_on(std::sync::Arc::new(mktree::store::device::MemDevice::from_bytes(f))).unwrap();
    let report = check(&db).unwrap();
    assert!(report.faults.iter().any(|f| f.contains("outside level 2")), "{:?}", report.faults);
}
