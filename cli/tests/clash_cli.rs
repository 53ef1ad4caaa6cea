//! Claim (issue 35): `mktree clash` with --a, --b and --type runs a typed
//! clash test: a table with counts by type and status, or one JSON line
//! per clash and a summary line; --test records it in FILE.clash with
//! statuses, which `clash-status` lists and sets, one writing process at a
//! time; --bcf writes a BCF archive; the untyped run is unchanged; bad
//! selectors, types and distances are one line and exit 1.

use std::path::Path;
use std::process::{Command, Output};

fn mktree(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_mktree")).args(args).output().unwrap()
}

fn ok(out: &Output) -> String {
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8(out.stdout.clone()).unwrap()
}

fn one_line_error(out: &Output, says: &str) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(stderr.contains(says), "{stderr}");
}

/// `clash-status` setting `status` on test "pipes"'s PIPE-1 / WALL-1 clash.
fn set_pipe_1<'a>(mkt: &'a str, status: &'a str) -> [&'a str; 10] {
    ["clash-status", mkt, "--test", "pipes", "--a", "PIPE-1", "--b", "WALL-1", "--set", status]
}

/// A wall, a pipe through it, a pipe 30 mm from it, a duct far away: as OBJ boxes keyed by name.
fn model(dir: &Path) -> String {
    let boxes = [
        ("WALL-1", [0.0, 0.0, 0.0], [200.0, 5000.0, 3000.0]),
        ("PIPE-1", [-500.0, 1000.0, 1000.0], [700.0, 1120.0, 1120.0]),
        ("PIPE-2", [230.0, 3000.0, 1000.0], [900.0, 3100.0, 1100.0]),
        ("DUCT-1", [5000.0, 0.0, 0.0], [5300.0, 200.0, 200.0]),
    ];
    let mut obj = String::new();
    for (i, (name, lo, hi)) in boxes.iter().enumerate() {
        obj.push_str(&format!("o {name}\n"));
        for c in 0..8 {
            let p = |a: usize| if c & (1 << a) == 0 { lo[a] } else { hi[a] };
            obj.push_str(&format!("v {} {} {}\n", p(0), p(1), p(2)));
        }
        let b = i * 8 + 1;
        for q in [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]] {
            obj.push_str(&format!(
                "f {} {} {}\nf {} {} {}\n",
                b + q[0],
                b + q[1],
                b + q[2],
                b + q[0],
                b + q[2],
                b + q[3]
            ));
        }
    }
    let path = dir.join("m.obj");
    std::fs::write(&path, obj).unwrap();
    let mkt = dir.join("m.mkt");
    ok(&mktree(&["build", path.to_str().unwrap(), "-o", mkt.to_str().unwrap(), "--key-names"]));
    mkt.to_str().unwrap().to_string()
}

#[test]
fn a_typed_test_prints_json_lines_and_a_table() {
    let dir = tempfile::tempdir().unwrap();
    let mkt = model(dir.path());
    let args =
        ["clash", &mkt, "--a", "name:PIPE*", "--b", "name:WALL*", "--type", "clearance", "--distance", "50"];
    let out = ok(&mktree(&[&args[..], &["--json"]].concat()));
    let lines: Vec<serde_json::Value> = out.lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    assert_eq!(lines.len(), 3, "two clashes and the summary");
    assert_eq!((lines[0]["a"].as_str(), lines[0]["type"].as_str()), (Some("PIPE-1"), Some("hard")));
    assert!((lines[0]["depth"].as_f64().unwrap() - 120.0).abs() < 1e-9);
    assert_eq!((lines[1]["a"].as_str(), lines[1]["type"].as_str()), (Some("PIPE-2"), Some("clearance")));
    assert!((lines[1]["distance"].as_f64().unwrap() - 30.0).abs() < 1e-9);
    assert_eq!(lines[1]["closest"].as_array().map(Vec::len), Some(2));
    assert_eq!(lines[2]["summary"]["clashes"], 2);
    let table = ok(&mktree(&args));
    assert!(
        table.contains("PIPE-1") && table.contains("clearance") && table.contains("2 clashes"),
        "{table}"
    );
    // The untyped run is what it was.
    let raw: serde_json::Value = serde_json::from_str(&ok(&mktree(&["clash", &mkt, "--json"]))).unwrap();
    assert!(raw["pairs"].is_array() && raw["block_reads"].is_object());
}

