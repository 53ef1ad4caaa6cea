//! Claim: clash detection by the tree against itself finds exactly the
//! pairs that brute force over all pairs finds at k = M (with and without a
//! clearance), a superset at every k < M, and reads no block twice: at most
//! the file's blocks.

mod common;

use common::{arb_scene, lod_db};
use mktree::lod::LodParams;
use mktree::query::{ClashOptions, brute_force_clash, clash};
use mktree::scene::Scene;
use mktree::scene::generate::{GenOptions, Preset, generate_scene};
use proptest::prelude::*;

fn check(scene: &Scene, db: &mktree::db::Database, clearance: f64) {
    let r = db.begin_read().unwrap();
    let m = db.lod_levels();
    let exact = brute_force_clash(scene, clearance).unwrap();
    for k in 1..=m {
        let got = clash(&r, &ClashOptions { lod: Some(k), clearance }, None).unwrap();
        assert!(got.stats.reads.total() <= u64::from(got.file_blocks), "a block read twice");
        if k == m {
            assert_eq!(got.pairs, exact, "k = M, d = {clearance}");
        } else {
            let missed: Vec<_> = exact.iter().filter(|p| !got.pairs.contains(p)).collect();
            assert!(missed.is_empty(), "level {k}, d = {clearance}: missed {missed:?}");
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(32))]
    #[test]
    fn clash_pairs_are_exact_at_m_and_supersets_below(
        scene in arb_scene(50),
        clearance in prop_oneof![Just(0.0), 0.0f64..60.0],
        m in 2u8..=4,
        cap in 1u32..6,
    ) {
        let db = lod_db(&scene, m, 2048, cap, LodParams::default());
        check(&scene, &db, clearance);
    }
}

#[test]
fn tanker1_clashes_equal_brute_force() {
    let scene = generate_scene(&GenOptions { preset: Preset::Tanker1, objects: None, seed: 0 }).unwrap();
    let db = lod_db(&scene, 4, 16 * 1024, 20, LodParams::default());
    check(&scene, &db, 0.0);
    check(&scene, &db, 50.0);
}

#[test]
fn a_negative_clearance_is_an_error() {
    let scene = common::grid_scene(10);
    let db = lod_db(&scene, 3, 2048, 4, LodParams::default());
    let r = db.begin_read().unwrap();
    assert!(clash(&r, &ClashOptions { lod: None, clearance: -1.0 }, None).is_err());
}
