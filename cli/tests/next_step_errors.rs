//! Claim: passing a scene where an .mkt file belongs fails with one line
//! that names the `build` command making the file, and a non-zero exit; any
//! other file that is not an MKtree file is named as such, without a panic.

mod common;

use common::mktree;

/// Runs `mktree args..`, which must fail: its stderr, one line.
fn fails(args: &[&str]) -> String {
    let out = mktree().args(args).output().unwrap();
    assert!(!out.status.success(), "{args:?} succeeded");
    assert_eq!(out.status.code(), Some(1), "{args:?}: {out:?}");
    let err = String::from_utf8(out.stderr).unwrap();
    assert_eq!(err.trim_end().lines().count(), 1, "{args:?}: not one line: {err}");
    assert!(!err.contains("panicked"), "{err}");
    err
}

#[test]
fn a_scene_given_to_a_reader_suggests_building_it() {
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("t1.obj");
    let out = mktree().args(["gen", "tanker1", "-o", obj.to_str().unwrap()]).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let o = obj.to_str().unwrap();
    let mkt = dir.path().join("t1.mkt");
    let want = format!(
        "{o} is a scene, not an MKtree file: build it first with `mktree build {o} -o {}`",
        mkt.display()
    );
    for args in
        [vec!["query", o, "--box", "0,0,0,1,1,1"], vec!["lods", o], vec!["check", o], vec!["compact", o]]
    {
        let err = fails(&args);
        assert!(err.contains(&want), "{args:?}: {err}");
    }
    // The suggestion works: the file it names then answers.
    let out =
        mktree().args(["build", o, "-o", mkt.to_str().unwrap(), "--block-size", "4096"]).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let out = mktree().args(["query", mkt.to_str().unwrap(), "--box", "0,0,0,1,1,1"]).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
}

#[test]
fn a_scene_shorter_than_a_header_also_suggests_building_it() {
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("tiny.obj");
    std::fs::write(&obj, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    let err = fails(&["check", obj.to_str().unwrap()]);
    assert!(
        err.contains("tiny.obj is a scene, not an MKtree file: build it first with `mktree build"),
        "{err}"
    );
}

#[test]
fn another_file_is_named_as_not_an_mktree_file() {
    let dir = tempfile::tempdir().unwrap();
    let notes = dir.path().join("notes.txt");
    std::fs::write(&notes, "not a tree, and longer than a header. ".repeat(64)).unwrap();
    let err = fails(&["query", notes.to_str().unwrap(), "--box", "0,0,0,1,1,1"]);
    assert!(err.contains("notes.txt is not an MKtree file"), "{err}");
    assert!(err.contains("mktree build SCENE -o FILE.mkt"), "{err}");
}
