//! Claim: with a buffer pool, a block found in the pool is a hit, reported
//! apart from reads, and the device sees no read for it.

mod common;

use std::sync::Arc;

use mktree::bulk::{BuildParams, LeafRule};
use mktree::db::CreateOptions;
use mktree::geom::Aabb;
use mktree::query::{QueryOptions, Region, query_region};
use mktree::store::BlockCache;
use mktree::store::device::{CountingDevice, MemDevice};

#[test]
fn a_repeated_query_is_served_from_the_pool() {
    let dev = Arc::new(CountingDevice::new(MemDevice::new()));
    let params = BuildParams { leaf: LeafRule::Objects(5), ..BuildParams::paper() };
    let db = common::load_on(
        dev.clone(),
        &common::grid_scene(200),
        &params,
        CreateOptions { block_size: 1024, lod_levels: 1 },
    );
    let r = db.begin_read().unwrap();
    let q = Aabb::from_array([0.0, 0.0, 0.0, 300.0, 300.0, 300.0]);
    let pool = BlockCache::new(1000);
    let first = query_region(&r, &Region::Box(q), &QueryOptions::default(), Some(&pool)).unwrap();
    assert!(first.stats.reads.total() > 1);
    assert_eq!(first.stats.reads.cache_hits, 0);
    let before = dev.counts().reads;
    let second = query_region(&r, &Region::Box(q), &QueryOptions::default(), Some(&pool)).unwrap();
    assert_eq!(second.objects, first.objects);
    assert_eq!(second.stats.reads.total(), 0);
    assert_eq!(second.stats.reads.cache_hits, first.stats.reads.total());
    assert_eq!(dev.counts().reads, before, "hits never reach the device");
    // A pool of 2 blocks cannot hold the working set: some reads again, never more than cold.
    let small = BlockCache::new(2);
    let cold = query_region(&r, &Region::Box(q), &QueryOptions::default(), Some(&small)).unwrap();
    let warm = query_region(&r, &Region::Box(q), &QueryOptions::default(), Some(&small)).unwrap();
    assert_eq!(cold.stats.reads.total(), first.stats.reads.total());
    assert!(warm.stats.reads.total() + warm.stats.reads.cache_hits == cold.stats.reads.total());
}

#[test]
fn reader_threads_share_one_pool() {
    let dev = Arc::new(CountingDevice::new(MemDevice::new()));
    let params = BuildParams { leaf: LeafRule::Objects(5), ..BuildParams::paper() };
    let db = common::load_on(
        dev.clone(),
        &common::grid_scene(400),
        &params,
        CreateOptions { block_size: 1024, lod_levels: 1 },
    );
    let queries: Vec<Aabb> = (0..8)
        .map(|i| {
            let lo = 60.0 * i as f64;
            Aabb::from_array([lo, 0.0, 0.0, lo + 250.0, 400.0, 400.0])
        })
        .collect();
    let uncached: Vec<_> = {
        let r = db.begin_read().unwrap();
        queries
            .iter()
            .map(|q| query_region(&r, &Region::Box(*q), &QueryOptions::default(), None).unwrap())
            .collect()
    };
    assert!(uncached.iter().all(|a| !a.objects.is_empty() && a.stats.reads.total() > 1));
    let pool = BlockCache::new(10_000);
    std::thread::scope(|s| {
        for (q, expected) in queries.iter().zip(&uncached) {
            let (db, pool) = (&db, &pool);
            s.spawn(move || {
                let r = db.begin_read().unwrap();
                let got = query_region(&r, &Region::Box(*q), &QueryOptions::default(), Some(pool)).unwrap();
                assert_eq!(got.objects, expected.objects);
                // Each block is read or hit, never both: the sum is what an uncached query reads.
                assert_eq!(
                    got.stats.reads.total() + got.stats.reads.cache_hits,
                    expected.stats.reads.total()
                );
            });
        }
    });
    // Every block any thread read is now shared: a second pass reaches no device.
    let before = dev.counts().reads;
    let r = db.begin_read().unwrap();
    for (q, expected) in queries.iter().zip(&uncached) {
        let warm = query_region(&r, &Region::Box(*q), &QueryOptions::default(), Some(&pool)).unwrap();
        assert_eq!(warm.objects, expected.objects);
        assert_eq!(warm.stats.reads.total(), 0);
    }
    assert_eq!(dev.counts().reads, before);
}
