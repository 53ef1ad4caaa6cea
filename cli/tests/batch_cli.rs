//! Claim: `mktree batch` answers one JSON line per request, in order, as the
//! library answers it (objects and reads; nearest and ray hits with their
//! distances), and a bad line gets a one-line error answer while the rest
//! are answered and the exit status stays 0.

use std::io::Write;
use std::process::Stdio;

use mktree::db::Database;
use mktree::geom::{Point, Ray, Vector};

mod common;

use common::{batch_with, mktree, tanker1_in};

#[test]
fn batch_answers_each_line_and_a_bad_line_with_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let (_, mkt) = tanker1_in(dir.path());
    let db = Database::open_read_only(&mkt).unwrap();
    let r = db.begin_read().unwrap();
    // Along x through the middle of the ship, from outside it.
    let c = r.root().unwrap().aabb.center();
    let origin = Point::new(r.root().unwrap().aabb.min.x - 1000.0, c.y, c.z);
    let requests = format!(
        r#"{{"query": "box", "box": [0, 0, 0, 1000, 1000, 1000]}}
# a comment, and a blank line

{{"query": "nearest", "point": [100, 200, 300], "k": 3}}
{{"query": "ray", "origin": [{}, {}, {}], "direction": [1, 0, 0], "all": true}}
{{"query": "sphere", "center": [0, 0, 0], "radius": -1}}
not json
{{"query": "collide", "object": 5, "clearance": 10}}
{{"query": "box", "box": [0, 0, 0, 1, 1, 1], "lod": 9}}
"#,
        origin.x, origin.y, origin.z
    );
    let mut child = mktree()
        .args(["batch", mkt.to_str().unwrap()])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    child.stdin.take().unwrap().write_all(requests.as_bytes()).unwrap();
    let out = child.wait_with_output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let answers: Vec<serde_json::Value> =
        String::from_utf8(out.stdout).unwrap().lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    let lines: Vec<u64> = answers.iter().map(|a| a["line"].as_u64().unwrap()).collect();
    assert_eq!(lines, [1, 4, 5, 6, 7, 8, 9]);
    for bad in [3, 4, 6] {
        assert!(answers[bad]["error"].is_string(), "line {}: {}", lines[bad], answers[bad]);
    }

    let ids = |v: &serde_json::Value| -> Vec<u32> {
        v["objects"].as_array().unwrap().iter().map(|x| x.as_u64().unwrap() as u32).collect()
    };
    let boxed = r.query_box(&mktree::geom::Aabb::from_array([0.0, 0.0, 0.0, 1e3, 1e3, 1e3])).unwrap();
    assert_eq!(ids(&answers[0]), boxed.objects.iter().map(|o| o.0).collect::<Vec<_>>());
    assert_eq!(answers[0]["reads"]["node"].as_u64().unwrap(), boxed.stats.reads.node);

    let near: Vec<_> =
        r.nearest(Point::new(100.0, 200.0, 300.0), None).unwrap().take(3).map(|x| x.unwrap()).collect();
    assert_eq!(ids(&answers[1]), near.iter().map(|n| n.object.0).collect::<Vec<_>>());
    let distances: Vec<f64> =
        answers[1]["distances"].as_array().unwrap().iter().map(|d| d.as_f64().unwrap()).collect();
    assert_eq!(distances, near.iter().map(|n| n.distance).collect::<Vec<_>>());

    let ray = Ray::new(origin, Vector::x(), None).unwrap();
    let hits: Vec<_> = r.ray(&ray, None).unwrap().map(|h| h.unwrap()).collect();
    assert!(!hits.is_empty(), "the ray crosses the ship");
    assert_eq!(ids(&answers[2]), hits.iter().map(|h| h.object.0).collect::<Vec<_>>());
    assert_eq!(answers[2]["points"].as_array().unwrap().len(), hits.len());
    assert!(answers[5]["objects"].is_array(), "collide: {}", answers[5]);
}

