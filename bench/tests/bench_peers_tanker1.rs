//! Claim: the whole peer benchmark runs on a real scene (the `tanker1`
//! preset), mktree and SQLite agree on every exact answer and every box
//! filter (a disagreement is an error), and every count it reports is
//! positive.

use mktree::scene::generate::{GenOptions, Preset, generate_scene};
use mktree_bench::{PeerOptions, bench_scene};

#[test]
fn tanker1_answers_agree_and_every_count_is_positive() {
    let seed = 11;
    println!("seed {seed}");
    let scene = generate_scene(&GenOptions { preset: Preset::Tanker1, objects: None, seed: 0 }).unwrap();
    let dir = tempfile::tempdir().unwrap();
    for block_size in [4096, 16384] {
        let options = PeerOptions {
            queries: 20,
            seed,
            block_size,
            lod_levels: mktree::db::DEFAULT_LOD_LEVELS,
            query_sets: None,
            files_dir: Some(dir.path().to_path_buf()),
        };
        let rows = bench_scene("tanker1", &scene, &options, &|_| {}).unwrap();
        let sets: Vec<&str> = rows.iter().map(|r| r.set.as_str()).collect();
        assert_eq!(sets, ["box 1%", "box 5%", "box 20%", "collide +50"]);
        for r in &rows {
            let at = format!("{block_size}: {r:?}");
            assert_eq!((r.objects, r.queries, r.block_size), (222, 20, block_size), "{at}");
            for x in [
                r.mktree_exact_reads,
                r.sqlite_exact_reads,
                r.mktree_filter_reads,
                r.sqlite_filter_reads,
                r.rstar_nodes_tested,
                r.mktree_warm_ms,
                r.sqlite_warm_ms,
            ] {
                assert!(x > 0.0, "{at}");
            }
            assert!(
                r.exact_answers <= r.mktree_filter_answers && r.exact_answers <= r.sqlite_filter_answers,
                "{at}"
            );
            assert!(r.mktree_exact_reads >= r.mktree_filter_reads, "{at}");
            assert!(r.sqlite_exact_reads >= r.sqlite_filter_reads, "{at}");
            assert_eq!(r.sqlite_exact_bytes, r.sqlite_exact_reads * f64::from(block_size), "{at}");
            assert!(r.mktree_file_bytes > 0 && r.sqlite_file_bytes > 0, "{at}");
            assert!(r.mktree_file_bytes.is_multiple_of(u64::from(block_size)), "{at}");
            assert!(r.sqlite_file_bytes.is_multiple_of(u64::from(block_size)), "{at}");
        }
        // Collisions are an object's box grown: each meets at least its object.
        assert!(rows[3].exact_answers >= 1.0 && rows[3].mktree_filter_answers >= 1.0);
    }
    let mut kept: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    kept.sort();
    assert_eq!(kept, ["bench-peers-tanker1.mkt", "bench-peers-tanker1.sqlite"]);
}
