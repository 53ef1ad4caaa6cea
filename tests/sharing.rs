//! Claim: several openers share one file as format-spec/commit.md's "Many
//! processes" says. Each `Database::open` is a separate owner of the file's
//! locks, as another process would be (multi-process runs are in
//! `tests/processes.rs`): readers never wait and never fail, writers exclude
//! each other, a read-only open works on a read-only file and never writes.

mod common;

use mktree::bulk::BuildParams;
use mktree::db::{CreateOptions, Database, WriterWait, check};
use mktree::store::StorageError;

fn load(db: &Database, objects: usize) {
    let mut w = db.begin_write().unwrap();
    w.bulk_load(&common::grid_scene(objects), &BuildParams::paper(), &|_| {}).unwrap();
    w.commit().unwrap();
}

#[test]
fn writers_exclude_each_other_and_readers_never_wait() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("t.mkt");
    let a = Database::create(&path, CreateOptions::default()).unwrap();
    load(&a, 30);
    let b = Database::open(&path).unwrap();
    let w = a.begin_write().unwrap();
    assert!(matches!(b.begin_write(), Err(StorageError::Locked)), "a second writer is refused");
    let r = b.begin_read().unwrap();
    assert_eq!(r.info().unwrap().objects, 30, "a reader works while a writer writes");
    drop(w);
    let w = b.begin_write_with(WriterWait::Wait).unwrap();
    drop(w);
    assert!(Database::create(&path, CreateOptions::default()).is_err(), "create never overwrites a file");
}

#[test]
fn a_reader_keeps_its_snapshot_through_commits_of_another_opener() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("t.mkt");
    let a = Database::create(&path, CreateOptions::default()).unwrap();
    load(&a, 30);
    let b = Database::open_read_only(&path).unwrap();
    let old = b.begin_read().unwrap();
    let everything = common::grid_scene(60).aabb();
    let before = old.query_box(&everything).unwrap().objects;
    // Enough commits that the old tree's blocks would be reused if nothing pinned them.
    for n in [40, 50, 60, 45] {
        load(&a, n);
    }
    assert_eq!(old.query_box(&everything).unwrap().objects, before, "the old snapshot still reads");
    assert_eq!(b.begin_read().unwrap().info().unwrap().objects, 45, "a new reader sees the newest commit");
    drop(old);
    load(&a, 35);
    assert!(check(&a).unwrap().ok());
}

#[test]
fn a_read_only_file_opens_and_is_never_written() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("t.mkt");
    load(&Database::create(&path, CreateOptions::default()).unwrap(), 30);
    let bytes = std::fs::read(&path).unwrap();
    let mut perms = std::fs::metadata(&path).unwrap().permissions();
    perms.set_readonly(true);
    std::fs::set_permissions(&path, perms).unwrap();
    let db = Database::open_read_only(&path).unwrap();
    assert_eq!(db.begin_read().unwrap().info().unwrap().objects, 30);
    assert!(check(&db).unwrap().ok());
    assert!(matches!(db.begin_write(), Err(StorageError::ReadOnly)));
    assert_eq!(std::fs::read(&path).unwrap(), bytes);
}

#[test]
fn a_write_transaction_moves_to_another_thread_and_a_second_writer_waits_for_it() {
    fn send<T: Send>(_: &T) {}
    let dir = tempfile::tempdir().unwrap();
    let db = Database::create(dir.path().join("t.mkt"), CreateOptions::default()).unwrap();
    let w = db.begin_write().unwrap();
    send(&w);
    std::thread::scope(|s| {
        // A second writer of this process waits for the first, wherever it runs.
        let second = s.spawn(|| {
            let mut w = db.begin_write().unwrap();
            w.bulk_load(&common::grid_scene(20), &BuildParams::paper(), &|_| {}).unwrap();
            w.commit().unwrap();
        });
        s.spawn(move || {
            let mut w = w;
            w.bulk_load(&common::grid_scene(10), &BuildParams::paper(), &|_| {}).unwrap();
            w.commit().unwrap();
        })
        .join()
        .unwrap();
        second.join().unwrap();
    });
    assert_eq!(db.begin_read().unwrap().info().unwrap().objects, 20, "the second writer committed last");
    assert!(check(&db).unwrap().ok());
}

#[test]
fn an_open_that_fails_names_the_file_and_why() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("missing.mkt");
    for err in [Database::open(&missing).err(), Database::open_read_only(&missing).err()] {
        let text = err.expect("a missing file does not open").to_string();
        assert!(text.contains("missing.mkt") && text.contains("No such file"), "{text}");
    }
    let path = dir.path().join("t.mkt");
    Database::create(&path, CreateOptions::default()).unwrap();
    let text = Database::create(&path, CreateOptions::default()).err().unwrap().to_string();
    assert!(text.contains("t.mkt") && text.contains("exists"), "{text}");
}

/// Issue 39: `check` is a reader. Run over and over by one opener while
/// another commits, it never makes a writer fail (before, it held the
/// writer's lock shared and writers failed with "locked"), and it finds no
/// fault in the free blocks the writer fills meanwhile.
#[test]
fn check_beside_a_writer_never_blocks_it_and_passes() {
    use std::sync::atomic::{AtomicBool, Ordering};
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("t.mkt");
    let a = Database::create(&path, CreateOptions::default()).unwrap();
    load(&a, 200);
    let checker = Database::open_read_only(&path).unwrap();
    let done = AtomicBool::new(false);
    std::thread::scope(|s| {
        let checks = s.spawn(|| {
            let mut runs = 0;
            while !done.load(Ordering::Relaxed) {
                let report = check(&checker).unwrap();
                assert!(report.ok(), "check beside a writer: {:?}", report.faults);
                runs += 1;
            }
            runs
        });
        for id in 0..40u64 {
            let mut w = a.begin_write().expect("a writer is never refused because of a check");
            assert!(w.remove(&mktree::scene::Key::Int(id)).unwrap().is_some());
            w.commit().unwrap();
        }
        let compacted = a.compact().expect("compact is never refused because of a check");
        assert!(compacted.blocks_after <= compacted.blocks_before);
        done.store(true, Ordering::Relaxed);
        let runs = checks.join().unwrap();
        assert!(runs > 0);
        println!("{runs} checks ran beside 40 commits and a compaction");
    });
    assert!(check(&a).unwrap().ok());
    assert_eq!(a.begin_read().unwrap().info().unwrap().objects, 160);
}

/// Issue 39: a refused writer is told who holds the lock, and how to wait.
#[test]
fn a_refused_writer_is_told_a_writer_holds_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("t.mkt");
    let a = Database::create(&path, CreateOptions::default()).unwrap();
    load(&a, 10);
    let b = Database::open(&path).unwrap();
    let _r = b.begin_read().unwrap();
    let w = a.begin_write().unwrap();
    let e = b.compact().unwrap_err().to_string();
    assert!(e.contains("another process is writing the file") && e.contains("--wait"), "{e}");
    drop(w);
    assert!(b.compact_with(WriterWait::Wait).is_ok());
}
