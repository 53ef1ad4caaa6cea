//! Claim (issue 12): the CLI reads a read-only file, never writes to a file
//! it only reads, and reports a damaged copy of a commit slot (a warning on
//! stderr; `check` prints it too) while answering from the newest tree.

use std::path::Path;
use std::process::{Command, Output};

use mktree::store::format::header::slot_offset;

fn mktree(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_mktree")).args(args).output().unwrap()
}

fn ok(out: Output) -> Output {
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    out
}

fn query(mkt: &Path) -> Output {
    ok(mktree(&["query", mkt.to_str().unwrap(), "--box", "0,0,0,3000,3000,3000", "--json"]))
}

fn objects(out: &Output) -> serde_json::Value {
    serde_json::from_slice::<serde_json::Value>(&out.stdout).unwrap()["objects"].clone()
}

#[test]
fn a_read_only_file_is_queried_and_a_damaged_slot_copy_is_reported() {
    let dir = tempfile::tempdir().unwrap();
    let (obj, mkt) = (dir.path().join("t1.obj"), dir.path().join("t1.mkt"));
    ok(mktree(&["gen", "tanker1", "-o", obj.to_str().unwrap()]));
    for _ in 0..2 {
        ok(mktree(&["build", obj.to_str().unwrap(), "-o", mkt.to_str().unwrap(), "--block-size", "4096"]));
    }
    let clean = query(&mkt);
    // One bit of one copy of each slot in turn; the file is read-only.
    for slot in 0..2 {
        let mut bytes = std::fs::read(&mkt).unwrap();
        let damaged = dir.path().join(format!("damaged{slot}.mkt"));
        bytes[slot_offset(slot, 1) + 9] ^= 0x04;
        std::fs::write(&damaged, &bytes).unwrap();
        let mut perms = std::fs::metadata(&damaged).unwrap().permissions();
        perms.set_readonly(true);
        std::fs::set_permissions(&damaged, perms).unwrap();
        let out = query(&damaged);
        assert_eq!(objects(&out), objects(&clean), "the newest tree's answer");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(stderr.contains(&format!("copy 1 of commit slot {slot} fails its checksum")), "{stderr}");
        let check = ok(mktree(&["check", damaged.to_str().unwrap()]));
        assert!(String::from_utf8_lossy(&check.stdout).contains("warning: block 0: copy 1"));
        assert_eq!(std::fs::read(&damaged).unwrap(), bytes, "reading never writes");
    }
}
