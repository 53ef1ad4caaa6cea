//! Claim: a change commit writes what its changes touch, not the tree
//! (format-spec/commit.md, "Change commits"). One insert, move or removal
//! in a tree of thousands of objects writes at most 2 x (the node blocks of
//! its path) + 8 blocks besides the commit slots; the first change of a
//! transaction reads at most its path, the key index's and 2 blocks more;
//! the file does not grow with the number of commits; and after each commit
//! `check` passes and box queries answer as brute force does.

mod common;

use std::collections::BTreeMap;
use std::sync::Arc;

use common::box_mesh;
use mktree::bulk::BuildParams;
use mktree::db::{CreateOptions, Database, Reads, check};
use mktree::geom::Aabb;
use mktree::query::{Region, brute_force_region};
use mktree::scene::generate::{GenOptions, Preset, generate_scene};
use mktree::scene::{Key, Object, Scene};
use mktree::store::BlockDevice;
use mktree::store::device::{CountingDevice, MemDevice};

type Model = BTreeMap<Key, Object>;

/// tanker2 (3,900 objects) in 16 KiB blocks on a counting device.
fn tanker2() -> (Database, Arc<CountingDevice<MemDevice>>, Model) {
    let scene = generate_scene(&GenOptions { preset: Preset::Tanker2, objects: None, seed: 0 }).unwrap();
    let dev = Arc::new(CountingDevice::new(MemDevice::new()));
    let db = Database::create_on(dev.clone() as Arc<dyn BlockDevice>, CreateOptions::default()).unwrap();
    let mut w = db.begin_write().unwrap();
    w.bulk_load(&scene, &BuildParams::default(), &|_| {}).unwrap();
    w.commit().unwrap();
    let model = scene.objects().iter().enumerate().map(|(i, o)| (Key::Int(i as u64), o.clone())).collect();
    (db, dev, model)
}

/// The node blocks on the path to `key`'s leaf, read cold.
fn path_blocks(db: &Database, key: &Key) -> u64 {
    let r = db.begin_read().unwrap();
    let mut reads = Reads::new(None);
    r.mesh_with(key, &mut reads).unwrap().expect("the key is in the tree");
    reads.stats.node
}

/// `check` finds no fault and box queries give what brute force over `model` gives.
fn agrees(db: &Database, model: &Model) {
    let report = check(db).unwrap();
    assert!(report.faults.is_empty(), "{:?}", report.faults);
    assert_eq!(report.objects as usize, model.len());
    let keys: Vec<&Key> = model.keys().collect();
    let scene = Scene::new(model.values().cloned().collect());
    let r = db.begin_read().unwrap();
    let world = scene.aabb();
    for i in 0..8 {
        let t = f64::from(i) / 8.0;
        let lo = world.min + world.extent() * t * 0.9;
        let q = Aabb::new(lo, lo + world.extent() * 0.15);
        let mut want: Vec<Key> =
            brute_force_region(&scene, &Region::Box(q)).iter().map(|id| keys[id.index()].clone()).collect();
        want.sort();
        let mut got = r.query_box(&q).unwrap().keys;
        got.sort();
        assert_eq!(got, want, "query {q:?}");
    }
}

fn shifted(o: &Object, d: [f64; 3]) -> Object {
    let b = o.aabb();
    let lo = [b.min.x + d[0], b.min.y + d[1], b.min.z + d[2]];
    let hi = [b.max.x + d[0], b.max.y + d[1], b.max.z + d[2]];
    Object::new(o.name.clone(), box_mesh(lo, hi))
}

