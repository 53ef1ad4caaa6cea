//! Claim: a crash at any write or sync of a commit, with the unsynced writes
//! dropped, kept, torn or mixed, reopens at the previous committed tree or at
//! the new one, never a mix, and `check` passes after reopening.

mod common;

use std::sync::Arc;

use common::grid_scene;
use mktree::bulk::{BuildParams, LeafRule, Method};
use mktree::db::{CreateOptions, Database, Warning, check};
use mktree::geom::Aabb;
use mktree::scene::Scene;
use mktree::store::BlockDevice;
use mktree::store::device::{CrashDevice, CrashImage, MemDevice};

fn load(db: &Database, scene: &Scene, method: Method) -> Result<(), mktree::Error> {
    let mut w = db.begin_write()?;
    w.bulk_load(scene, &BuildParams { method, leaf: LeafRule::Objects(6), ..BuildParams::paper() }, &|_| {})?;
    w.commit()?;
    Ok(())
}

/// The answer of a query covering everything, as a fingerprint of the tree.
fn fingerprint(db: &Database) -> Option<(u32, Vec<u32>)> {
    let r = db.begin_read().unwrap();
    let info = r.info()?;
    let q = r.query_box(&Aabb::from_array([0.0, 0.0, 0.0, 450.0, 450.0, 450.0])).unwrap();
    Some((info.objects, q.objects.iter().map(|o| o.0).collect()))
}

#[test]
fn a_crash_anywhere_in_a_commit_reopens_at_one_side_of_it() {
    let old_scene = grid_scene(120);
    let new_scene = grid_scene(150);
    // A committed old tree, as a durable image.
    let base = Arc::new(MemDevice::new());
    let db = Database::create_on(
        base.clone() as Arc<dyn BlockDevice>,
        CreateOptions { block_size: 1024, lod_levels: 2 },
    )
    .unwrap();
    load(&db, &old_scene, Method::Moa).unwrap();
    let old = fingerprint(&db);
    drop(db);
    let image = base.to_bytes();
    // The new tree, committed without a crash, for its fingerprint and event count.
    let clean = Arc::new(CrashDevice::new(image.clone(), u64::MAX));
    let db = Database::open_on(clean.clone() as Arc<dyn BlockDevice>).unwrap();
    let before = clean.events();
    load(&db, &new_scene, Method::Median).unwrap();
    let new = fingerprint(&db);
    let events = clean.events() - before;
    assert_ne!(old, new);
    let outcomes = common::crash::every_crash_reopens_at_one_side(
        &image,
        events,
        |db: &Database| load(db, &new_scene, Method::Median).is_ok(),
        fingerprint,
        &old,
        &new,
    );
    assert!(outcomes[0] > 0 && outcomes[1] > 0, "both outcomes occur: {outcomes:?}");
}

#[test]
fn an_aborted_transaction_leaves_the_file_as_it_was() {
    let dev = Arc::new(MemDevice::new());
    let db = Database::create_on(
        dev.clone() as Arc<dyn BlockDevice>,
        CreateOptions { block_size: 1024, lod_levels: 1 },
    )
    .unwrap();
    load(&db, &grid_scene(50), Method::Moa).unwrap();
    let before = fingerprint(&db);
    let mut w = db.begin_write().unwrap();
    // Leaves that fit a 1 KiB node block: a version 3 leaf record holds 20 bytes per object.
    let params = BuildParams { leaf: LeafRule::Objects(6), ..BuildParams::paper() };
    w.bulk_load(&grid_scene(90), &params, &|_| {}).unwrap();
    w.abort().unwrap();
    assert_eq!(fingerprint(&db), before);
    drop(db);
    let db = Database::open_on(dev as Arc<dyn BlockDevice>).unwrap();
    assert!(db.warnings().is_empty(), "an abort clears its pending slot: {:?}", db.warnings());
    assert_eq!(fingerprint(&db), before);
    assert!(check(&db).unwrap().ok());
}

#[test]
fn a_reader_keeps_its_snapshot_while_a_writer_replaces_the_tree_twice() {
    let dev = Arc::new(MemDevice::new());
    let db =
        Database::create_on(dev as Arc<dyn BlockDevice>, CreateOptions { block_size: 1024, lod_levels: 1 })
            .unwrap();
    load(&db, &grid_scene(60), Method::Moa).unwrap();
    let reader = db.begin_read().unwrap();
    let q = Aabb::from_array([0.0, 0.0, 0.0, 1e4, 1e4, 1e4]);
    let seen = reader.query_box(&q).unwrap().objects;
    load(&db, &grid_scene(70), Method::Sah).unwrap();
    load(&db, &grid_scene(80), Method::Hilbert).unwrap();
    assert_eq!(reader.query_box(&q).unwrap().objects, seen, "the old tree's blocks were not reused");
    assert_eq!(db.begin_read().unwrap().query_box(&q).unwrap().objects.len(), 80);
    drop(reader);
    load(&db, &grid_scene(90), Method::Median).unwrap();
    assert!(check(&db).unwrap().ok());
}

#[test]
fn readers_leave_a_crashed_file_alone_and_the_next_writer_cleans_up() {
    let base = Arc::new(MemDevice::new());
    let db = Database::create_on(
        base.clone() as Arc<dyn BlockDevice>,
        CreateOptions { block_size: 1024, lod_levels: 2 },
    )
    .unwrap();
    load(&db, &grid_scene(120), Method::Moa).unwrap();
    let old = fingerprint(&db);
    drop(db);
    // A crash halfway through the next commit, every write kept: appended
    // blocks past the committed end and a pending slot.
    let clean = Arc::new(CrashDevice::new(base.to_bytes(), u64::MAX));
    let db = Database::open_on(clean.clone() as Arc<dyn BlockDevice>).unwrap();
    let before = clean.events();
    load(&db, &grid_scene(150), Method::Median).unwrap();
    let events = clean.events() - before;
    let dev = Arc::new(CrashDevice::new(base.to_bytes(), events / 2));
    let db = Database::open_on(dev.clone() as Arc<dyn BlockDevice>).unwrap();
    assert!(load(&db, &grid_scene(150), Method::Median).is_err());
    drop(db);
    let crashed = dev.image(CrashImage::KeepAll);
    let after = Arc::new(MemDevice::from_bytes(crashed.clone()));
    let db = Database::open_on(after.clone() as Arc<dyn BlockDevice>).unwrap();
    assert_eq!(db.warnings(), &[Warning::Interrupted]);
    assert_eq!(fingerprint(&db), old);
    let report = check(&db).unwrap();
    assert!(report.ok() && report.interrupted, "{:?}", report.faults);
    assert!(after.to_bytes() == crashed, "opening, reading and checking wrote nothing");
    let w = db.begin_write().unwrap();
    let r = w.recovery();
    assert!(r.interrupted && r.truncated_blocks > 0, "{r:?}");
    w.abort().unwrap();
    drop(db);
    let db = Database::open_on(after as Arc<dyn BlockDevice>).unwrap();
    assert!(db.warnings().is_empty(), "{:?}", db.warnings());
    assert_eq!(fingerprint(&db), old);
    let report = check(&db).unwrap();
    assert!(report.ok() && !report.interrupted);
}
