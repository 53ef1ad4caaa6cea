//! Claims about the levels of detail a version 3 file stores, through the
//! public API:
//!
//! - `check` finds no fault on random scenes for M = 1 .. 5, whether every
//!   bound is stored (`LodParams::store_all`) or only those that pay;
//! - every stored bound B(o,k) holds its object's surface (sampled points,
//!   read back with `fetch_level` as `Piece::ObjectVoxels`), and not the
//!   inside of a closed object: version 3 bounds are surface cells;
//! - an object's bound at level k + 1 lies in its bound at level k: level
//!   k + 1 sits on a finer level of the one lattice (the cuberille, k = 2,
//!   on the coarsest), and a finer surface set lifts into a coarser one;
//! - `check` catches a forged bound, one set cell cleared (with every
//!   checksum up the chain made to match again);
//! - the policy stores no bound for a scene whose bounds buy nothing
//!   (axis-aligned boxes), and does store some where they pay;
//! - user eps values bound every stored level's cells; bad ones are a
//!   typed error.
//!
//! Dropped from version 2: "b(S_n,k+1) lies in b(S_n,k)" and "bounds have
//! fewer faces than long triangle strips". Version 3 stores no group bounds
//! b(S_n,k) (only leaf records hold bounds, one per entry and level), and
//! a closed object's bound is its surface, no longer its filled solid.

mod common;

use std::collections::HashMap;
use std::sync::Arc;

use common::{arb_scene, box_mesh, forge, grid_scene, triangle};
use mktree::bulk::{BuildParams, LeafRule, Method};
use mktree::db::{CreateOptions, Database, Piece, check};
use mktree::geom::Point;
use mktree::lod::{LodParams, Voxels};
use mktree::scene::{Object, ObjectId, Scene};
use mktree::store::BlockDevice;
use mktree::store::ReadStats;
use mktree::store::device::MemDevice;
use proptest::prelude::*;

/// `scene` in a fresh in-memory file: M levels, blocks of `bs` bytes, MOA
/// leaves of at most `cap` objects; also the device, to forge its bytes.
fn build(scene: &Scene, m: u8, bs: u32, cap: u32, lod: LodParams) -> (Database, Arc<MemDevice>) {
    let dev = Arc::new(MemDevice::new());
    let db = Database::create_on(
        dev.clone() as Arc<dyn BlockDevice>,
        CreateOptions { block_size: bs, lod_levels: m },
    )
    .unwrap();
    let mut w = db.begin_write().unwrap();
    w.set_lod_params(lod);
    let params = BuildParams { method: Method::Moa, leaf: LeafRule::Objects(cap), ..BuildParams::paper() };
    w.bulk_load(scene, &params, &|_| {}).unwrap();
    w.commit().unwrap();
    (db, dev)
}

fn store_all() -> LodParams {
    LodParams { store_all: true, ..LodParams::default() }
}

/// Every object's bound at level k as `fetch_level` reads it from the root:
/// its finest stored voxel set up to k, or `None` when it has only its box.
fn bounds_at(db: &Database, k: u8) -> HashMap<ObjectId, Option<Voxels>> {
    let r = db.begin_read().unwrap();
    let level = r.fetch_level(0, k, true, &mut ReadStats::default()).unwrap();
    let mut out = HashMap::new();
    for piece in level.pieces {
        match piece {
            Piece::ObjectVoxels(v) => out.extend(v.into_iter().map(|(id, v)| (id, Some(v)))),
            Piece::ObjectBoxes(b) => out.extend(b.into_iter().map(|(id, _)| (id, None))),
            other => panic!("level {k} of the root holds {other:?}"),
        }
    }
    out
}