#[test]
fn one_insert_move_or_removal_writes_its_paths_not_the_tree() {
    let (db, dev, mut model) = tanker2();
    let key = Key::Int(1234);
    let depth = path_blocks(&db, &key);
    assert!(depth >= 2, "the path crosses {depth} node blocks");
    let bound = 2 * depth + 8;
    let keys_height = u64::from(db.begin_read().unwrap().key_index_height());

    // A move of one object by a few millimetres.
    let before = dev.counts();
    let mut w = db.begin_write().unwrap();
    let moved = shifted(&model[&key], [5.0, -3.0, 2.0]);
    let reads_before = dev.counts().reads;
    w.update(moved.clone().with_key(key.clone())).unwrap();
    let first_change_reads = dev.counts().reads - reads_before;
    let stats = w.commit_with_stats().unwrap();
    assert!(stats.in_place, "{stats:?}");
    // Four writes are the commit slots' copies (pending, then committed).
    let writes = dev.counts().writes - before.writes - 4;
    assert!(writes <= bound, "a move wrote {writes} blocks, the bound is {bound} ({stats:?})");
    assert!(
        first_change_reads <= depth + keys_height + 2,
        "the first change read {first_change_reads} blocks: path {depth}, key index {keys_height}"
    );
    model.insert(key.clone(), moved);
    agrees(&db, &model);

    // A removal.
    let gone = Key::Int(77);
    let before = dev.counts();
    let mut w = db.begin_write().unwrap();
    assert!(w.remove(&gone).unwrap().is_some());
    let stats = w.commit_with_stats().unwrap();
    assert!(stats.in_place, "{stats:?}");
    let writes = dev.counts().writes - before.writes - 4;
    assert!(
        writes <= 2 * path_blocks(&db, &key).max(depth) + 8,
        "a removal wrote {writes} blocks ({stats:?})"
    );
    model.remove(&gone);
    agrees(&db, &model);

    // An insert of a new object beside an existing one.
    let new = shifted(&model[&Key::Int(500)], [1.0, 1.0, 1.0]);
    let before = dev.counts();
    let mut w = db.begin_write().unwrap();
    let k = w.insert(new.clone().with_key(Key::bytes("new").unwrap())).unwrap();
    let stats = w.commit_with_stats().unwrap();
    assert!(stats.in_place, "{stats:?}");
    let writes = dev.counts().writes - before.writes - 4;
    assert!(writes <= bound + 2, "an insert wrote {writes} blocks ({stats:?})");
    model.insert(k, new);
    agrees(&db, &model);
}

#[test]
fn a_box_that_grows_past_the_scene_rewrites_paths_only() {
    let (db, _, mut model) = tanker2();
    let world = Scene::new(model.values().cloned().collect()).aabb();
    let key = Key::Int(10);
    // Far outside the scene box: every box on the path grows, the root's too.
    let far = shifted(&model[&key], [world.extent().x * 2.0, 0.0, 0.0]);
    let mut w = db.begin_write().unwrap();
    w.update(far.clone().with_key(key.clone())).unwrap();
    let stats = w.commit_with_stats().unwrap();
    assert!(stats.in_place, "{stats:?}");
    assert!(stats.blocks_written < 40, "{stats:?}");
    model.insert(key, far);
    agrees(&db, &model);
    let scene_box = db.begin_read().unwrap().info().unwrap().scene_box;
    assert!(scene_box[3] > world.max.x + world.extent().x, "the scene box grew: {scene_box:?}");
}

#[test]
fn the_file_does_not_grow_with_the_number_of_commits() {
    let (db, _, model) = tanker2();
    let key = Key::Int(2000);
    let blocks = |db: &Database| db.begin_read().unwrap().info().unwrap().file_blocks;
    let mut sizes = Vec::new();
    for i in 0..40 {
        let mut w = db.begin_write().unwrap();
        let d = if i % 2 == 0 { 4.0 } else { 0.0 };
        w.update(shifted(&model[&key], [d, 0.0, 0.0]).with_key(key.clone())).unwrap();
        assert!(w.commit_with_stats().unwrap().in_place);
        sizes.push(blocks(&db));
    }
    // Freed blocks are reused once no reader can reach them.
    let (first, last) = (sizes[2], sizes[39]);
    assert!(last <= first + 8, "the file grew from {first} to {last} blocks: {sizes:?}");
    agrees(&db, &{
        let mut m = model.clone();
        m.insert(key.clone(), shifted(&model[&key], [0.0, 0.0, 0.0]));
        m
    });
}

#[test]
fn a_change_that_empties_a_leaf_writes_the_tree_whole() {
    let objects: Vec<Object> = (0..12)
        .map(|i| {
            Object::new(
                format!("o{i}"),
                box_mesh([f64::from(i) * 100.0, 0.0, 0.0], [f64::from(i) * 100.0 + 50.0, 50.0, 50.0]),
            )
        })
        .collect();
    let scene = Scene::new(objects.clone());
    let params = BuildParams { leaf: mktree::bulk::LeafRule::Objects(2), ..BuildParams::paper() };
    let db = Database::create_on(
        Arc::new(MemDevice::new()),
        CreateOptions { block_size: 4096, ..Default::default() },
    )
    .unwrap();
    let mut w = db.begin_write().unwrap();
    w.bulk_load(&scene, &params, &|_| {}).unwrap();
    w.commit().unwrap();
    let mut model: Model = objects.into_iter().enumerate().map(|(i, o)| (Key::Int(i as u64), o)).collect();
    // Every object gone from one end: some leaf loses all it held.
    let mut w = db.begin_write().unwrap();
    for i in 0..4u64 {
        w.remove(&Key::Int(i)).unwrap();
        model.remove(&Key::Int(i));
    }
    let stats = w.commit_with_stats().unwrap();
    assert!(!stats.in_place, "{stats:?}");
    agrees(&db, &model);
}
