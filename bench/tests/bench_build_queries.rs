//! Claim: the benchmark's query sets are answered right. For every kind
//! of query (boxes, cubes, collisions), the in-memory count of
//! `count_in_tree` equals a scan of every leaf and object, and a query
//! through the file returns exactly the brute-force answer, on trees of
//! the new methods (`vsah`, `refine`) and a paper method.

use std::sync::Arc;

use mktree::bulk::{BuildParams, Hierarchy, LeafRule, Method};
use mktree::db::{CreateOptions, Database};
use mktree::geom::Aabb;
use mktree::query::{Region, brute_force_region};
use mktree::scene::Scene;
use mktree::scene::generate::{GenOptions, Preset, generate_scene};
use mktree::store::device::MemDevice;
use mktree_bench::{QueryKind, TreeQueryCount, count_in_tree};

/// `scene` bulk-loaded by `params` into a fresh in-memory database.
fn mem_db(scene: &Scene, params: &BuildParams, options: CreateOptions) -> Database {
    let db = Database::create_on(Arc::new(MemDevice::new()), options).expect("create");
    let mut w = db.begin_write().expect("begin_write");
    w.bulk_load(scene, params, &|_| {}).expect("bulk_load");
    w.commit().expect("commit");
    db
}

/// Every leaf and object tested, no pruning: a leaf whose box meets the
/// query is reached (its ancestors' boxes contain its box).
fn scan(tree: &Hierarchy, boxes: &[Aabb], query: &Aabb) -> TreeQueryCount {
    let mut c = TreeQueryCount::default();
    for (id, objects) in tree.leaves() {
        if tree.node(id).is_some_and(|n| n.aabb.intersects(query)) {
            c.leaves_visited += 1;
            let hits = objects.iter().filter(|o| boxes[o.index()].intersects(query)).count() as u64;
            c.answers += hits;
            c.answer_leaves += u64::from(hits > 0);
        }
    }
    c
}

#[test]
fn bench_queries_equal_brute_force_in_memory_and_through_the_file() {
    let seed = 7;
    println!("seed {seed}");
    let scene = generate_scene(&GenOptions { preset: Preset::Tanker1, objects: None, seed: 0 }).unwrap();
    let boxes = scene.object_boxes();
    for method in [Method::Moa, Method::Vsah, Method::Refine] {
        let params = BuildParams { method, leaf: LeafRule::Objects(12), ..BuildParams::paper() };
        let db = mem_db(&scene, &params, CreateOptions { block_size: 4096, lod_levels: 2 });
        let txn = db.begin_read().unwrap();
        let tree = mktree::db::read_hierarchy(&txn).unwrap();
        for kind in QueryKind::STANDARD {
            for q in kind.generate(&boxes, 25, seed) {
                assert_eq!(
                    count_in_tree(&tree, &boxes, &q),
                    scan(&tree, &boxes, &q),
                    "{method} {kind:?} {q:?}"
                );
                let got = txn.query_box(&q).unwrap();
                assert_eq!(
                    got.objects,
                    brute_force_region(&scene, &Region::Box(q)),
                    "{method} {kind:?} {q:?}"
                );
            }
        }
    }
}
