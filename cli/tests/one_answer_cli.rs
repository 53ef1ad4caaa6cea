//! Claims (issue 39, "one answer for one question"): a file emptied by
//! removals answers `query` and `clash` alike (no objects, no pairs, exit
//! 0); a key is an integer only when written as one, so `get --key +5`
//! does not find key 5; and a FIFO given as a scene or a file is refused
//! in one line instead of waiting for a writer that never comes.

mod common;

use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use common::{mktree, tanker1_in};

fn run(args: &[&str]) -> Output {
    mktree().args(args).output().unwrap()
}

fn json(out: &Output) -> serde_json::Value {
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).unwrap()
}

/// Runs `cmd`, killing it and failing the test if it runs past 30 s.
fn within_30_s(cmd: &mut Command) -> Output {
    let mut child = cmd.stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().unwrap();
    let started = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if started.elapsed() > Duration::from_secs(30) {
            let _ = child.kill();
            let _ = child.wait();
            panic!("{cmd:?} still ran after 30 s");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    child.wait_with_output().unwrap()
}

#[test]
fn an_emptied_file_answers_query_and_clash_alike() {
    let dir = tempfile::tempdir().unwrap();
    let (_, mkt) = tanker1_in(dir.path());
    let mkt = mkt.to_str().unwrap();
    let objects = json(&run(&["stats", mkt, "--json"]))["file"]["objects"].as_u64().unwrap();
    let keys: Vec<String> = (0..objects).map(|k| k.to_string()).collect();
    let mut args = vec!["remove", mkt];
    for k in &keys {
        args.extend(["--key", k]);
    }
    json(&run(&[args.as_slice(), &["--json"]].concat()));

    let q = json(&run(&["query", mkt, "--box", "-1e6,-1e6,-1e6,1e6,1e6,1e6", "--json"]));
    assert_eq!(q["objects"].as_array().unwrap().len(), 0);
    let c = json(&run(&["clash", mkt, "--json"]));
    assert_eq!(c["pairs"].as_array().unwrap().len(), 0, "{c}");
    let out = run(&["collide", mkt, "--object", "0"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && stderr.contains("object 0 is not in the file (0 objects)"), "{stderr}");
}

#[test]
fn a_key_is_an_integer_only_when_written_as_one() {
    let dir = tempfile::tempdir().unwrap();
    let (_, mkt) = tanker1_in(dir.path());
    let mkt = mkt.to_str().unwrap();
    assert_eq!(json(&run(&["get", mkt, "--key", "5", "--json"]))["id"], 5);
    for text in ["+5", "05", " 5"] {
        let out = run(&["get", mkt, "--key", text]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "get --key {text:?} found key 5");
        assert!(stderr.contains("no object has the key"), "{stderr}");
        let out = run(&["remove", mkt, "--key", text]);
        assert_eq!(out.status.code(), Some(1), "remove --key {text:?} removed key 5");
    }
    assert_eq!(json(&run(&["get", mkt, "--key", "5", "--json"]))["id"], 5, "key 5 is still there");
}

#[cfg(unix)]
#[test]
fn a_fifo_as_a_scene_or_a_file_is_refused_in_one_line() {
    let dir = tempfile::tempdir().unwrap();
    let (_, mkt) = tanker1_in(dir.path());
    let fifo = dir.path().join("scene.obj");
    let made = Command::new("mkfifo").arg(&fifo).status().unwrap();
    assert!(made.success());
    let (fifo, mkt) = (fifo.to_str().unwrap(), mkt.to_str().unwrap());
    let out_mkt = dir.path().join("out.mkt");
    for args in [
        vec!["info", fifo],
        vec!["build", fifo, "-o", out_mkt.to_str().unwrap()],
        vec!["collide", mkt, "--mesh", fifo],
        vec!["stats", fifo],
        vec!["check", fifo],
    ] {
        let out = within_30_s(mktree().args(&args));
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?}");
        assert!(stderr.contains("not a regular file"), "{args:?}: {stderr}");
        assert_eq!(stderr.trim().lines().count(), 1, "{args:?}: {stderr}");
    }
}

/// The OBJ reader keys `o caf\xe9` (Latin-1) as `caf\u{fffd}`; `get` and
/// `remove` read the same bytes typed as a key the same way (before, clap
/// refused them as invalid UTF-8, and the object could not be reached).
#[cfg(unix)]
#[test]
fn a_key_from_a_name_that_is_not_utf8_is_reached_by_that_name() {
    use std::ffi::OsStr;
    use std::os::unix::ffi::OsStrExt;
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("latin1.obj");
    let mut text = b"o caf\xe9\nv 0 0 0\nv 10 0 0\nv 0 10 0\nf 1 2 3\n".to_vec();
    text.extend_from_slice(b"o plain\nv 0 0 5\nv 10 0 5\nv 0 10 5\nf 4 5 6\n");
    std::fs::write(&obj, text).unwrap();
    let mkt = dir.path().join("k.mkt");
    let (obj, mkt) = (obj.to_str().unwrap(), mkt.to_str().unwrap());
    json(&run(&["build", obj, "-o", mkt, "--key-names", "--json"]));
    let shown = json(&run(&["query", mkt, "--box", "-1,-1,-1,11,11,1", "--json"]))["keys"][0].clone();
    assert_eq!(shown, "caf\u{fffd}");
    let latin1 = OsStr::from_bytes(b"caf\xe9");
    let get = |key: &OsStr| mktree().args(["get", mkt, "--json", "--key"]).arg(key).output().unwrap();
    assert_eq!(json(&get(latin1))["id"], 0);
    assert_eq!(json(&get(OsStr::new("caf\u{fffd}")))["id"], 0);
    json(&mktree().args(["remove", mkt, "--json", "--key"]).arg(latin1).output().unwrap());
    assert_eq!(get(latin1).status.code(), Some(1));
    assert_eq!(
        json(&run(&["get", mkt, "--key", "plain", "--json"]))["id"],
        1,
        "a change commit leaves the other objects' ids as they were"
    );
}
