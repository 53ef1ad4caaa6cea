//! Claim (issue 12, many processes): readers in other processes keep working
//! while writers commit, each read seeing one whole committed tree, never an
//! error; writers in two processes take turns when asked to wait. The
//! children are this test binary run again on one ignored test, `child`,
//! with the role in the environment.

mod common;

use std::collections::BTreeSet;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use mktree::bulk::{BuildParams, LeafRule, Method};
use mktree::db::{CreateOptions, Database, WriterWait};
use mktree::geom::Aabb;

const ROLE: &str = "MKTREE_TEST_ROLE";
const FILE: &str = "MKTREE_TEST_FILE";
/// Queries per reader process, at least; two readers make 1,000.
const QUERIES: usize = 500;
/// Commits by the parent, at least.
const COMMITS: usize = 20;
/// Sizes of the trees the writers commit (and the first one).
const SIZES: [usize; 3] = [30, 45, 70];

fn everything() -> Aabb {
    Aabb::from_array([-1e6, -1e6, -1e6, 1e6, 1e6, 1e6])
}

fn commit(db: &Database, objects: usize) {
    let mut w = db.begin_write_with(WriterWait::Wait).expect("begin_write");
    let params = BuildParams { method: Method::Median, leaf: LeafRule::Objects(4), ..BuildParams::paper() };
    w.bulk_load(&common::grid_scene(objects), &params, &|_| {}).expect("bulk_load");
    w.commit().expect("commit");
}

/// One read: the whole tree, which must be one of the committed trees whole.
fn read_once(db: &Database) -> Result<usize, String> {
    let r = db.begin_read().map_err(|e| e.to_string())?;
    let n = r.info().ok_or("no tree")?.objects as usize;
    let got: Vec<u32> =
        r.query_box(&everything()).map_err(|e| e.to_string())?.objects.iter().map(|o| o.0).collect();
    if !SIZES.contains(&n) || got != (0..n as u32).collect::<Vec<_>>() {
        return Err(format!("a mixed answer: {} objects from a tree of {n}", got.len()));
    }
    Ok(n)
}

/// A child's work, by role: `reader` (one open, many reads), `reopener` (an
/// open per read, read-only) or `writer` (five commits, waiting its turn).
#[test]
#[ignore = "run by the other tests of this file as a child process"]
fn child() {
    let (Ok(role), Ok(file)) = (std::env::var(ROLE), std::env::var(FILE)) else {
        panic!("run by processes.rs's tests, with {ROLE} and {FILE} set")
    };
    let path = Path::new(&file);
    let deadline = Instant::now() + Duration::from_secs(120);
    let (mut failures, mut sizes, mut reads) = (0, BTreeSet::new(), 0);
    match role.as_str() {
        "writer" => {
            let db = Database::open(path).expect("open");
            for _ in 0..5 {
                commit(&db, SIZES[1]);
            }
        }
        "reader" | "reopener" => {
            let db = Database::open_read_only(path).expect("open");
            std::fs::write(path.with_extension(&role), b"").unwrap();
            // Until the parent has made its commits, and at least QUERIES reads.
            let stop = path.with_extension("stop");
            while reads < QUERIES || !stop.exists() {
                reads += 1;
                assert!(Instant::now() < deadline, "the reads took over two minutes");
                let result = if role == "reader" {
                    read_once(&db)
                } else {
                    Database::open_read_only(path).map_err(|e| e.to_string()).and_then(|db| read_once(&db))
                };
                match result {
                    Ok(n) => {
                        sizes.insert(n);
                    }
                    Err(e) => {
                        failures += 1;
                        eprintln!("read failed: {e}");
                    }
                }
            }
        }
        r => panic!("unknown role {r}"),
    }
    println!("\nRESULT failures={failures} reads={reads} sizes={sizes:?}");
}

fn spawn(role: &str, file: &Path) -> std::process::Child {
    Command::new(std::env::current_exe().unwrap())
        .args(["--exact", "child", "--ignored", "--nocapture", "--test-threads=1"])
        .env(ROLE, role)
        .env(FILE, file)
        .stdout(Stdio::piped())
        .spawn()
        .unwrap()
}

#[test]
fn readers_in_other_processes_never_fail_during_commits() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("shared.mkt");
    let db = Database::create(&path, CreateOptions { block_size: 4096, lod_levels: 2 }).unwrap();
    commit(&db, SIZES[0]);
    let readers = [spawn("reader", &path), spawn("reopener", &path)];
    let started = Instant::now();
    // The readers are reading before the first commit.
    while !["reader", "reopener"].iter().all(|r| path.with_extension(r).exists()) {
        assert!(started.elapsed() < Duration::from_secs(60), "the readers did not start");
        std::thread::sleep(Duration::from_millis(5));
    }
    let writer = spawn("writer", &path);
    for commits in 0..COMMITS {
        commit(&db, SIZES[commits % 2 * 2]);
    }
    std::fs::write(path.with_extension("stop"), b"").unwrap();
    let outputs: Vec<_> =
        readers.into_iter().chain([writer]).map(|c| c.wait_with_output().unwrap()).collect();
    let mut reads_saw = BTreeSet::new();
    for out in &outputs {
        let text = String::from_utf8_lossy(&out.stdout);
        assert!(out.status.success(), "a child failed: {text}");
        let line =
            text.lines().find(|l| l.starts_with("RESULT")).unwrap_or_else(|| panic!("no result in {text}"));
        assert!(line.contains("failures=0 "), "{line}");
        eprintln!("{line}");
        reads_saw.insert(line.to_string());
    }
    // The readers saw more than one tree: the reads really overlapped the commits.
    assert!(reads_saw.iter().any(|l| l.matches(',').count() >= 1), "no reader saw two trees: {reads_saw:?}");
    assert!(mktree::db::check(&db).unwrap().ok());
}
