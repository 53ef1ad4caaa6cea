//! Claim (issue 12, many processes): readers in other processes keep working
//! while writers commit, each read seeing one whole committed tree, never an
//! error, through bulk loads and through a stream of single-object change
//! commits written in place (issue 33: splits and merges among them);
//! writers in two processes take turns when asked to wait. The
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

/// One read of a tree that change commits reshape: every object once, as
/// many as the snapshot counts, and each key answered found by key in it.
fn read_changed(db: &Database) -> Result<usize, String> {
    let r = db.begin_read().map_err(|e| e.to_string())?;
    let n = r.info().ok_or("no tree")?.objects as usize;
    let answer = r.query_box(&everything()).map_err(|e| e.to_string())?;
    let mut ids: Vec<u32> = answer.objects.iter().map(|o| o.0).collect();
    ids.sort_unstable();
    ids.dedup();
    if ids.len() != n || answer.keys.len() != n {
        return Err(format!(
            "a mixed answer: {} objects, {} keys from a tree of {n}",
            ids.len(),
            answer.keys.len()
        ));
    }
    for key in answer.keys.iter().step_by(17) {
        r.get(key).map_err(|e| e.to_string())?.ok_or_else(|| format!("key {key} answered, not found"))?;
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
        "reader" | "reopener" | "change-reader" | "change-reopener" => {
            let read = if role.starts_with("change-") { read_changed } else { read_once };
            let db = Database::open_read_only(path).expect("open");
            std::fs::write(path.with_extension(&role), b"").unwrap();
            // Until the parent has made its commits, and at least QUERIES reads.
            let stop = path.with_extension("stop");
            while reads < QUERIES || !stop.exists() {
                reads += 1;
                assert!(Instant::now() < deadline, "the reads took over two minutes");
                let result = if role.ends_with("reader") {
                    read(&db)
                } else {
                    Database::open_read_only(path).map_err(|e| e.to_string()).and_then(|db| read(&db))
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
        "holder" => {
            // One snapshot held until the parent says stop.
            let db = Database::open_read_only(path).expect("open");
            let r = db.begin_read().expect("begin_read");
            std::fs::write(path.with_extension(&role), b"").unwrap();
            while !path.with_extension("stop").exists() {
                assert!(Instant::now() < deadline, "held for over two minutes");
                std::thread::sleep(Duration::from_millis(5));
            }
            reads = r.query_box(&everything()).expect("query").objects.len();
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

/// Waits until each child of `roles` has marked itself started beside `path`.
fn started(path: &Path, roles: &[&str]) {
    let t = Instant::now();
    while !roles.iter().all(|r| path.with_extension(r).exists()) {
        assert!(t.elapsed() < Duration::from_secs(60), "{roles:?} did not start");
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// Each child's RESULT line, once it succeeded with no failed read.
fn results(children: impl IntoIterator<Item = std::process::Child>) -> Vec<String> {
    let mut lines = Vec::new();
    for child in children {
        let out = child.wait_with_output().unwrap();
        let text = String::from_utf8_lossy(&out.stdout);
        assert!(out.status.success(), "a child failed: {text}");
        let line =
            text.lines().find(|l| l.starts_with("RESULT")).unwrap_or_else(|| panic!("no result in {text}"));
        assert!(line.contains("failures=0 "), "{line}");
        eprintln!("{line}");
        lines.push(line.to_string());
    }
    lines
}

#[test]
fn readers_in_other_processes_never_fail_during_commits() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("shared.mkt");
    let db = Database::create(&path, CreateOptions { block_size: 4096, lod_levels: 2 }).unwrap();
    commit(&db, SIZES[0]);
    let readers = [spawn("reader", &path), spawn("reopener", &path)];
    // The readers are reading before the first commit.
    started(&path, &["reader", "reopener"]);
    let writer = spawn("writer", &path);
    for commits in 0..COMMITS {
        commit(&db, SIZES[commits % 2 * 2]);
    }
    std::fs::write(path.with_extension("stop"), b"").unwrap();
    let reads_saw: BTreeSet<String> = results(readers.into_iter().chain([writer])).into_iter().collect();
    // The readers saw more than one tree: the reads really overlapped the commits.
    assert!(reads_saw.iter().any(|l| l.matches(',').count() >= 1), "no reader saw two trees: {reads_saw:?}");
    assert!(mktree::db::check(&db).unwrap().ok());
}

#[test]
fn readers_in_other_processes_never_fail_during_single_change_commits() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("changed.mkt");
    let db = Database::create(&path, CreateOptions { block_size: 4096, lod_levels: 2 }).unwrap();
    let mut w = db.begin_write().unwrap();
    let params = BuildParams { method: Method::Moa, leaf: LeafRule::Objects(4), ..BuildParams::paper() };
    w.bulk_load(&common::grid_scene(200), &params, &|_| {}).unwrap();
    w.commit().unwrap();
    let readers = [spawn("change-reader", &path), spawn("change-reopener", &path)];
    started(&path, &["change-reader", "change-reopener"]);
    // Inserts around one place (its leaves split), moves and removals, one per commit.
    let mut in_place = 0;
    for i in 0..300u64 {
        let mut w = db.begin_write_with(WriterWait::Wait).unwrap();
        common::stream_change(&mut w, i);
        in_place += usize::from(w.commit_with_stats().unwrap().in_place);
    }
    // The rest emptied a leaf beside a subtree of more than 64 objects, which writes the tree whole.
    assert!(in_place >= 270, "{in_place} of 300 commits in place");
    std::fs::write(path.with_extension("stop"), b"").unwrap();
    results(readers);
    assert!(mktree::db::check(&db).unwrap().ok());
}

#[test]
fn a_reader_in_another_process_keeps_only_the_blocks_it_reads() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("held.mkt");
    let db = Database::create(&path, CreateOptions { block_size: 4096, lod_levels: 2 }).unwrap();
    let mut w = db.begin_write().unwrap();
    let params = BuildParams { method: Method::Moa, leaf: LeafRule::Objects(8), ..BuildParams::paper() };
    w.bulk_load(&common::grid_scene(400), &params, &|_| {}).unwrap();
    w.commit().unwrap();
    let blocks = |db: &Database| db.begin_read().unwrap().info().unwrap().file_blocks;
    let start = blocks(&db);
    let holder = spawn("holder", &path);
    started(&path, &["holder"]);
    let mut written = 0;
    for i in 0..20u64 {
        let mut w = db.begin_write().unwrap();
        let by = if i % 2 == 0 { 5.0 } else { -5.0 };
        w.move_by(&mktree::scene::Key::Int(7), mktree::geom::Vector::new(by, 0.0, 0.0)).unwrap();
        written = written.max(w.commit_with_stats().unwrap().blocks_written);
    }
    let grown = blocks(&db);
    // The holder's state keeps what the first commit freed, and a block
    // freed later is reused once no state between its writing and its
    // freeing is held: the file grows by a few commits' blocks, not by
    // twenty (each commit writes at most `written`).
    assert!(
        u64::from(grown) <= u64::from(start) + 3 * written,
        "{start} -> {grown} blocks under a reader, {written} written per commit"
    );
    assert!(written > 0 && grown < start + 20 * written as u32, "{start} -> {grown}, {written} a commit");
    let c = db.compact().unwrap();
    assert!(c.held_by_reader.is_some() && c.blocks_after <= c.blocks_before, "{c:?}");
    std::fs::write(path.with_extension("stop"), b"").unwrap();
    let out = holder.wait_with_output().unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success() && text.contains("reads=400"), "{text}");
    assert!(mktree::db::check(&db).unwrap().ok());
}
