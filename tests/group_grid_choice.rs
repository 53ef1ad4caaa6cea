//! Claim (format-spec/group.md, "What is stored"): a bulk load builds its
//! group bounds on grids of twice the asked cells when its group blocks
//! still hold the level-2 bound of 99% of the nodes, and on the asked grids
//! otherwise; the meta block names the grids it chose, so a reader derives
//! them, and the bounds hold their objects either way.

use mktree::db::{CreateOptions, Database, GroupSummary, check};
use mktree::lod::LodParams;
use mktree::scene::Scene;
use mktree::scene::generate::{GenOptions, Preset, generate_scene};

fn scene(preset: Preset, objects: u64) -> Scene {
    generate_scene(&GenOptions { preset, objects: Some(objects), seed: 0 }).unwrap()
}

/// `scene` bulk-loaded with 16 KiB blocks, M = 4 and level-2 group grids
/// of at most `cells` cells asked; its group summary.
fn groups(scene: &Scene, cells: u32) -> GroupSummary {
    let db = Database::create_on(
        std::sync::Arc::new(mktree::store::device::MemDevice::new()),
        CreateOptions { block_size: 16384, lod_levels: 4 },
    )
    .unwrap();
    let mut w = db.begin_write().unwrap();
    w.set_lod_params(LodParams { cuberille_bits: cells, ..LodParams::default() });
    w.bulk_load(scene, &mktree::bulk::BuildParams::default(), &|_| {}).unwrap();
    w.commit().unwrap();
    assert!(check(&db).unwrap().ok());
    db.begin_read().unwrap().group_summary().unwrap()
}

/// The share of the nodes whose level-2 bound is stored (every node of
/// these scenes bounds some surface, so each has one to store).
fn level2_kept(g: &GroupSummary) -> f64 {
    g.levels[0].stored as f64 / g.nodes as f64
}

#[test]
fn finer_grids_are_taken_where_the_group_blocks_hold_them() {
    // Ship 5,000: the finer level-2 bounds all fit (at 10^4 they did
    // until node blocks were packed fuller, each with its group block).
    let g = groups(&scene(Preset::Ship, 5_000), 4096);
    assert_eq!(g.cuberille_bits, 8192, "{g:?}");
    assert!(level2_kept(&g) >= 0.99, "{g:?}");
}

#[test]
fn the_asked_grids_are_kept_where_finer_ones_would_not_fit() {
    // The plant's bounds are larger: at 8,192 cells its group blocks drop
    // more than 1 in 100 level-2 bounds, so 4,096 stays.
    let plant = scene(Preset::Plant, 3_000);
    let g = groups(&plant, 4096);
    assert_eq!(g.cuberille_bits, 4096, "{g:?}");
    assert_eq!(level2_kept(&g), 1.0, "{g:?}");
    // Asked for 8,192 (so 16,384 tried first, and refused), the load
    // builds on 8,192 and shows what the default build refused.
    let finer = groups(&plant, 8192);
    assert_eq!(finer.cuberille_bits, 8192, "{finer:?}");
    assert!(level2_kept(&finer) < 0.99, "{finer:?}");
}
