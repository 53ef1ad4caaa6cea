//! Claim: `mktree bench-peers --json` reports a row per query set with the
//! reads of both peers and their ratios; `--out` writes the JSON, both
//! charts (the PNG with its title and axis labels drawn) and keeps the built files; `--query-file` replaces the generated
//! sets by its labelled ones. A bad block size or query file is one line on
//! stderr and exit 1.

mod common;

use common::mktree;

#[test]
fn every_set_is_measured_and_the_chart_and_files_are_written() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let run = mktree()
        .args(["bench-peers", "tanker1", "--queries", "5", "--block-size", "4096", "--json", "--out", out])
        .output()
        .unwrap();
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let v: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    let rows = v["rows"].as_array().unwrap();
    let sets: Vec<&str> = rows.iter().map(|r| r["set"].as_str().unwrap()).collect();
    assert_eq!(sets, ["box 1%", "box 5%", "box 20%", "collide +50"]);
    for r in rows {
        assert_eq!(r["block_size"], 4096);
        for key in ["mktree_exact_reads", "sqlite_exact_reads", "exact_reads_ratio", "filter_reads_ratio"] {
            assert!(r[key].as_f64().unwrap() > 0.0, "{key}: {r}");
        }
    }
    for f in [
        "bench-peers.json",
        "bench-peers.svg",
        "bench-peers.png",
        "bench-peers-tanker1.mkt",
        "bench-peers-tanker1.sqlite",
    ] {
        assert!(dir.path().join(f).metadata().unwrap().len() > 0, "{f}");
    }
    common::assert_chart_has_text(&dir.path().join("bench-peers.png"));
}

#[test]
fn a_query_file_gives_the_sets_and_bad_input_is_one_line_and_exit_1() {
    let dir = tempfile::tempdir().unwrap();
    let queries = dir.path().join("q.txt");
    std::fs::write(&queries, "0,0,0,1000,1000,1000,big\n100,100,100,200,200,200\n").unwrap();
    let run = mktree().args(["bench-peers", "tanker1", "--query-file"]).arg(&queries).output().unwrap();
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let table = String::from_utf8(run.stdout).unwrap();
    assert!(table.contains("| tanker1 | big "), "{table}");
    assert!(table.contains("| tanker1 | file "), "{table}");

    std::fs::write(&queries, "0,0,0,1,1\n").unwrap();
    for args in [vec!["--block-size", "3000"], vec!["--query-file", queries.to_str().unwrap()]] {
        let run = mktree().args(["bench-peers", "tanker1"]).args(&args).output().unwrap();
        assert_eq!(run.status.code(), Some(1), "{args:?}");
        let err = String::from_utf8(run.stderr).unwrap();
        assert_eq!(err.lines().count(), 1, "{err}");
        assert!(err.starts_with("mktree: error: "), "{err}");
    }
}
