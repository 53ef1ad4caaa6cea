//! Claim: `mktree bench-build --json` reports every method on every query
//! set, with leaves visited never below the leaves that hold an answer, and
//! with `--block-size` the block reads of each set; `--out` writes the JSON
//! and both charts, the PNG with its title and axis labels drawn. A bad scene name is one line on stderr and exit 1.

mod common;

use common::mktree;

fn bench(args: &[&str]) -> serde_json::Value {
    let out =
        mktree().args(["bench-build", "tanker1", "--queries", "20", "--json"]).args(args).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).unwrap()
}

#[test]
fn every_method_is_measured_on_every_query_set() {
    let v = bench(&["--page-objects", "30"]);
    let methods = v["scenes"][0]["methods"].as_array().unwrap();
    let names: Vec<&str> = methods.iter().map(|m| m["method"].as_str().unwrap()).collect();
    assert_eq!(names, ["moa", "laa", "median", "hilbert", "sah", "vsah", "refine"]);
    for m in methods {
        let sets = m["queries"].as_array().unwrap();
        assert_eq!(sets.len(), 7);
        for s in sets {
            assert!(s["leaves_visited"].as_f64().unwrap() >= s["answer_leaves"].as_f64().unwrap());
            assert!(s["ratio_to_best_reference"].as_f64().unwrap() > 0.0);
            assert!(s["reads"].is_null());
        }
    }
}

#[test]
fn block_reads_are_counted_and_the_chart_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let v = bench(&["--block-size", "4096", "--methods", "vsah,refine", "--out", out]);
    for m in v["scenes"][0]["methods"].as_array().unwrap() {
        assert!(m["file"]["node_blocks"].as_u64().unwrap() > 0);
        for s in m["queries"].as_array().unwrap() {
            assert!(s["reads"].as_f64().unwrap() >= 1.0, "the root block at least");
        }
    }
    for f in ["bench-build.json", "bench-build.svg", "bench-build.png"] {
        assert!(dir.path().join(f).metadata().unwrap().len() > 0, "{f}");
    }
    common::assert_chart_has_text(&dir.path().join("bench-build.png"));
}

#[test]
fn an_unknown_scene_is_one_line_and_exit_one() {
    let out = mktree().args(["bench-build", "no-such-scene"]).output().unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(err.trim().lines().count(), 1, "{err}");
}
