//! Claim (issue 13): `mktree get` finds an object by its key through the key
//! index, with its block reads; `build --key-names` keys objects by their
//! names and refuses repeated names with one line; a missing key is one
//! line and exit 1.

use std::process::{Command, Output};

fn mktree(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_mktree")).args(args).output().unwrap()
}

fn json(out: &Output) -> serde_json::Value {
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).unwrap()
}

fn one_line_error(out: &Output, says: &str) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(stderr.contains(says), "{stderr}");
}

#[test]
fn objects_are_found_by_id_key_or_name_key() {
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("s.obj");
    std::fs::write(
        &obj,
        "o pump\nv 0 0 0\nv 10 0 0\nv 0 10 0\nf 1 2 3\no valve\nv 50 0 0\nv 60 0 0\nv 50 10 5\nf 4 5 6\n",
    )
    .unwrap();
    let (by_id, by_name) = (dir.path().join("id.mkt"), dir.path().join("name.mkt"));
    let (obj, by_id_s, by_name_s) =
        (obj.to_str().unwrap(), by_id.to_str().unwrap(), by_name.to_str().unwrap());
    json(&mktree(&["build", obj, "-o", by_id_s, "--json"]));
    json(&mktree(&["build", obj, "-o", by_name_s, "--key-names", "--json"]));

    let got = json(&mktree(&["get", by_id_s, "--key", "1", "--mesh", "--json"]));
    assert_eq!(got["id"], 1);
    assert_eq!(got["key"], 1);
    assert_eq!(got["box"], serde_json::json!([50.0, 0.0, 0.0, 60.0, 10.0, 5.0]));
    assert_eq!(got["triangles"], 1);
    let reads = &got["block_reads"];
    assert_eq!(
        (reads["keys"].as_u64(), reads["node"].as_u64(), reads["geometry"].as_u64()),
        (Some(1), Some(1), Some(1))
    );

    let got = json(&mktree(&["get", by_name_s, "--key", "valve", "--json"]));
    assert_eq!((got["id"].as_u64(), got["key"].as_str()), (Some(1), Some("valve")));
    one_line_error(&mktree(&["get", by_name_s, "--key", "1"]), "no object has the key 1");
    one_line_error(&mktree(&["get", by_id_s, "--key", "2"]), "no object has the key 2");
    // A file that is not there is named once, with the reason.
    let missing = dir.path().join("missing.mkt");
    let out = mktree(&["get", missing.to_str().unwrap(), "--key", "1"]);
    one_line_error(&out, "No such file");
    assert_eq!(String::from_utf8_lossy(&out.stderr).matches("missing.mkt").count(), 1);

    // Two objects named alike cannot both be keyed by their name.
    let twice = dir.path().join("twice.obj");
    std::fs::write(
        &twice,
        "o pump\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\no pump\nv 5 0 0\nv 6 0 0\nv 5 1 0\nf 4 5 6\n",
    )
    .unwrap();
    let out = dir.path().join("twice.mkt");
    one_line_error(
        &mktree(&["build", twice.to_str().unwrap(), "-o", out.to_str().unwrap(), "--key-names"]),
        "share the key pump",
    );
    assert!(!out.exists(), "a refused scene leaves no file");
}
