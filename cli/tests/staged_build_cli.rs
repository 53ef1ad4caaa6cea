//! Claim: `mktree build --memory SIZE` stages an OBJ file larger than half
//! of SIZE on disk, beside the output, and writes the same file as a build
//! that reads it whole: the same blocks apart from the recorded build time,
//! hence the same `stats` and answers. The spill file is gone afterwards,
//! and a size that is not one is refused.

mod common;

use common::mktree;

fn json(args: &[&str]) -> serde_json::Value {
    let out = mktree().args(args).output().unwrap();
    assert!(out.status.success(), "{args:?}: {}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).unwrap()
}

#[test]
fn a_staged_build_writes_the_same_tree_as_a_whole_one() {
    let dir = tempfile::tempdir().unwrap();
    let (obj, whole) = common::tanker1_in(dir.path());
    let staged_dir = dir.path().join("staged");
    std::fs::create_dir(&staged_dir).unwrap();
    let staged = staged_dir.join("t1.mkt");
    let (obj, whole, staged) = (obj.to_str().unwrap(), whole.to_str().unwrap(), staged.to_str().unwrap());
    json(&["build", obj, "-o", staged, "--block-size", "4096", "--stage", "--json"]);
    assert_eq!(std::fs::read_dir(&staged_dir).unwrap().count(), 1, "the spill file is removed");
    assert_eq!(std::fs::metadata(whole).unwrap().len(), std::fs::metadata(staged).unwrap().len());
    let mut a = json(&["stats", whole, "--json"]);
    let mut b = json(&["stats", staged, "--json"]);
    for v in [&mut a, &mut b] {
        v.as_object_mut().unwrap().retain(|k, _| k != "build_seconds" && k != "file");
    }
    assert_eq!(a, b);
    let q = ["--box", "0,-20000,0,60000,20000,20000", "--json"];
    let answer = |file: &str| {
        let mut v = json(&[&["query", file][..], &q[..]].concat());
        v.as_object_mut().unwrap().retain(|k, _| k == "objects" || k == "reads");
        v
    };
    assert_eq!(answer(whole), answer(staged));
}

#[test]
fn a_memory_size_that_is_not_one_is_refused() {
    for bad in ["lots", "0", "4Q", "99999999999T", "1", "1K", "63M"] {
        let out = mktree().args(["build", "x.obj", "-o", "x.mkt", "--memory", bad]).output().unwrap();
        assert!(!out.status.success(), "{bad}");
        assert!(String::from_utf8_lossy(&out.stderr).contains("--memory"), "{bad}");
    }
}