#[test]
fn batch_skips_an_endless_line_with_an_error_and_answers_the_next() {
    let dir = tempfile::tempdir().unwrap();
    let (_, mkt) = tanker1_in(dir.path());
    // 64 MiB of zero bytes without a newline (what /dev/zero gives), then a request.
    let mut input = vec![0u8; 64 << 20];
    input.extend_from_slice(b"\n{\"query\": \"box\", \"box\": [0, 0, 0, 1000, 1000, 1000]}\n");
    let (status, answers, stderr) = batch_with(&mkt, &[], input);
    assert!(status.success(), "{stderr}");
    assert_eq!(answers.len(), 2, "{answers:?}");
    assert_eq!(answers[0]["line"], 1);
    let error = answers[0]["error"].as_str().unwrap();
    assert!(error.contains("line 1") && error.contains("longer than 1048576 bytes"), "{error}");
    assert_eq!(answers[1]["line"], 2);
    assert!(answers[1]["objects"].is_array(), "{}", answers[1]);

    // The flag sets the limit.
    let input = b"{\"query\": \"nearest\", \"point\": [0, 0, 0], \"k\": 1}\n".to_vec();
    let (status, answers, _) = batch_with(&mkt, &["--max-line", "16"], input.clone());
    assert!(status.success());
    assert!(answers[0]["error"].as_str().unwrap().contains("longer than 16 bytes"), "{}", answers[0]);
    let (_, answers, _) = batch_with(&mkt, &["--max-line", "1K"], input);
    assert!(answers[0]["objects"].is_array(), "{}", answers[0]);
}

#[test]
fn batch_answers_a_non_utf8_line_with_an_error_and_goes_on() {
    let dir = tempfile::tempdir().unwrap();
    let (_, mkt) = tanker1_in(dir.path());
    let mut input = b"{\"query\": \"box\", \"box\": [0, 0, 0, 1000, 1000, 1000]}\n".to_vec();
    input.extend_from_slice(b"{\"query\": \"box\", \"box\": [0, 0, 0, 1, 1, \xff\xfe]}\n");
    input.extend_from_slice(b"{\"query\": \"nearest\", \"point\": [0, 0, 0], \"k\": 2}\n");
    let (status, answers, stderr) = batch_with(&mkt, &[], input);
    assert!(status.success(), "{stderr}");
    let lines: Vec<u64> = answers.iter().map(|a| a["line"].as_u64().unwrap()).collect();
    assert_eq!(lines, [1, 2, 3]);
    assert!(answers[0]["objects"].is_array());
    let error = answers[1]["error"].as_str().unwrap();
    assert!(error.contains("line 2 is not UTF-8"), "{error}");
    assert_eq!(answers[2]["distances"].as_array().unwrap().len(), 2);
}

#[test]
fn batch_and_query_refuse_an_inverted_box_and_a_far_point_alike() {
    let dir = tempfile::tempdir().unwrap();
    let (_, mkt) = tanker1_in(dir.path());
    let input = b"{\"query\": \"box\", \"box\": [100, 0, 0, 0, 100, 100]}\n\
        {\"query\": \"nearest\", \"point\": [1e160, 0, 0], \"k\": 2}\n"
        .to_vec();
    let (status, answers, _) = batch_with(&mkt, &[], input);
    assert!(status.success());
    let inverted = answers[0]["error"].as_str().expect("an inverted box is an error in batch");
    assert!(inverted.contains("inverted"), "{inverted}");
    let far = answers[1]["error"].as_str().expect("a far point is an error, not null distances");
    assert!(far.contains("coordinate range"), "{far}");

    let out = mktree().args(["query", mkt.to_str().unwrap(), "--box", "100,0,0,0,100,100"]).output().unwrap();
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains(inverted), "query --box says {stderr:?}, batch {inverted:?}");
    assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");
    let out = mktree().args(["query", mkt.to_str().unwrap(), "--box", "0,0,0,1e30,1,1"]).output().unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("coordinate range"));
}

#[test]
fn batch_reports_an_endless_line_before_it_ends() {
    use std::io::BufRead;
    let dir = tempfile::tempdir().unwrap();
    let (_, mkt) = tanker1_in(dir.path());
    let mut child = mktree()
        .args(["batch", mkt.to_str().unwrap(), "--max-line", "64K"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdin = child.stdin.take().unwrap();
    // /dev/zero never ends its line: 1 MiB of it, the input left open.
    stdin.write_all(&vec![0u8; 1 << 20]).unwrap();
    stdin.flush().unwrap();
    let mut first = String::new();
    std::io::BufReader::new(child.stdout.take().unwrap()).read_line(&mut first).unwrap();
    let answer: serde_json::Value = serde_json::from_str(&first).unwrap();
    assert_eq!(answer["line"], 1);
    assert!(answer["error"].as_str().unwrap().contains("longer than 65536 bytes"), "{answer}");
    drop(stdin);
    assert!(child.wait().unwrap().success());
}
