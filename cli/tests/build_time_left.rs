//! Claim: `mktree build --json` reports, per stage, how the time left its
//! progress bar told compared with the time the stage took: at each of
//! `TIME_LEFT_CHECKS` of every stage that reports progress, nothing for
//! the read and the commit, which report none.

mod common;

use common::mktree;

#[test]
fn build_json_checks_the_time_left_told_in_every_stage() {
    let dir = tempfile::tempdir().unwrap();
    let (obj, _) = common::tanker1_in(dir.path());
    let out_path = dir.path().join("again.mkt");
    let out = mktree()
        .args(["build", obj.to_str().unwrap(), "-o", out_path.to_str().unwrap(), "--json"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let stages = v["stages"].as_array().unwrap();
    let names: Vec<&str> = stages.iter().map(|s| s["stage"].as_str().unwrap()).collect();
    assert_eq!(
        names,
        ["read", "tree", "layout", "levels", "choose", "geometry", "groups", "nodes", "keys", "commit"]
    );
    for s in stages {
        let (name, seconds) = (s["stage"].as_str().unwrap(), s["seconds"].as_f64().unwrap());
        let checks = s["time_left"].as_array().unwrap();
        if name == "read" || name == "commit" {
            assert!(checks.is_empty(), "{name}: {checks:?}");
            continue;
        }
        let at: Vec<f64> = checks.iter().map(|c| c["at"].as_f64().unwrap()).collect();
        assert_eq!(at, mktree::bulk::TIME_LEFT_CHECKS, "{name}");
        for c in checks {
            // What was left after the report checked: within the stage.
            let actual = c["actual_seconds"].as_f64().unwrap();
            assert!((0.0..=seconds).contains(&actual), "{name}: {c} of {seconds} s");
            let told = &c["told_seconds"];
            assert!(told.is_null() || told.as_f64().is_some_and(|t| t >= 0.0), "{name}: {c}");
            // The error is told over taken, less one, wherever both are.
            match (told.as_f64(), c["error"].as_f64()) {
                (Some(t), Some(e)) => assert!((t / actual - 1.0 - e).abs() < 1e-9, "{name}: {c}"),
                (t, None) => assert!(t.is_none() || actual == 0.0, "{name}: {c}"),
                (None, Some(_)) => panic!("{name}: an error with nothing told: {c}"),
            }
        }
    }
}