#[test]
fn a_recorded_test_keeps_statuses_that_clash_status_sets() {
    let dir = tempfile::tempdir().unwrap();
    let mkt = model(dir.path());
    let run = [
        "clash",
        &mkt,
        "--test",
        "pipes",
        "--a",
        "name:PIPE*",
        "--b",
        "name:WALL*",
        "--type",
        "hard",
        "--json",
    ];
    let first = ok(&mktree(&run));
    assert!(first.contains("\"status\":\"new\"") && first.contains("no recorded run"), "{first}");
    assert!(Path::new(&format!("{mkt}.clash")).exists());
    ok(&mktree(&set_pipe_1(&mkt, "approved")));
    let again = ok(&mktree(&["clash", &mkt, "--test", "pipes", "--json"]));
    assert!(again.contains("\"status\":\"approved\"") && again.contains("incremental"), "{again}");
    let listed = ok(&mktree(&["clash-status", &mkt, "--test", "pipes"]));
    assert!(listed.contains("approved") && listed.contains("PIPE-1"), "{listed}");
    one_line_error(&mktree(&set_pipe_1(&mkt, "resolved")), "a person sets");
    one_line_error(&mktree(&["clash-status", &mkt, "--test", "nothing"]), "no recorded run");
    // A damaged store is one line, not a panic.
    std::fs::write(format!("{mkt}.clash"), b"MKTCLASH garbage").unwrap();
    one_line_error(&mktree(&["clash", &mkt, "--test", "pipes"]), "clash store");
}

#[test]
fn a_status_set_while_another_process_writes_the_store_waits_and_both_changes_stay() {
    use std::io::BufRead;
    let dir = tempfile::tempdir().unwrap();
    let mkt = model(dir.path());
    let run = ["clash", &mkt, "--test", "pipes", "--a", "name:PIPE*", "--b", "name:WALL*", "--type", "hard"];
    ok(&mktree(&run));
    let path = mktree::clash::store_path(Path::new(&mkt));
    // This process writes the store (as a long run would) while another sets a status.
    let lock = mktree::clash::StoreLock::acquire(&path).unwrap();
    let mut store = lock.load().unwrap();
    let mut child = Command::new(env!("CARGO_BIN_EXE_mktree"))
        .args(set_pipe_1(&mkt, "approved"))
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut said = String::new();
    std::io::BufReader::new(child.stderr.take().unwrap()).read_line(&mut said).unwrap();
    assert!(said.starts_with("waiting for another process writing"), "{said}");
    let saved = store.tests["pipes"].clone();
    store.tests.insert("later".into(), saved);
    lock.save(&store).unwrap();
    drop(lock);
    let out = child.wait_with_output().unwrap();
    assert!(out.status.success());
    assert!(String::from_utf8_lossy(&out.stdout).contains("set to approved"));
    // Unserialized, the status set would have been written over, or this test's entry.
    let after = mktree::clash::ClashStore::load(&path).unwrap();
    assert!(after.tests.contains_key("later"));
    let listed = ok(&mktree(&["clash-status", &mkt, "--test", "pipes"]));
    assert!(listed.contains("approved") && listed.contains("PIPE-1"), "{listed}");
}

#[test]
fn bcf_is_written_and_bad_input_is_one_line() {
    let dir = tempfile::tempdir().unwrap();
    let mkt = model(dir.path());
    let bcf = dir.path().join("out.bcf");
    ok(&mktree(&["clash", &mkt, "--a", "name:PIPE*", "--b", "name:WALL*", "--bcf", bcf.to_str().unwrap()]));
    let bytes = std::fs::read(&bcf).unwrap();
    assert_eq!(&bytes[..4], b"PK\x03\x04");
    let text = String::from_utf8_lossy(&bytes);
    assert!(text.contains("bcf.version") && text.contains("markup.bcf") && text.contains("snapshot.png"));
    assert!(text.contains("<AuthoringToolId>PIPE-1</AuthoringToolId>"), "keys that are not GlobalIds");
    one_line_error(&mktree(&["clash", &mkt, "--a", "colour:red"]), "selector");
    one_line_error(&mktree(&["clash", &mkt, "--type", "soft"]), "--type soft");
    one_line_error(&mktree(&["clash", &mkt, "--type", "clearance"]), "distance above 0");
    one_line_error(&mktree(&["clash", &mkt, "--distance=-5"]), "distance");
    one_line_error(&mktree(&["clash", &mkt, "--a", "all", "--clearance", "5"]), "--clearance");
}
