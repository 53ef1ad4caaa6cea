//! Claim: with a buffer pool, a block found in the pool is a hit, reported
//! apart from reads, and the device sees no read for it.

mod common;

use std::sync::Arc;

use mktree::build::{BuildParams, LeafRule};
use mktree::db::CreateOptions;
use mktree::geom::Aabb;
use mktree::query::{QueryOptions, Region, query_region};
use mktree::store::BlockCache;
use mktree::store::device::{CountingDevice, MemDevice};

#[test]
fn a_repeated_query_is_served_from_the_pool() {
    let dev = Arc::new(CountingDevice::new(MemDevice::new()));
    let params = BuildParams { leaf: LeafRule::Objects(5), ..BuildParams::default() };
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
