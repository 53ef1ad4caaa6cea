//! Claim: a recorded clash test marks its clashes New, Active and Resolved
//! across three revisions of a file, by keys and type; Approved, set by a
//! person, persists while the clash does; the statuses survive the store's
//! file; re-runs after change commits are incremental and equal full runs.

mod common;

use common::box_mesh;
use mktree::clash::{
    ClashKind, ClashStore, ClashTest, RunMode, Status, StoreLock, TestKind, run_recorded, run_test,
    set_status, store_path,
};
use mktree::geom::Vector;
use mktree::scene::{Key, Object, Scene};
use mktree::{BuildParams, CreateOptions, Database};

fn key(s: &str) -> Key {
    Key::bytes(s).unwrap()
}

fn obj(name: &str, lo: [f64; 3], hi: [f64; 3]) -> Object {
    Object::new(name, box_mesh(lo, hi)).with_key(key(name))
}

fn status_of(store: &ClashStore, a: &str) -> Vec<(ClashKind, Status)> {
    store.runs["pipes"]
        .tracked
        .iter()
        .filter(|t| t.clash.a == key(a))
        .map(|t| (t.clash.kind, t.status))
        .collect()
}

#[test]
fn three_revisions_new_active_resolved_and_a_persisting_approval() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("m.mkt");
    let db = Database::create(&file, CreateOptions::default()).unwrap();
    let mut w = db.begin_write().unwrap();
    let scene = Scene::new(vec![
        obj("WALL", [0.0, 0.0, 0.0], [200.0, 5000.0, 3000.0]),
        obj("PIPE-1", [-500.0, 1000.0, 1000.0], [700.0, 1120.0, 1120.0]), // hard
        obj("PIPE-3", [230.0, 3000.0, 1000.0], [900.0, 3100.0, 1100.0]),  // clearance 30
        obj("PIPE-5", [50.0, 4500.0, 100.0], [150.0, 4600.0, 200.0]),     // hard, inside
        obj("FAR", [9000.0, 0.0, 0.0], [9100.0, 100.0, 100.0]),
    ]);
    w.bulk_load(&scene, &BuildParams::default(), &|_| {}).unwrap();
    w.commit().unwrap();
    let test = ClashTest {
        a: vec!["name:PIPE*".parse().unwrap()],
        b: Some(vec!["name:WALL".parse().unwrap()]),
        kind: TestKind::Clearance,
        distance: 50.0,
        ..Default::default()
    };
    let path = store_path(&file);

    // Revision 1: everything is New.
    let lock = StoreLock::acquire(&path).unwrap();
    let mut store = lock.load().unwrap();
    let rec = run_recorded(&db.begin_read().unwrap(), &mut store, "pipes", Some(&test), true).unwrap();
    assert!(matches!(rec.mode, RunMode::Full { .. }), "no recorded run yet");
    assert_eq!(status_of(&store, "PIPE-1"), vec![(ClashKind::Hard, Status::New)]);
    assert_eq!(status_of(&store, "PIPE-3"), vec![(ClashKind::Clearance, Status::New)]);
    let runs = store.runs.get_mut("pipes").unwrap();
    assert_eq!(set_status(&mut runs.tracked, &key("WALL"), &key("PIPE-3"), None, Status::Approved), 1);
    lock.save(&store).unwrap();
    drop(lock);

    // Revision 2: PIPE-1 moved clear, PIPE-7 added through the wall.
    let mut w = db.begin_write().unwrap();
    w.move_by(&key("PIPE-1"), Vector::new(0.0, 0.0, 5000.0)).unwrap();
    w.insert(obj("PIPE-7", [-100.0, 2500.0, 500.0], [300.0, 2600.0, 600.0])).unwrap();
    w.commit().unwrap();
    let lock = StoreLock::acquire(&path).unwrap();
    let mut store = lock.load().unwrap();
    let r = db.begin_read().unwrap();
    let rec = run_recorded(&r, &mut store, "pipes", None, true).unwrap();
    assert!(matches!(rec.mode, RunMode::Incremental { changed: 2, removed: 0, .. }), "{:?}", rec.mode);
    let clashes: Vec<_> = store.runs["pipes"].clashes().cloned().collect();
    assert_eq!(clashes, run_test(&r, &test).unwrap().clashes, "incremental equals full");
    assert_eq!(status_of(&store, "PIPE-1"), vec![(ClashKind::Hard, Status::Resolved)]);
    assert_eq!(status_of(&store, "PIPE-3"), vec![(ClashKind::Clearance, Status::Approved)]);
    assert_eq!(status_of(&store, "PIPE-5"), vec![(ClashKind::Hard, Status::Active)]);
    assert_eq!(status_of(&store, "PIPE-7"), vec![(ClashKind::Hard, Status::New)]);
    lock.save(&store).unwrap();
    drop(lock);

    // Revision 3: PIPE-3 removed (its approval ends with it), PIPE-1 back.
    let mut w = db.begin_write().unwrap();
    w.remove(&key("PIPE-3")).unwrap();
    w.move_by(&key("PIPE-1"), Vector::new(0.0, 0.0, -5000.0)).unwrap();
    w.commit().unwrap();
    let lock = StoreLock::acquire(&path).unwrap();
    let mut store = lock.load().unwrap();
    let r = db.begin_read().unwrap();
    let rec = run_recorded(&r, &mut store, "pipes", None, true).unwrap();
    assert!(matches!(rec.mode, RunMode::Incremental { changed: 1, removed: 1, .. }), "{:?}", rec.mode);
    let clashes: Vec<_> = store.runs["pipes"].clashes().cloned().collect();
    assert_eq!(clashes, run_test(&r, &test).unwrap().clashes);
    assert_eq!(status_of(&store, "PIPE-3"), vec![(ClashKind::Clearance, Status::Resolved)]);
    assert_eq!(status_of(&store, "PIPE-1"), vec![(ClashKind::Hard, Status::New)], "back after resolved: New");
    assert_eq!(status_of(&store, "PIPE-5"), vec![(ClashKind::Hard, Status::Active)]);
    assert_eq!(status_of(&store, "PIPE-7"), vec![(ClashKind::Hard, Status::Active)]);
    let first = store.runs["pipes"].tracked.iter().find(|t| t.clash.a == key("PIPE-5")).unwrap();
    assert!(first.first_txn < first.last_txn);
    lock.save(&store).unwrap();
    drop(lock);
    assert_eq!(ClashStore::load(&path).unwrap(), store);

    // A bulk load numbers objects anew: the next run is a full one.
    let mut w = db.begin_write().unwrap();
    w.bulk_load(&scene, &BuildParams::default(), &|_| {}).unwrap();
    w.commit().unwrap();
    let rec = run_recorded(&db.begin_read().unwrap(), &mut store, "pipes", None, true).unwrap();
    assert!(matches!(rec.mode, RunMode::Full { .. }), "{:?}", rec.mode);
}
