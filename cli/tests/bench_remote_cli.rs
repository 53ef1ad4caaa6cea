//! Claim (issue 36 item 7): `mktree bench-remote` reads a file at a URL
//! (here over `mktree serve`) through a proxy that adds round trips, checks
//! every remote answer against the local file's, reports cold rows (the
//! open apart) and warm rows per set and added round trip, and each added
//! round trip costs the query at least that much wall time. Bad inputs,
//! and a URL that holds another file than the local one, end in one line
//! and exit 1.

mod common;

use common::{assert_chart_has_text, mktree, serve, tanker1_in};
use serde_json::Value;

const SETS: [&str; 4] = ["box 1%", "box 5%", "box 20%", "collide +50"];

#[test]
fn bench_remote_checks_answers_and_adds_the_round_trips_it_is_asked_for() {
    let dir = tempfile::tempdir().unwrap();
    let (_, built) = tanker1_in(dir.path());
    // `serve` serves a tileset's folder; the file is served beside it.
    let tiles = dir.path().join("tiles");
    let out = mktree().args(["export-3dtiles"]).arg(&built).arg(&tiles).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    std::fs::copy(&built, tiles.join("t1.mkt")).unwrap();
    let (_server, port) = serve(dir.path());
    let url = format!("http://127.0.0.1:{port}/tiles/t1.mkt");
    let charts = dir.path().join("out");

    let out = mktree()
        .arg("bench-remote")
        .arg(&built)
        .arg(&url)
        // An open of two blocks: tanker1 is small enough for the default's
        // 256 KiB to hold every block a query reads.
        .args(["--queries", "3", "--latency", "0,20", "--open-bytes", "8K", "--json", "--out"])
        .arg(&charts)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let bench: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(bench["latencies_ms"], serde_json::json!([0.0, 20.0]));
    assert_eq!(bench["open_bytes"], 8192);
    assert_eq!(bench["block_size"], 4096);
    let local = bench["local"].as_array().unwrap();
    assert_eq!(local.iter().map(|l| l["set"].as_str().unwrap()).collect::<Vec<_>>(), SETS);
    let rows = bench["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 2 * SETS.len() * 2, "{bench}");

    for row in rows {
        let set = local.iter().find(|l| l["set"] == row["set"]).unwrap();
        // Every answer was checked equal to the local file's, reads included.
        assert_eq!(row["block_reads"], set["block_reads"], "{row}");
        assert_eq!(row["queries"], 3);
        let q = &row["query"];
        for key in ["requests", "round_trips", "bytes", "wall_ms", "wall_ms_p95"] {
            assert!(q[key].is_f64(), "{key}: {row}");
        }
        match row["cache"].as_str().unwrap() {
            "cold" => {
                assert!(row["open"]["requests"].as_f64().unwrap() >= 1.0, "{row}");
                if set["block_reads"].as_f64().unwrap() > 0.0 {
                    assert!(q["requests"].as_f64().unwrap() > 0.0, "{row}");
                    assert!(row["bytes_ratio"].as_f64().unwrap() > 0.0, "{row}");
                }
            }
            // tanker1 fits the cache: a warm pass fetches nothing.
            "warm" => {
                assert!(row["open"].is_null(), "{row}");
                assert_eq!(q["requests"].as_f64(), Some(0.0), "{row}");
            }
            other => panic!("cache {other}"),
        }
        // Each round trip the proxy adds costs at least that much: a lower
        // bound only, as the machine may be slower than that, never faster.
        if row["latency_ms"] == 20.0 && row["cache"] == "cold" {
            let per_trip = |t: &Value| t["wall_ms"].as_f64().unwrap() / t["round_trips"].as_f64().unwrap();
            assert!(per_trip(q) >= 19.0, "{row}");
            assert!(per_trip(&row["open"]) >= 19.0, "{row}");
        }
    }
    let written: Value =
        serde_json::from_str(&std::fs::read_to_string(charts.join("bench-remote.json")).unwrap()).unwrap();
    assert_eq!(written["rows"].as_array().map(Vec::len), Some(rows.len()));
    assert_chart_has_text(&charts.join("bench-remote.png"));

    // Bad inputs: one line, exit 1, naming what is wrong.
    let fails = |args: &[&str], says: &str| {
        let out = mktree().arg("bench-remote").args(args).output().unwrap();
        assert_eq!(out.status.code(), Some(1), "{args:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(err.trim_end().lines().count(), 1, "{err}");
        assert!(err.contains(says), "{args:?}: {err}");
    };
    let mkt = built.to_str().unwrap();
    let obj = dir.path().join("t1.obj");
    fails(&[mkt, "ftp://127.0.0.1/t1.mkt"], "not ftp://");
    fails(&[mkt, "no url"], "not a URL");
    fails(&[obj.to_str().unwrap(), &url], "opening");
    fails(&[mkt, &format!("http://127.0.0.1:{port}/tiles/none.mkt")], "none.mkt");
    fails(&[mkt, &url, "--latency=-5"], "between 0 and");
    fails(&[mkt, &url, "--gap-share=-1"], "gap share");
    fails(&[mkt, &url, "--gap-share=NaN"], "gap share");
    // Another file at the URL: its answers would differ, so it is refused at once.
    let other = dir.path().join("other.mkt");
    let out = mktree()
        .arg("build")
        .arg(&obj)
        .arg("-o")
        .arg(&other)
        .args(["--block-size", "8192"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    fails(&[other.to_str().unwrap(), &url], "is not the file");
}