/// Vertices and a spread of points on every triangle of `scene`'s object `id`.
fn surface_points(scene: &Scene, id: ObjectId) -> Vec<Point> {
    let mesh = &scene.objects()[id.index()].mesh;
    let mut out: Vec<Point> = mesh.vertices().collect();
    for t in mesh.triangle_points() {
        for (a, b) in [(0.5, 0.0), (0.0, 0.5), (0.5, 0.5), (1.0 / 3.0, 1.0 / 3.0), (0.1, 0.8), (0.7, 0.2)] {
            out.push(t[0] + (t[1] - t[0]) * a + (t[2] - t[0]) * b);
        }
    }
    out
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn random_scenes_check_clean_for_every_m_with_and_without_store_all(
        scene in arb_scene(30),
        m in 1u8..=5,
        cap in 1u32..5,
        bs in prop::sample::select(vec![1024u32, 2048, 4096]),
        all in any::<bool>(),
    ) {
        let (db, _) = build(&scene, m, bs, cap, LodParams { store_all: all, ..LodParams::default() });
        let report = check(&db).unwrap();
        prop_assert!(report.ok(), "{:?}", report.faults);
        let info = db.begin_read().unwrap().lod_info().unwrap();
        if all && m >= 3 {
            // Every object's cuberille fits its cell budget, so each has one.
            prop_assert_eq!(info.stored[1], scene.len() as u64);
        }
        prop_assert_eq!(info.stored.len(), usize::from(m));
    }

    #[test]
    fn every_stored_bound_holds_its_objects_surface(
        scene in arb_scene(24), m in 3u8..=5, cap in 1u32..5,
    ) {
        let (db, _) = build(&scene, m, 4096, cap, store_all());
        let info = db.begin_read().unwrap().lod_info().unwrap();
        for k in 2..m {
            let bounds = bounds_at(&db, k);
            prop_assert_eq!(bounds.len(), scene.len(), "level {} reaches every object", k);
            let voxels = bounds.values().filter(|v| v.is_some()).count() as u64;
            // Objects without a level-k bound answer with a coarser one.
            prop_assert!(voxels >= info.stored[usize::from(k) - 1]);
            for (id, v) in &bounds {
                let Some(v) = v else { continue };
                for p in surface_points(&scene, *id) {
                    prop_assert!(v.contains_point(&p), "level {} of object {}: {:?} outside", k, id, p);
                }
                // Every cell holds a piece of the surface: the bound is no larger than it must be.
                let surface = Voxels::of_surfaces(v.grid().clone(), [&scene.objects()[id.index()].mesh]);
                prop_assert_eq!(&surface, v, "level {} of object {} is not its surface cells", k, id);
            }
        }
        prop_assert_eq!(bounds_at(&db, 2).values().filter(|v| v.is_some()).count(), scene.len());
    }

    #[test]
    fn an_objects_bound_at_level_k_plus_1_lies_in_its_bound_at_level_k(
        scene in arb_scene(24), m in 4u8..=6, cap in 1u32..5,
    ) {
        let (db, _) = build(&scene, m, 4096, cap, store_all());
        let mut coarser = bounds_at(&db, 2);
        for k in 3..m {
            let finer = bounds_at(&db, k);
            for (id, f) in &finer {
                let (Some(f), Some(Some(c))) = (f, coarser.get(id)) else {
                    return Err(TestCaseError::fail(format!("object {id} lost its bound between levels {} and {k}", k - 1)));
                };
                prop_assert!(f.grid().level() <= c.grid().level(), "level {} is coarser than level {}", k, k - 1);
                prop_assert!(f.is_subset_of(c).unwrap(), "object {}: level {} leaves level {}", id, k, k - 1);
            }
            coarser = finer;
        }
    }
}

#[test]
fn a_closed_boxs_bound_holds_its_surface_not_its_inside() {
    let scene = Scene::new(vec![
        Object::new("box", box_mesh([0.0; 3], [100.0, 100.0, 100.0])),
        Object::new("twin", box_mesh([200.0, 0.0, 0.0], [300.0, 100.0, 100.0])),
    ]);
    // Cells of about 12 mm (eps 20 mm at level 3, the cuberille as fine
    // within its budget): a 100 mm box is several cells across, so its
    // inside is cells of their own. (With the default eps, from the median
    // object's sides, it would be two cells across, each touching a face.)
    let lod = LodParams { eps: Some(vec![20.0]), ..store_all() };
    let (db, _) = build(&scene, 4, 4096, 4, lod);
    assert!(check(&db).unwrap().ok());
    for k in 2..4 {
        let bounds = bounds_at(&db, k);
        let v = bounds[&ObjectId(0)].as_ref().expect("store_all stores a bound");
        assert!(v.contains_point(&Point::new(0.0, 50.0, 50.0)), "level {k}: a face point");
        assert!(!v.contains_point(&Point::new(50.0, 50.0, 50.0)), "level {k}: the centre is not surface");
    }
}

#[test]
fn user_eps_bound_every_stored_levels_cells() {
    let scene = grid_scene(60);
    for eps in [vec![80.0, 40.0, 20.0], vec![30.0, 30.0, 30.0]] {
        let (db, _) = build(&scene, 6, 4096, 4, LodParams { eps: Some(eps.clone()), ..store_all() });
        let report = check(&db).unwrap();
        assert!(report.ok(), "eps {eps:?}: {:?}", report.faults);
        let info = db.begin_read().unwrap().lod_info().unwrap();
        for (k, e) in eps.iter().enumerate() {
            let k = k + 3;
            assert!(info.stored[k - 1] > 0, "level {k} stores bounds");
            assert!(
                info.eps[k - 1] <= *e * (1.0 + 1e-6),
                "level {k} eps {} above the asked {e}",
                info.eps[k - 1]
            );
            for v in bounds_at(&db, k as u8).values().flatten() {
                assert!(
                    v.grid().max_cell_diagonal() <= *e * (1.0 + 1e-6),
                    "level {k}: a cell wider than {e}"
                );
            }
        }
    }
}

#[test]
fn bad_eps_is_a_typed_error_not_a_panic() {
    let scene = grid_scene(10);
    let db =
        Database::create_on(Arc::new(MemDevice::new()), CreateOptions { block_size: 4096, lod_levels: 5 })
            .unwrap();
    for eps in [vec![1.0], vec![1.0, 2.0], vec![-1.0, -2.0], vec![f64::NAN, 1.0]] {
        let mut w = db.begin_write().unwrap();
        w.set_lod_params(LodParams { eps: Some(eps.clone()), ..LodParams::default() });
        let err = w.bulk_load(&scene, &BuildParams::paper(), &|_| {}).unwrap_err();
        assert!(err.to_string().contains("eps"), "{eps:?}: {err}");
    }
}

