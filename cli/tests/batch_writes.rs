//! Claim: `mktree batch` takes changes by key (insert, update, move,
//! remove) besides queries: each change commits on its own, or every
//! `--commit-every N` together with a last commit when the input ends;
//! queries see committed changes only; a change that fails answers its
//! error and the rest go on; and the file afterwards checks clean and
//! holds exactly the committed changes.

use mktree::db::Database;
use mktree::scene::Key;
use serde_json::Value;

mod common;

use common::{batch_with, tanker1_in};

fn batch(mkt: &std::path::Path, args: &[&str], input: &str) -> Vec<Value> {
    let (status, answers, stderr) = batch_with(mkt, args, input.as_bytes().to_vec());
    assert!(status.success(), "{stderr}");
    answers
}

const EVERYTHING: &str = r#"{"query": "box", "box": [-1e6, -1e6, -1e6, 1e6, 1e6, 1e6]}"#;
const TRIANGLE: &str = r#""vertices": [[0, 0, 0], [100, 0, 0], [0, 100, 0]], "triangles": [[0, 1, 2]]"#;

#[test]
fn grouped_changes_commit_together_and_queries_see_commits_only() {
    let dir = tempfile::tempdir().unwrap();
    let (_, mkt) = tanker1_in(dir.path());
    let before = Database::open_read_only(&mkt).unwrap().begin_read().unwrap().object(&Key::Int(3)).unwrap();
    let before = before.expect("tanker1 has key 3").aabb();
    let input = [
        EVERYTHING.to_string(),
        r#"{"write": "move", "key": 3, "by": [500, 0, 0]}"#.into(),
        EVERYTHING.into(),
        r#"{"write": "remove", "key": 4}"#.into(),
        r#"{"write": "remove", "key": 99999}"#.into(),
        format!(r#"{{"write": "insert", "key": "extra", "name": "tri", {TRIANGLE}}}"#),
        format!(r#"{{"write": "insert", "key": 5, {TRIANGLE}}}"#),
        format!(r#"{{"write": "update", "key": "nobody", {TRIANGLE}}}"#),
        r#"{"write": "teleport", "key": 1}"#.into(),
        EVERYTHING.into(),
        r#"{"write": "remove", "key": 7}"#.into(),
    ]
    .join("\n");
    let a = batch(&mkt, &["--commit-every", "2"], &input);
    assert_eq!(a.len(), 12, "an answer per line and one for the last commit: {a:#?}");
    let count = |v: &Value| v["objects"].as_array().unwrap().len();
    let n = count(&a[0]);
    assert_eq!(a[1]["pending"], true, "{}", a[1]);
    assert_eq!(count(&a[2]), n, "a pending change is not seen");
    assert_eq!(a[3]["committed"]["lines"], serde_json::json!([2, 4]), "{}", a[3]);
    assert_eq!(a[3]["committed"]["stats"]["changes"], 2);
    assert_eq!(a[3]["committed"]["stats"]["in_place"], true);
    assert_eq!((a[4]["found"].clone(), a[4]["pending"].clone()), (false.into(), true.into()));
    assert_eq!(a[5]["committed"]["lines"], serde_json::json!([5, 6]), "{}", a[5]);
    for failed in [6, 7, 8] {
        assert!(a[failed]["error"].is_string(), "line {}: {}", failed + 1, a[failed]);
    }
    assert_eq!(count(&a[9]), n, "one removed, one inserted");
    assert_eq!(a[10]["pending"], true);
    assert!(a[11].get("line").is_none() && a[11]["lines"] == serde_json::json!([11]), "{}", a[11]);

    let db = Database::open_read_only(&mkt).unwrap();
    let report = mktree::check(&db).unwrap();
    assert!(report.ok(), "{:?}", report.faults);
    let r = db.begin_read().unwrap();
    assert!(r.object(&Key::Int(4)).unwrap().is_none());
    assert!(r.object(&Key::Int(7)).unwrap().is_none());
    assert_eq!(r.object(&Key::bytes("extra").unwrap()).unwrap().unwrap().name, "tri");
    let moved = r.object(&Key::Int(3)).unwrap().unwrap().aabb();
    assert!((moved.min.x - before.min.x - 500.0).abs() < 1e-6 && moved.min.y == before.min.y);
}

#[test]
fn each_change_commits_on_its_own_by_default() {
    let dir = tempfile::tempdir().unwrap();
    let (_, mkt) = tanker1_in(dir.path());
    let input =
        [r#"{"write": "move", "key": 1, "by": [0, 0, 10]}"#, r#"{"write": "remove", "key": 2}"#, EVERYTHING]
            .join("\n");
    let a = batch(&mkt, &[], &input);
    assert_eq!(a.len(), 3, "{a:#?}");
    for (i, lines) in [(0, [1]), (1, [2])] {
        assert_eq!(a[i]["committed"]["lines"], serde_json::json!(lines), "{}", a[i]);
        assert_eq!(a[i]["committed"]["stats"]["syncs"], 1, "a small commit syncs once: {}", a[i]);
    }
    let keys: Vec<u64> = a[2]["keys"].as_array().unwrap().iter().filter_map(Value::as_u64).collect();
    assert!(keys.contains(&1) && !keys.contains(&2));
}
