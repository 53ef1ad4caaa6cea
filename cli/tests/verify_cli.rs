//! Claim: `mktree verify FILE SCENE` passes a file against the scene it was
//! built from, and fails (non-zero, one line) against a scene of as many
//! objects with other geometry, or of another size.

mod common;

use common::mktree;

#[test]
fn verify_passes_its_own_scene_and_fails_another() {
    let dir = tempfile::tempdir().unwrap();
    let (obj, mkt) = common::tanker1_in(dir.path());
    let out =
        mktree().args(["verify", mkt.to_str().unwrap(), obj.to_str().unwrap(), "--json"]).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["differing_queries"], serde_json::json!([]));
    assert!(v["objects_found"].as_u64().unwrap() > 2 * v["box_queries"].as_u64().unwrap());

    // The same preset with another seed: as many objects, placed otherwise.
    let other = dir.path().join("t1-seed7.obj");
    let made =
        mktree().args(["gen", "tanker1", "--seed", "7", "-o", other.to_str().unwrap()]).output().unwrap();
    assert!(made.status.success());
    let out = mktree().args(["verify", mkt.to_str().unwrap(), other.to_str().unwrap()]).output().unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("differ from the exact scan") && err.lines().count() == 1, "{err}");

    // Fewer objects.
    let small = dir.path().join("one.obj");
    std::fs::write(&small, "o plate\nv 0 0 0\nv 10 0 0\nv 0 10 0\nf 1 2 3\n").unwrap();
    let out = mktree().args(["verify", mkt.to_str().unwrap(), small.to_str().unwrap()]).output().unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("not the scene of this file"));
}
