//! Claim: every change commit records in its meta block which keys it
//! inserted, updated or removed (format-spec/meta.md, "The change log"),
//! so a reader learns every key changed since any commit the log reaches
//! back to; the log keeps the latest commits that fit the block, a bulk
//! load starts it anew, and compaction and `optimize` continue it.

mod common;

use std::sync::Arc;

use common::{box_mesh, load_on};
use mktree::geom::Vector;
use mktree::scene::{Key, Object, Scene};
use mktree::store::device::MemDevice;
use mktree::{BuildParams, ChangeKind, CreateOptions, Database};

fn cube(k: u64, x: f64) -> Object {
    Object::new(format!("c{k}"), box_mesh([x, 0.0, 0.0], [x + 10.0, 10.0, 10.0])).with_key(Key::Int(k))
}

fn scene(n: u64) -> Scene {
    Scene::new((0..n).map(|k| cube(k, k as f64 * 20.0)).collect())
}

/// (commit, kind, key) of every change after `txn`, or `None`.
fn since(db: &Database, txn: u64) -> Option<Vec<(u64, ChangeKind, Key)>> {
    let r = db.begin_read().unwrap();
    r.changes_since(txn).unwrap().map(|c| c.into_iter().map(|c| (c.txn, c.kind, c.key)).collect())
}

#[test]
fn a_reader_learns_what_each_commit_since_a_state_changed() {
    let db =
        load_on(Arc::new(MemDevice::new()), &scene(10), &BuildParams::default(), CreateOptions::default());
    let loaded = db.begin_read().unwrap().txn();
    assert_eq!(since(&db, loaded), Some(vec![]));
    assert_eq!(since(&db, loaded - 1), None, "the bulk load itself is not a change of keys");

    let mut w = db.begin_write().unwrap();
    w.insert(cube(20, 500.0)).unwrap();
    assert!(w.move_by(&Key::Int(3), Vector::new(1.0, 0.0, 0.0)).unwrap());
    w.remove(&Key::Int(5)).unwrap();
    // Inserted and removed in one transaction: the committed state never had it.
    w.insert(cube(21, 600.0)).unwrap();
    w.remove(&Key::Int(21)).unwrap();
    w.commit().unwrap();
    let first = loaded + 1;
    let mut w = db.begin_write().unwrap();
    w.update(cube(20, 700.0)).unwrap();
    w.commit().unwrap();

    use ChangeKind::*;
    let all = since(&db, loaded).unwrap();
    assert_eq!(
        all,
        [
            (first, Updated, Key::Int(3)),
            (first, Removed, Key::Int(5)),
            (first, Inserted, Key::Int(20)),
            (first + 1, Updated, Key::Int(20)),
        ]
    );
    assert_eq!(since(&db, first).unwrap(), all[3..]);
    assert_eq!(since(&db, first + 1).unwrap(), []);
    assert_eq!(since(&db, first + 2), None, "a commit after the snapshot's");
}

#[test]
fn the_log_keeps_the_latest_commits_that_fit_and_a_bulk_load_restarts_it() {
    // 1 KiB blocks: a meta block's log holds a few single-key records.
    let options = CreateOptions { block_size: 1024, ..Default::default() };
    let db = load_on(Arc::new(MemDevice::new()), &scene(30), &BuildParams::default(), options);
    let loaded = db.begin_read().unwrap().txn();
    for k in 0..12 {
        let mut w = db.begin_write().unwrap();
        assert!(w.move_by(&Key::Int(k), Vector::new(1.0, 0.0, 0.0)).unwrap());
        w.commit().unwrap();
    }
    let last = db.begin_read().unwrap().txn();
    let reach = (loaded..=last).find(|&t| since(&db, t).is_some()).unwrap();
    assert!(reach > loaded, "twelve commits do not fit a 1 KiB block's log");
    let listed = since(&db, reach).unwrap();
    assert!(!listed.is_empty());
    let keys: Vec<Key> = listed.iter().map(|c| c.2.clone()).collect();
    let want: Vec<Key> = (12 - (last - reach)..12).map(Key::Int).collect();
    assert_eq!(keys, want, "one record per commit after {reach}, the latest");

    let mut w = db.begin_write().unwrap();
    w.bulk_load(&scene(5), &BuildParams::default(), &|_| {}).unwrap();
    w.commit().unwrap();
    let reloaded = db.begin_read().unwrap().txn();
    assert_eq!(since(&db, reloaded - 1), None);
    assert_eq!(since(&db, reloaded), Some(vec![]));
}

#[test]
fn compaction_and_optimize_continue_the_log() {
    let db =
        load_on(Arc::new(MemDevice::new()), &scene(40), &BuildParams::default(), CreateOptions::default());
    let loaded = db.begin_read().unwrap().txn();
    let mut w = db.begin_write().unwrap();
    w.remove(&Key::Int(7)).unwrap();
    w.commit().unwrap();
    db.compact().unwrap();
    let mut w = db.begin_write().unwrap();
    assert!(w.move_by(&Key::Int(8), Vector::new(0.0, 5.0, 0.0)).unwrap());
    w.optimize().unwrap();
    w.commit().unwrap();
    let keys: Vec<(ChangeKind, Key)> = since(&db, loaded).unwrap().into_iter().map(|c| (c.1, c.2)).collect();
    assert_eq!(keys, [(ChangeKind::Removed, Key::Int(7)), (ChangeKind::Updated, Key::Int(8))]);
    assert!(mktree::check(&db).unwrap().ok());
}
