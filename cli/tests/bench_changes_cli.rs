//! Claim: `mktree bench-changes` runs the same changes on mktree and on
//! SQLite (WAL and rollback journal) in one run: a row per engine and
//! phase with the commits asked for, mktree's single-object commits in
//! place with one sync each, the reads of the changed file beside a fresh
//! load, and a two-process stream per engine (a writer process committing
//! moves while a reader process queries) in which no query fails.

use serde_json::Value;

mod common;

use common::mktree;

#[test]
fn both_engines_take_the_same_changes_and_the_stream_fails_no_read() {
    let dir = tempfile::tempdir().unwrap();
    let out = mktree()
        .args([
            "bench-changes",
            "tanker1",
            "--singles",
            "20",
            "--batch",
            "30",
            "--queries",
            "5",
            "--json",
            "--dir",
        ])
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    let report = &v["scenes"][0]["report"];
    assert_eq!(report["objects"], 222);
    let rows = report["rows"].as_array().unwrap();
    for engine in ["mktree", "sqlite-wal", "sqlite-rollback"] {
        for phase in ["insert", "move", "remove"] {
            let row = rows
                .iter()
                .find(|r| r["engine"] == engine && r["phase"] == phase)
                .unwrap_or_else(|| panic!("no {engine} {phase} row: {rows:#?}"));
            assert_eq!(row["commits"], 20, "{row}");
            assert!(row["median_ms"].as_f64().unwrap() > 0.0, "{row}");
            if engine == "mktree" {
                assert_eq!(row["in_place"], 1.0, "{row}");
                assert_eq!(row["syncs_per_commit"], 1.0, "{row}");
            }
        }
        assert!(rows.iter().any(|r| r["engine"] == engine && r["phase"] == "mixed 30"), "{engine}");
    }
    assert_eq!(report["reads"].as_array().unwrap().len(), 4, "four query sets");
    let streams = report["streams"].as_array().unwrap();
    assert_eq!(streams.len(), 3, "{streams:#?}");
    for s in streams {
        assert_eq!(s["commits"], 20, "{s}");
        assert!(s["reader_queries"].as_u64().unwrap() > 0, "the reader ran: {s}");
        assert_eq!(s["reader_failed"], 0, "{s}");
    }
    assert!(std::fs::read_dir(dir.path()).unwrap().next().is_none(), "the bench removes its files");
}
