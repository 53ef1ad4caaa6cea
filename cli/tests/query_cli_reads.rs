//! Claim: `mktree query` runs the library's one traversal: for the same file
//! and box it returns the same objects and the same block reads as
//! `query_region` does, and as `bench-queries` averages.

use mktree::db::Database;
use mktree::geom::Aabb;
use mktree::query::{QueryOptions, Region, query_region};

mod common;

use common::{mktree, tanker1_in};

#[test]
fn the_cli_and_the_library_read_the_same_blocks() {
    let dir = tempfile::tempdir().unwrap();
    let (_, mkt) = tanker1_in(dir.path());
    for b in [[0.0, 0.0, 0.0, 1000.0, 1000.0, 1000.0], [500.0, 200.0, 100.0, 2500.0, 900.0, 700.0]] {
        let arg = b.map(|x| x.to_string()).join(",");
        let out = mktree().args(["query", mkt.to_str().unwrap(), "--box", &arg, "--json"]).output().unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        let db = Database::open(&mkt).unwrap();
        let a = query_region(
            &db.begin_read().unwrap(),
            &Region::Box(Aabb::from_array(b)),
            &QueryOptions::default(),
            None,
        )
        .unwrap();
        let objects: Vec<u64> = a.objects.iter().map(|o| u64::from(o.0)).collect();
        assert_eq!(
            v["objects"].as_array().unwrap().iter().map(|x| x.as_u64().unwrap()).collect::<Vec<_>>(),
            objects
        );
        assert_eq!(v["block_reads"]["total"].as_u64().unwrap(), a.stats.reads.total());
        assert_eq!(v["block_reads"]["node"].as_u64().unwrap(), a.stats.reads.node);
    }
}
