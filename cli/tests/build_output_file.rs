//! Claim: `mktree build -o FILE` writes a valid file wherever no work can
//! be lost, and touches nothing else. An empty file, or the start of a
//! header with nothing after it (what a crash while a file was created
//! leaves), is replaced; a file that is not an mktree file is refused with
//! a message saying so and left as it was; a refused scene leaves no new
//! file behind; and an mktree file gets its tree replaced, as before.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const PLATE: &str = "o plate\nv 0 0 0\nv 10 0 0\nv 0 10 0\nf 1 2 3\n";

fn mktree(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_mktree")).args(args).output().unwrap()
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// A one-triangle scene beside the output.
fn scene(dir: &Path) -> PathBuf {
    let path = dir.join("plate.obj");
    std::fs::write(&path, PLATE).unwrap();
    path
}

fn build(scene: &Path, out: &Path) -> Output {
    mktree(&["build", scene.to_str().unwrap(), "-o", out.to_str().unwrap()])
}

fn assert_checks(out: &Path) {
    let check = mktree(&["check", out.to_str().unwrap()]);
    assert!(check.status.success(), "check: {}", stderr(&check));
    assert!(String::from_utf8_lossy(&check.stdout).contains("1 objects"));
}

#[test]
fn an_empty_output_file_is_replaced_by_a_valid_one() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("plate.mkt");
    std::fs::write(&out, b"").unwrap();
    let built = build(&scene(dir.path()), &out);
    assert!(built.status.success(), "{}", stderr(&built));
    assert_checks(&out);
}

#[test]
fn a_torn_header_is_replaced_by_a_valid_file() {
    let dir = tempfile::tempdir().unwrap();
    let whole = dir.path().join("whole.mkt");
    let scene = scene(dir.path());
    assert!(build(&scene, &whole).status.success());
    let header = std::fs::read(&whole).unwrap();
    // What a crash part way through writing a new file's header can leave.
    for torn in [&header[..3], &header[..100], &[0u8; 200][..]] {
        let out = dir.path().join("torn.mkt");
        std::fs::write(&out, torn).unwrap();
        let built = build(&scene, &out);
        assert!(built.status.success(), "{} bytes: {}", torn.len(), stderr(&built));
        assert_checks(&out);
    }
}

#[test]
fn a_file_that_is_not_an_mktree_file_is_refused_and_left_untouched() {
    let dir = tempfile::tempdir().unwrap();
    let scene = scene(dir.path());
    let whole = dir.path().join("whole.mkt");
    assert!(build(&scene, &whole).status.success());
    let mut damaged = std::fs::read(&whole).unwrap();
    damaged[200] ^= 1;
    let contents: [(&str, Vec<u8>); 4] = [
        ("notes.txt", b"my notes, not a tree\n".to_vec()),
        ("short.bin", vec![7u8; 10]),
        ("zeros.bin", vec![0u8; 64 * 1024]),
        ("damaged.mkt", damaged),
    ];
    for (name, bytes) in contents {
        let out = dir.path().join(name);
        std::fs::write(&out, &bytes).unwrap();
        let built = build(&scene, &out);
        assert!(!built.status.success(), "{name} was overwritten");
        let message = stderr(&built);
        assert_eq!(message.lines().count(), 1, "{name}: {message}");
        assert!(message.contains(out.to_str().unwrap()), "{name}: {message}");
        if name != "damaged.mkt" {
            assert!(message.contains("not an mktree file"), "{name}: {message}");
        }
        assert_eq!(std::fs::read(&out).unwrap(), bytes, "{name} was changed");
    }
}

#[test]
fn an_existing_tree_is_replaced_and_a_refused_scene_leaves_no_new_file() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("scene.mkt");
    let scene = scene(dir.path());
    assert!(build(&scene, &out).status.success());
    assert!(build(&scene, &out).status.success());
    assert_checks(&out);

    let wide = dir.path().join("wide.obj");
    std::fs::write(&wide, format!("{PLATE}o far\nv 1e39 0 0\nv 1e39 1 0\nv 1e39 0 1\nf 4 5 6\n")).unwrap();
    let refused = dir.path().join("wide.mkt");
    let built = build(&wide, &refused);
    assert!(!built.status.success());
    assert!(
        stderr(&built)
            .contains("object 1: x = 1e39 mm is beyond the range of ±9007199254740992 mm a file holds"),
        "{}",
        stderr(&built)
    );
    assert!(!refused.exists(), "a refused scene left {}", refused.display());
}
