//! Claim (property 4 of the levels of detail): for every node, every level
//! k and both b(S_n,k) and B(S_n,k), the reads its record predicts for
//! fetching the level from a cold cache equal the reads done; and the reads
//! the pager counts are the reads the device sees.

mod common;

use std::sync::Arc;

use common::{arb_scene, grid_scene};
use mktree::bulk::NodeId;
use mktree::bulk::{BuildParams, LeafRule, Method};
use mktree::db::{CreateOptions, Database, Piece, read_hierarchy};
use mktree::geom::Aabb;
use mktree::store::ReadStats;
use mktree::store::device::{CountingDevice, MemDevice};
use proptest::prelude::*;

/// Checks every node of `db`: predicted = actual at every level, and at
/// level M the objects fetched are exactly the node's subtree's.
fn check_predictions(db: &Database) {
    let r = db.begin_read().unwrap();
    let m = db.lod_levels();
    let tree = read_hierarchy(&r).unwrap();
    for id in 0..tree.nodes.len() as u32 {
        let mut subtree = Vec::new();
        let mut stack = vec![NodeId(id)];
        while let Some(n) = stack.pop() {
            match (tree.node(n).and_then(|x| x.children()), tree.node(n).and_then(|x| x.objects())) {
                (Some(c), _) => stack.extend(c),
                (None, Some(o)) => subtree.extend_from_slice(o),
                _ => {}
            }
        }
        for k in 1..=m {
            for objects in [false, true] {
                let mut stats = ReadStats::default();
                let got = r.fetch_level(id, k, objects, &mut stats).unwrap();
                assert_eq!(stats.total(), got.predicted_reads, "node {id} k={k} objects={objects}");
                if k == m {
                    // Objects larger than a block come as several parts of one id.
                    let mut ids: Vec<_> = got
                        .pieces
                        .iter()
                        .flat_map(|p| match p {
                            Piece::Objects(o) => o.iter().map(|x| x.0).collect::<Vec<_>>(),
                            _ => panic!("level M holds objects"),
                        })
                        .collect();
                    ids.sort_unstable();
                    ids.dedup();
                    subtree.sort_unstable();
                    assert_eq!(ids, subtree);
                }
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]
    #[test]
    fn predicted_reads_equal_actual_reads(scene in arb_scene(80), cap in 1u32..6, bs in prop::sample::select(vec![1024u32, 1536, 4096]), m in 1u8..6) {
        let params = BuildParams { method: Method::Moa, leaf: LeafRule::Objects(cap), ..BuildParams::paper() };
        let (db, _) = common::mem_db(&scene, &params, CreateOptions { block_size: bs, lod_levels: m });
        check_predictions(&db);
    }
}

#[test]
fn multi_block_leaves_and_big_objects_are_predicted_too() {
    // 20 objects per leaf of 12-triangle boxes (~280 bytes each) overflow 1 KiB blocks.
    let scene = grid_scene(300);
    let params = BuildParams { leaf: LeafRule::Objects(20), ..BuildParams::paper() };
    let (db, _) = common::mem_db(&scene, &params, CreateOptions { block_size: 1024, lod_levels: 2 });
    check_predictions(&db);
}

/// With M = 1 the one level is the exact geometry (format-spec/lod.md:
/// level M is the exact objects), so the prediction covers its geometry
/// blocks and the pieces are objects.
#[test]
fn with_one_level_fetching_level_1_reads_the_exact_objects() {
    let params = BuildParams { leaf: LeafRule::Objects(4), ..BuildParams::paper() };
    let (db, _) = common::mem_db(&grid_scene(30), &params, CreateOptions { block_size: 1024, lod_levels: 1 });
    check_predictions(&db);
}

#[test]
fn counted_reads_are_the_device_reads() {
    let scene = grid_scene(400);
    let counting = Arc::new(CountingDevice::new(MemDevice::new()));
    let params = BuildParams { leaf: LeafRule::Objects(8), ..BuildParams::paper() };
    let db =
        common::load_on(counting.clone(), &scene, &params, CreateOptions { block_size: 2048, lod_levels: 2 });
    let r = db.begin_read().unwrap();
    for q in [
        [0.0, 0.0, 0.0, 250.0, 250.0, 250.0],
        [300.0, 0.0, 0.0, 320.0, 800.0, 10.0],
        [-9.0, -9.0, -9.0, -8.0, -8.0, -8.0],
    ] {
        let before = counting.counts().reads;
        let res = r.query_box(&Aabb::from_array(q)).unwrap();
        assert_eq!(counting.counts().reads - before, res.stats.reads.total());
    }
}
