//! Claim (issue 13): `mktree remove` deletes objects by key in one commit,
//! all or none; `stats` reports free blocks; `compact` gives a file that
//! grew across rewrites back its size; `stats` reports the layout's drift,
//! which `optimize` takes back to none.

mod common;

use std::process::Output;

use common::{mktree, tanker1_in};

fn run(args: &[&str]) -> Output {
    mktree().args(args).output().unwrap()
}

fn json(out: &Output) -> serde_json::Value {
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).unwrap()
}

fn file_stats(mkt: &str) -> serde_json::Value {
    json(&run(&["stats", mkt, "--json"]))["file"].clone()
}

#[test]
fn remove_is_all_or_none_and_compact_shrinks_a_rewritten_file() {
    let dir = tempfile::tempdir().unwrap();
    let (obj, mkt) = tanker1_in(dir.path());
    let (obj, mkt) = (obj.to_str().unwrap(), mkt.to_str().unwrap());
    let before = file_stats(mkt);
    let objects = before["objects"].as_u64().unwrap();

    // A missing key refuses the whole command: nothing is removed.
    let out = run(&["remove", mkt, "--key", "0", "--key", "999999"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(stderr.contains("no object has the key 999999"), "{stderr}");
    assert_eq!(file_stats(mkt)["objects"], objects);

    let removed = json(&run(&["remove", mkt, "--key", "0", "--key", "1", "--json"]));
    assert_eq!((removed["removed"].as_u64(), removed["objects"].as_u64()), (Some(2), Some(objects - 2)));
    assert!(run(&["get", mkt, "--key", "0"]).status.code() == Some(1), "key 0 is gone");
    json(&run(&["get", mkt, "--key", "2", "--json"]));
    let check = run(&["check", mkt]);
    assert!(check.status.success(), "{}", String::from_utf8_lossy(&check.stdout));

    // Building again into the same file leaves the old tree's blocks free.
    json(&run(&["build", obj, "-o", mkt, "--block-size", "4096", "--json"]));
    let grown = file_stats(mkt);
    assert!(grown["free_blocks"].as_u64().unwrap() > 0, "{grown}");
    let text = String::from_utf8_lossy(&run(&["stats", mkt]).stdout).to_string();
    assert!(text.contains("free"), "{text}");

    let c = json(&run(&["compact", mkt, "--json"]));
    assert_eq!(c["blocks_before"], grown["file_blocks"]);
    assert_eq!(c["free_after"], 0);
    let after = file_stats(mkt);
    assert_eq!(after["file_blocks"], c["blocks_after"]);
    assert!(after["file_blocks"].as_u64() < grown["file_blocks"].as_u64(), "{after}");
    assert_eq!(after["objects"], objects);
    let len = std::fs::metadata(mkt).unwrap().len();
    assert_eq!(len, after["file_blocks"].as_u64().unwrap() * 4096);
    assert!(run(&["check", mkt]).status.success());
}

/// Issue 39: `check` is a reader, so `remove` and `compact` beside a
/// running `check` succeed (before, 23 of 24 writers failed with "another
/// process is writing the file"); a writer refused by a real writer is told
/// so, and with `--wait` waits for it.
#[test]
fn remove_and_compact_beside_check_succeed_and_wait_waits_for_a_writer() {
    use std::sync::atomic::{AtomicBool, Ordering};
    let dir = tempfile::tempdir().unwrap();
    let (_, mkt) = tanker1_in(dir.path());
    let mkt = mkt.to_str().unwrap();
    let done = AtomicBool::new(false);
    std::thread::scope(|s| {
        let checks = s.spawn(|| {
            let mut runs = 0;
            while !done.load(Ordering::Relaxed) {
                let out = run(&["check", mkt]);
                assert!(
                    out.status.success(),
                    "check beside writers: {}",
                    String::from_utf8_lossy(&out.stdout)
                );
                runs += 1;
            }
            runs
        });
        for key in 0..12 {
            let out = run(&["remove", mkt, "--key", &key.to_string()]);
            assert!(out.status.success(), "remove beside check: {}", String::from_utf8_lossy(&out.stderr));
        }
        let out = run(&["compact", mkt]);
        assert!(out.status.success(), "compact beside check: {}", String::from_utf8_lossy(&out.stderr));
        done.store(true, Ordering::Relaxed);
        assert!(checks.join().unwrap() > 0);
    });

    // A real writer: this process holds the writer's lock.
    let db = mktree::db::Database::open(mkt).unwrap();
    let w = db.begin_write().unwrap();
    for args in [["remove", mkt, "--key", "20"].as_slice(), ["compact", mkt].as_slice()] {
        let out = run(args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{stderr}");
        assert!(
            stderr.contains("another process is writing the file") && stderr.contains("--wait"),
            "{stderr}"
        );
        assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");
    }
    let waiting = mktree()
        .args(["remove", mkt, "--key", "20", "--wait"])
        .stdout(std::process::Stdio::null())
        .spawn()
        .unwrap();
    std::thread::sleep(std::time::Duration::from_millis(300));
    drop(w);
    let out = waiting.wait_with_output().unwrap();
    assert!(out.status.success(), "remove --wait");
    let out = run(&["compact", mkt, "--wait"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(json(&run(&["check", mkt, "--json"]))["faults"].as_array().unwrap().is_empty());
}

#[test]
fn optimize_lays_a_changed_tree_out_again_and_keeps_every_object() {
    let dir = tempfile::tempdir().unwrap();
    let (obj, mkt) = tanker1_in(dir.path());
    let (obj, mkt) = (obj.to_str().unwrap(), mkt.to_str().unwrap());
    // The scene again, under new keys: its leaves overflow and split.
    let inserted = json(&run(&["insert", mkt, obj, "--json"]));
    assert_eq!(inserted["commit"]["in_place"], true, "{inserted}");
    let objects = file_stats(mkt)["objects"].as_u64().unwrap();
    let drift = || json(&run(&["stats", mkt, "--json"]))["drift"].clone();
    let before = drift();
    assert_eq!(before["stored_reads"].as_array().map(Vec::len), Some(4), "{before}");
    assert!(before["worst_ratio"].as_f64() >= Some(1.0), "{before}");
    let o = json(&run(&["optimize", mkt, "--json"]));
    // Leaves filled to twice their capacity in place go back to a bulk load's.
    assert!(o["after"]["leaves"].as_u64() > o["before"]["leaves"].as_u64(), "{o}");
    assert_eq!(file_stats(mkt)["objects"].as_u64(), Some(objects));
    let after = drift();
    assert_eq!(after["stored_reads"], after["fresh_reads"], "{after}");
    assert_eq!(after["worst_ratio"].as_f64(), Some(1.0), "{after}");
    let text = String::from_utf8_lossy(&run(&["stats", mkt]).stdout).to_string();
    assert!(text.contains("layout drift:") && text.contains("1.00x at worst"), "{text}");
    let check = run(&["check", mkt]);
    assert!(check.status.success(), "{}", String::from_utf8_lossy(&check.stdout));
    let out = run(&["optimize", &format!("{mkt}.missing")]);
    assert_eq!(out.status.code(), Some(1));
    assert_eq!(String::from_utf8_lossy(&out.stderr).lines().count(), 1);
}
