//! Claim: `ReadTransaction::layout_drift` says how far change commits moved
//! the node layout from a fresh one. A bulk load's layout is the fresh one
//! (the same reads at every scale, the same node blocks); single-object
//! moves that split leaves leave a layout whose sample queries read more
//! node blocks than a fresh packing of the same tree; `optimize` brings it
//! back to no drift.

use mktree::db::{CreateOptions, Database};
use mktree::geom::Vector;
use mktree::scene::generate::{GenOptions, Preset, generate_scene};
use mktree::scene::{Key, Scene};
use mktree::{BuildParams, LayoutDrift};
use proptest::prelude::*;

fn keyed(preset: Preset, objects: Option<u64>, seed: u64) -> Scene {
    let scene = generate_scene(&GenOptions { preset, objects, seed }).unwrap();
    Scene::new(scene.objects().iter().enumerate().map(|(i, o)| o.clone().with_key(i as u64)).collect())
}

fn loaded(dir: &std::path::Path, scene: &Scene, block_size: u32, lod_levels: u8) -> Database {
    let db = Database::create(dir.join("d.mkt"), CreateOptions { block_size, lod_levels }).unwrap();
    let mut w = db.begin_write().unwrap();
    w.bulk_load(scene, &BuildParams::for_blocks(block_size), &|_| {}).unwrap();
    w.commit().unwrap();
    db
}

fn drift(db: &Database) -> LayoutDrift {
    db.begin_read().unwrap().layout_drift().unwrap().expect("a tree")
}

fn assert_no_drift(d: &LayoutDrift) {
    assert_eq!(d.stored_reads, d.fresh_reads, "{d:?}");
    assert_eq!(d.stored_node_blocks, d.fresh_node_blocks, "{d:?}");
    assert_eq!(d.worst_ratio(), 1.0);
}

#[test]
fn moves_drift_the_layout_and_optimize_restores_it() {
    let dir = tempfile::tempdir().unwrap();
    let scene = keyed(Preset::Ship, Some(3_000), 11);
    let db = loaded(dir.path(), &scene, 4096, CreateOptions::default().lod_levels);
    let d = drift(&db);
    assert_eq!(d.stored_reads.len(), 4, "four scales of the query mix: {d:?}");
    assert!(d.stored_reads.iter().all(|&r| r >= 1.0), "every sample meets the root: {d:?}");
    assert_no_drift(&d);

    // Objects moved one per commit to far places land in leaves that split.
    let e = scene.aabb().extent();
    for i in 0..300u64 {
        let key = Key::Int((i * 7_919) % scene.len() as u64);
        let f = |k: u64| ((i * k) % 200) as f64 / 100.0 - 1.0;
        let by = Vector::new(e.x * 0.4 * f(13), e.y * 0.4 * f(29), e.z * 0.4 * f(31));
        let mut w = db.begin_write().unwrap();
        w.move_by(&key, by).unwrap();
        assert!(w.commit_with_stats().unwrap().in_place, "commit {i} went in place");
    }
    let d = drift(&db);
    assert!(d.worst_ratio() > 1.02, "300 moves drift the layout: {d:?}");
    assert!(d.stored_node_blocks > d.fresh_node_blocks, "{d:?}");

    let mut w = db.begin_write().unwrap();
    w.optimize().unwrap();
    w.commit().unwrap();
    assert_no_drift(&drift(&db));
}

#[test]
fn an_empty_file_has_no_drift_to_report() {
    let dir = tempfile::tempdir().unwrap();
    let db = Database::create(dir.path().join("e.mkt"), CreateOptions::default()).unwrap();
    assert_eq!(db.begin_read().unwrap().layout_drift().unwrap(), None);
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 12, ..ProptestConfig::default() })]

    /// A bulk load is laid out fresh, whatever the scene and block size.
    #[test]
    fn a_bulk_load_has_no_drift(
        seed in 0u64..1_000,
        objects in 100u64..600,
        block_size in prop::sample::select(vec![4096u32, 8192, 16384]),
        preset in prop::sample::select(vec![Preset::Ship, Preset::Plant]),
        lod_levels in prop::sample::select(vec![2u8, 4]),
    ) {
        let dir = tempfile::tempdir().unwrap();
        let db = loaded(dir.path(), &keyed(preset, Some(objects), seed), block_size, lod_levels);
        assert_no_drift(&drift(&db));
    }
}
