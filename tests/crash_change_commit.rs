//! Claim: a crash at any write or sync of a change commit written in place
//! (copy on write, sharing blocks with the committed tree), with the
//! unsynced writes dropped, kept, torn or mixed, reopens at the committed
//! tree or at the new one, never a mix, and `check` passes after reopening:
//! for a commit of a move, a removal and an insert, for one that splits a
//! leaf, and for ones that merge a leaf with a leaf or a subtree; synced twice (1 KiB blocks, whose
//! meta block cannot list what the first two write) and once.

mod common;

use std::sync::Arc;

use common::{box_mesh, grid_scene};
use mktree::bulk::{BuildParams, LeafRule, Method};
use mktree::db::{ChangeStats, CreateOptions, Database};
use mktree::geom::Aabb;
use mktree::scene::{Key, Object};
use mktree::store::BlockDevice;
use mktree::store::device::{CrashDevice, MemDevice};

/// One move, one removal and one insert in one transaction.
fn change(db: &Database) -> Result<ChangeStats, mktree::Error> {
    let mut w = db.begin_write()?;
    let moved = Object::new("moved", box_mesh([3.0, 5.0, 7.0], [13.0, 15.0, 17.0])).with_key(4u64);
    w.update(moved)?;
    w.remove(&Key::Int(40))?;
    w.insert(Object::new("new", box_mesh([100.0, 100.0, 100.0], [104.0, 104.0, 104.0])).with_key(1_000u64))?;
    w.commit_with_stats()
}

/// Every object's key and the box a query over everything finds.
fn fingerprint(db: &Database) -> Option<Vec<Key>> {
    let r = db.begin_read().unwrap();
    r.info()?;
    let mut keys = r.query_box(&Aabb::from_array([-1e4, -1e4, -1e4, 1e4, 1e4, 1e4])).unwrap().keys;
    keys.sort();
    Some(keys)
}

/// Fourteen small objects inserted around one place: their leaf splits.
fn split(db: &Database) -> Result<ChangeStats, mktree::Error> {
    let mut w = db.begin_write()?;
    for i in 0..14u64 {
        let x = 3.0 + i as f64 * 0.5;
        w.insert(Object::new("s", box_mesh([x, 5.0, 7.0], [x + 0.3, 5.3, 7.3])).with_key(2_000 + i))?;
    }
    w.commit_with_stats()
}

/// The two objects of the first leaf removed: it merges with its sibling leaf.
fn merge(db: &Database) -> Result<ChangeStats, mktree::Error> {
    let mut w = db.begin_write()?;
    w.remove(&Key::Int(0))?;
    w.remove(&Key::Int(1))?;
    w.commit_with_stats()
}

/// The lone object at the row's start removed: its leaf merges with the
/// subtree of the others beside it.
fn merge_beside_subtree(db: &Database) -> Result<ChangeStats, mktree::Error> {
    let mut w = db.begin_write()?;
    w.remove(&Key::Int(0))?;
    w.commit_with_stats()
}

/// Bulk-loads `scene` in 1 KiB blocks, then runs the crash loop over `change`.
fn crash_loop(
    scene: &mktree::scene::Scene,
    params: BuildParams,
    change: fn(&Database) -> Result<ChangeStats, mktree::Error>,
    block_size: u32,
    syncs: u64,
) -> [usize; 3] {
    let base = Arc::new(MemDevice::new());
    let db = Database::create_on(
        base.clone() as Arc<dyn BlockDevice>,
        CreateOptions { block_size, lod_levels: 2 },
    )
    .unwrap();
    let mut w = db.begin_write().unwrap();
    w.bulk_load(scene, &params, &|_| {}).unwrap();
    w.commit().unwrap();
    let old = fingerprint(&db);
    drop(db);
    let image = base.to_bytes();
    let clean = Arc::new(CrashDevice::new(image.clone(), u64::MAX));
    let db = Database::open_on(clean.clone() as Arc<dyn BlockDevice>).unwrap();
    let before = clean.events();
    let stats = change(&db).unwrap();
    assert!(stats.in_place, "the change commit goes in place: {stats:?}");
    assert_eq!(stats.syncs, syncs, "{block_size}-byte blocks: {stats:?}");
    let new = fingerprint(&db);
    let events = clean.events() - before;
    assert_ne!(old, new);
    let outcomes = common::crash::every_crash_reopens_at_one_side(
        &image,
        events,
        |db: &Database| change(db).is_ok(),
        fingerprint,
        &old,
        &new,
    );
    assert!(outcomes[0] > 0 && outcomes[1] > 0, "both outcomes occur: {outcomes:?}");
    outcomes
}

fn moa(leaf: u32) -> BuildParams {
    BuildParams { method: Method::Moa, leaf: LeafRule::Objects(leaf), rate: 0.5, ..BuildParams::paper() }
}

#[test]
fn a_crash_anywhere_in_a_change_commit_reopens_at_one_side_of_it() {
    crash_loop(&grid_scene(120), moa(6), change, 1024, 2);
    let once = crash_loop(&grid_scene(120), moa(6), change, 4096, 1);
    assert!(once[2] > 0, "a commit whose blocks were partly lost is read as unfinished: {once:?}");
}

#[test]
fn a_crash_anywhere_in_a_split_reopens_at_one_side_of_it() {
    crash_loop(&grid_scene(120), moa(6), split, 1024, 2);
    let once = crash_loop(&grid_scene(120), moa(6), split, 4096, 1);
    assert!(once[2] > 0, "a commit whose blocks were partly lost is read as unfinished: {once:?}");
}

#[test]
fn a_crash_anywhere_in_a_merge_reopens_at_one_side_of_it() {
    let row: Vec<Object> = (0..8)
        .map(|i| {
            let x = f64::from(i) * 100.0;
            Object::new(format!("o{i}"), box_mesh([x, 0.0, 0.0], [x + 50.0, 50.0, 50.0]))
        })
        .collect();
    // A merge writes few blocks: even a 1 KiB meta block lists them.
    let lone = Object::new("lone", box_mesh([-5000.0, 0.0, 0.0], [-4950.0, 50.0, 50.0]));
    let beside = std::iter::once(lone).chain(row.iter().skip(1).cloned()).collect();
    let scene = mktree::scene::Scene::new(beside);
    crash_loop(&scene, moa(1), merge_beside_subtree, 1024, 1);
    crash_loop(&mktree::scene::Scene::new(row.clone()), moa(2), merge, 1024, 1);
    crash_loop(&mktree::scene::Scene::new(row), moa(2), merge, 4096, 1);
}