/// Rods along the space diagonal: their boxes are mostly empty, so a query
/// that meets a box usually misses the rod, and a bound says so.
fn diagonal_rods(n: usize) -> Scene {
    Scene::new(
        (0..n)
            .map(|i| {
                let o = [(i % 5) as f64 * 300.0, (i / 5 % 5) as f64 * 300.0, (i / 25) as f64 * 300.0];
                let m = triangle(
                    o,
                    [o[0] + 250.0, o[1] + 250.0, o[2] + 250.0],
                    [o[0] + 252.0, o[1] + 250.0, o[2] + 250.0],
                );
                Object::new(format!("rod{i}"), m)
            })
            .collect(),
    )
}

/// `n` axis-aligned boxes of side `side` mm, 100 mm apart.
fn small_boxes(n: usize, side: f64) -> Scene {
    Scene::new(
        (0..n)
            .map(|i| {
                let o = [(i % 5) as f64 * 100.0, (i / 5 % 5) as f64 * 100.0, (i / 25) as f64 * 100.0];
                Object::new(format!("b{i}"), box_mesh(o, [o[0] + side, o[1] + side, o[2] + side]))
            })
            .collect(),
    )
}

#[test]
fn bounds_are_stored_only_where_they_pay() {
    // Small axis-aligned boxes under the default query model (queries of
    // the mean object extent + 100 mm): a query that meets such a box
    // nearly always holds one of its faces, so the box decides it already
    // and a voxel bound would only cost bytes. None is stored.
    let (db, _) = build(&small_boxes(100, 2.0), 4, 4096, 8, LodParams::default());
    let info = db.begin_read().unwrap().lod_info().unwrap();
    assert_eq!(&info.stored[1..3], &[0, 0], "small boxes store no bound: {info:?}");
    assert_eq!(&info.bytes[1..3], &[0, 0]);
    assert!(check(&db).unwrap().ok());
    // Diagonal rods: a bound rules out most queries their boxes let through.
    let (db, _) = build(&diagonal_rods(50), 4, 4096, 8, LodParams::default());
    let info = db.begin_read().unwrap().lod_info().unwrap();
    assert!(info.stored[1..3].iter().sum::<u64>() > 0, "rods store bounds: {info:?}");
    assert!(info.predicted_saving[1..3].iter().zip(&info.predicted_cost[1..3]).all(|(s, c)| s >= c));
    assert!(check(&db).unwrap().ok());
}

#[test]
fn check_catches_a_forged_bound_that_misses_part_of_its_surface() {
    use mktree::store::format::frame::BlockType;
    // Slanted triangles, stored with every bound, in 1 KiB blocks: several
    // node blocks, so the forged leaf's checksum is held by a parent entry.
    let scene = Scene::new(common::slanted_triangles(24));
    let (db, dev) = build(&scene, 4, 1024, 3, store_all());
    assert!(check(&db).unwrap().ok());
    drop(db);
    let mut img = forge::Image { bytes: dev.to_bytes(), bs: 1024 };
    let nodes = img.blocks_of(BlockType::Node);
    assert!(nodes.len() > 1, "the scene spans several node blocks");
    // A bitmap bound (form 1) in the last node block: clear its first set cell.
    let (block, blob) = nodes
        .iter()
        .rev()
        .flat_map(|&b| img.records(b).into_iter().map(move |r| (b, r)))
        .filter(|&(_, r)| img.bytes[r] == 2)
        .flat_map(|(b, r)| img.leaf_bounds(r).into_iter().map(move |x| (b, x)))
        .find(|(_, (_, _, at, _))| img.bytes[at + 1] == 1)
        .map(|(b, (_, _, at, len))| (b, at..at + len))
        .expect("a bitmap bound");
    let root_block = u32::from_le_bytes(img.bytes[img.meta() * 1024 + 16..][..4].try_into().unwrap());
    assert_ne!(block as u32, root_block, "the forged leaf's checksum is held by a parent entry");
    // The blob's head is its lattice level and form; the bitmap follows.
    let bits = blob.start + 2..blob.end;
    let byte = bits.clone().find(|&i| img.bytes[i] != 0).expect("a set cell");
    img.bytes[byte] &= img.bytes[byte] - 1;
    img.reseal(block, BlockType::Node);
    let db = Database::open_on(Arc::new(MemDevice::from_bytes(img.bytes)) as Arc<dyn BlockDevice>).unwrap();
    let report = check(&db).unwrap();
    assert!(!report.faults.is_empty(), "the forged bound went unnoticed");
    // Every checksum matches again: the bound is the one fault.
    assert!(report.faults.iter().all(|f| f.contains("does not hold its surface")), "{:?}", report.faults);
}
