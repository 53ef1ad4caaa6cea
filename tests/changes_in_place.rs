//! Claim: a change commit writes what its changes touch, not the tree
//! (format-spec/commit.md, "Change commits"). One insert, move or removal
//! in a tree of thousands of objects writes at most 2 x (the node blocks of
//! its path) + 8 blocks besides the commit slots; the first change of a
//! transaction reads at most its path, the key index's and 2 blocks more;
//! the file does not grow with the number of commits, nor much under a
//! reader held through them; a leaf past its capacity splits and an emptied
//! one merges in place ("Splits", "Merges"), a block its records outgrow
//! moves leaves or whole subtrees out, and `optimize` lays the result
//! out as a bulk load does; and after each commit `check` passes and box
//! queries answer as brute force does.

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

/// A row of `n` boxes along x, bulk-loaded in leaves of two objects.
fn row(n: u32) -> (Database, Model) {
    let objects: Vec<Object> = (0..n)
        .map(|i| {
            Object::new(
                format!("o{i}"),
                box_mesh([f64::from(i) * 100.0, 0.0, 0.0], [f64::from(i) * 100.0 + 50.0, 50.0, 50.0]),
            )
        })
        .collect();
    let scene = Scene::new(objects.clone());
    let params = BuildParams { leaf: mktree::bulk::LeafRule::Objects(2), rate: 0.5, ..BuildParams::paper() };
    let db = Database::create_on(
        Arc::new(MemDevice::new()),
        CreateOptions { block_size: 4096, ..Default::default() },
    )
    .unwrap();
    let mut w = db.begin_write().unwrap();
    w.bulk_load(&scene, &params, &|_| {}).unwrap();
    w.commit().unwrap();
    (db, objects.into_iter().enumerate().map(|(i, o)| (Key::Int(i as u64), o)).collect())
}

#[test]
fn a_leaf_emptied_beside_a_leaf_merges_with_it_in_place() {
    // Two leaves under the root: emptying one leaves the root a leaf.
    let (db, mut model) = row(4);
    let mut w = db.begin_write().unwrap();
    for i in 0..2u64 {
        w.remove(&Key::Int(i)).unwrap();
        model.remove(&Key::Int(i));
    }
    let stats = w.commit_with_stats().unwrap();
    assert!(stats.in_place, "{stats:?}");
    let info = db.begin_read().unwrap().info().unwrap();
    assert_eq!((info.nodes, info.leaves), (1, 1));
    agrees(&db, &model);
    // The merged leaf takes changes like any other, and splits again.
    let mut w = db.begin_write().unwrap();
    for i in 10..16u64 {
        let o = shifted(&model[&Key::Int(2)], [f64::from(i as u32) * 10.0, 0.0, 0.0]);
        w.insert(o.clone().with_key(Key::Int(i))).unwrap();
        model.insert(Key::Int(i), o);
    }
    assert!(w.commit_with_stats().unwrap().in_place);
    agrees(&db, &model);
    let r = db.begin_read().unwrap();
    for key in model.keys() {
        assert!(r.mesh_with(key, &mut Reads::new(None)).unwrap().is_some(), "{key}");
    }
}

#[test]
fn removals_that_empty_leaves_keep_the_tree_right() {
    // Every object gone from one end, one commit each: leaves empty beside
    // leaves and beside subtrees, and merge with them in place.
    let (db, mut model) = row(24);
    let nodes = |db: &Database| db.begin_read().unwrap().info().unwrap().nodes;
    let (mut merged, mut whole) = (0, 0);
    for i in 0..14u64 {
        let before = nodes(&db);
        let mut w = db.begin_write().unwrap();
        w.remove(&Key::Int(i)).unwrap();
        model.remove(&Key::Int(i));
        let stats = w.commit_with_stats().unwrap();
        merged += usize::from(stats.in_place && nodes(&db) < before);
        whole += usize::from(!stats.in_place);
        agrees(&db, &model);
    }
    assert!(merged >= 6 && whole == 0, "{merged} merges in place, {whole} commits written whole");
}

#[test]
fn a_leaf_past_its_capacity_splits_in_place() {
    let (db, _, mut model) = tanker2();
    let info = |db: &Database| db.begin_read().unwrap().info().unwrap();
    let before = info(&db);
    // Many small objects around one object: its leaf, then the leaves the
    // split makes, overflow again and again.
    let centre = model[&Key::Int(1500)].aabb();
    let mut n = 0u32;
    for commit in 0..6 {
        let mut w = db.begin_write().unwrap();
        for _ in 0..(if commit == 0 { 120 } else { 25 }) {
            let d = f64::from(n % 10) * 7.0;
            let lo = [centre.min.x + d, centre.min.y + f64::from(n / 10) * 3.0, centre.min.z];
            let o = Object::new(format!("s{n}"), box_mesh(lo, [lo[0] + 5.0, lo[1] + 2.0, lo[2] + 4.0]));
            let key = w.insert(o.clone().with_key(Key::bytes(format!("s{n}")).unwrap())).unwrap();
            model.insert(key, o);
            n += 1;
        }
        let stats = w.commit_with_stats().unwrap();
        assert!(stats.in_place, "commit {commit} wrote the tree whole: {stats:?}");
        agrees(&db, &model);
    }
    let after = info(&db);
    assert!(after.nodes > before.nodes, "no leaf split: {} nodes", after.nodes);
    assert_eq!(after.nodes, 2 * after.leaves - 1);
    // Every key still finds its mesh, through paths a split left at an ancestor.
    let r = db.begin_read().unwrap();
    for (key, o) in &model {
        let mesh = r.mesh_with(key, &mut Reads::new(None)).unwrap().expect("a key lost its object");
        assert_eq!(mesh.triangle_count(), o.mesh.triangle_count(), "{key}");
    }
    // Nodes are found by id, though ids are no longer preorder numbers: a
    // split's nodes took the ids after the bulk load's.
    let mut stats = mktree::store::ReadStats::default();
    for id in [0, before.nodes - 1, before.nodes, after.nodes - 1] {
        assert!(r.fetch_level(id, 1, true, &mut stats).is_ok(), "node {id} is not found");
    }
    assert!(r.fetch_level(after.nodes, 1, true, &mut stats).is_err());
}

#[test]
fn an_upper_block_its_records_outgrow_moves_subtrees_out_in_place() {
    // Moves of up to 2.5 m in 4 KiB blocks: the records on a moved
    // object's path take frames of their own, until a block of internal
    // records outgrows its block (5 of these 150 commits wrote the tree
    // whole when only leaves could move out).
    let scene =
        generate_scene(&GenOptions { preset: Preset::Tanker2, objects: Some(3000), seed: 1 }).unwrap();
    let options = CreateOptions { block_size: 4096, ..Default::default() };
    let db = Database::create_on(Arc::new(MemDevice::new()), options).unwrap();
    let mut w = db.begin_write().unwrap();
    w.bulk_load(&scene, &BuildParams::for_blocks(4096), &|_| {}).unwrap();
    w.commit().unwrap();
    let mut model: Model =
        scene.objects().iter().enumerate().map(|(i, o)| (Key::Int(i as u64), o.clone())).collect();
    let mut s = 12345u64;
    for i in 0..150 {
        s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        let key = Key::Int((s >> 33) % model.len() as u64);
        let d = ((s >> 20) % 5000) as f64 - 2500.0;
        let moved = shifted(&model[&key], [d, -d * 0.5, d * 0.3]);
        let mut w = db.begin_write().unwrap();
        w.update(moved.clone().with_key(key.clone())).unwrap();
        let stats = w.commit_with_stats().unwrap();
        assert!(stats.in_place, "commit {i} wrote the tree whole: {stats:?}");
        model.insert(key, moved);
        if i % 30 == 29 {
            agrees(&db, &model);
        }
    }
}

#[test]
fn changes_that_cancel_out_commit_the_same_tree() {
    let (db, _, model) = tanker2();
    let mut w = db.begin_write().unwrap();
    let o = shifted(&model[&Key::Int(7)], [1.0, 0.0, 0.0]);
    let key = w.insert(o.with_key(Key::bytes("brief").unwrap())).unwrap();
    assert!(w.remove(&key).unwrap().is_some());
    let stats = w.commit_with_stats().unwrap();
    assert!(stats.in_place, "{stats:?}");
    agrees(&db, &model);
}

#[test]
fn optimize_lays_a_changed_tree_out_as_a_bulk_load_does() {
    let (db, _, mut model) = tanker2();
    let centre = model[&Key::Int(900)].aabb();
    let mut w = db.begin_write().unwrap();
    for n in 0..150u32 {
        let lo =
            [centre.min.x + f64::from(n % 10) * 6.0, centre.min.y + f64::from(n / 10) * 3.0, centre.min.z];
        let o = Object::new(format!("p{n}"), box_mesh(lo, [lo[0] + 5.0, lo[1] + 2.0, lo[2] + 4.0]));
        model.insert(w.insert(o.clone().with_key(Key::bytes(format!("p{n}")).unwrap())).unwrap(), o);
    }
    for i in 0..200u64 {
        w.remove(&Key::Int(i * 7)).unwrap();
        model.remove(&Key::Int(i * 7));
    }
    assert!(w.commit_with_stats().unwrap().in_place);
    let mut w = db.begin_write().unwrap();
    w.optimize().unwrap();
    w.commit().unwrap();
    agrees(&db, &model);
    // The same tree a bulk load of the same objects builds.
    let scene = Scene::new(model.iter().map(|(k, o)| o.clone().with_key(k.clone())).collect());
    let fresh = Database::create_on(Arc::new(MemDevice::new()), CreateOptions::default()).unwrap();
    let mut w = fresh.begin_write().unwrap();
    w.bulk_load(&scene, &BuildParams::default(), &|_| {}).unwrap();
    w.commit().unwrap();
    let (a, b) = (db.begin_read().unwrap().info().unwrap(), fresh.begin_read().unwrap().info().unwrap());
    assert_eq!((a.nodes, a.leaves, a.depth, a.node_blocks), (b.nodes, b.leaves, b.depth, b.node_blocks));
    // Node ids are preorder numbers again: every one below the count is found.
    let r = db.begin_read().unwrap();
    let mut stats = mktree::store::ReadStats::default();
    assert!(r.fetch_level(a.nodes - 1, 1, true, &mut stats).is_ok());
}

#[test]
fn a_stream_of_single_changes_keeps_every_rule_after_each_commit() {
    // Inserts around one place (leaves split), moves and removals (a key
    // leaf empties at commit 296), one per commit, checked after each.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("changed.mkt");
    let db = Database::create(&path, CreateOptions { block_size: 4096, lod_levels: 2 }).unwrap();
    let mut w = db.begin_write().unwrap();
    let params = BuildParams {
        method: mktree::bulk::Method::Moa,
        leaf: mktree::bulk::LeafRule::Objects(4),
        ..BuildParams::paper()
    };
    w.bulk_load(&common::grid_scene(200), &params, &|_| {}).unwrap();
    w.commit().unwrap();
    for i in 0..300u64 {
        let mut w = db.begin_write().unwrap();
        common::stream_change(&mut w, i);
        if let Err(e) = w.commit_with_stats() {
            panic!("commit {i}: {e}");
        }
        let r = mktree::db::check(&db).unwrap();
        assert!(r.ok(), "after {i}: {:?}", r.faults);
    }
}

#[test]
fn a_reader_held_through_twenty_commits_keeps_only_what_it_reads() {
    let (db, _, model) = tanker2();
    let blocks = |db: &Database| db.begin_read().unwrap().info().unwrap().file_blocks;
    let start = blocks(&db);
    let reader = db.begin_read().unwrap();
    let seen = reader.query_box(&Aabb::from_array([-1e9, -1e9, -1e9, 1e9, 1e9, 1e9])).unwrap().objects.len();
    for i in 0..20u64 {
        let mut w = db.begin_write().unwrap();
        let key = Key::Int(100 + i % 4);
        w.update(shifted(&model[&key], [f64::from(i as u32 % 2) * 3.0, 0.0, 0.0]).with_key(key)).unwrap();
        assert!(w.commit_with_stats().unwrap().in_place);
    }
    // Blocks the first commit freed stay for the reader; those later
    // commits wrote and freed again no reader reaches, and are reused.
    let grown = blocks(&db);
    eprintln!("under a reader: {start} -> {grown} blocks");
    assert!(u64::from(grown) * 10 <= u64::from(start) * 12, "{start} -> {grown} blocks under a reader");
    assert_eq!(
        reader.query_box(&Aabb::from_array([-1e9, -1e9, -1e9, 1e9, 1e9, 1e9])).unwrap().objects.len(),
        seen
    );
    // compact does not move the tree under the reader, and says so.
    let c = db.compact().unwrap();
    assert!(c.held_by_reader.is_some() && c.rewrites == 0 && c.blocks_after <= c.blocks_before, "{c:?}");
    drop(reader);
    let c = db.compact().unwrap();
    assert!(c.held_by_reader.is_none() && c.rewrites > 0, "{c:?}");
    agrees(&db, &{
        let mut m = model.clone();
        for i in 0..4u64 {
            let key = Key::Int(100 + i);
            let d = if (16 + i) % 2 == 1 { 3.0 } else { 0.0 };
            m.insert(key.clone(), shifted(&model[&key], [d, 0.0, 0.0]));
        }
        m
    });
}

#[test]
fn the_next_commit_finds_the_path_the_last_one_wrote_in_the_cache() {
    let (db, dev, model) = tanker2();
    let key = Key::Int(1234);
    let depth = path_blocks(&db, &key);
    // Device reads of the lookup a change of `key` makes, shifted by `d`.
    let change_reads = |d: [f64; 3]| {
        let mut w = db.begin_write().unwrap();
        let before = dev.counts().reads;
        w.update(shifted(&model[&key], d).with_key(key.clone())).unwrap();
        let reads = dev.counts().reads - before;
        assert!(w.commit_with_stats().unwrap().in_place);
        reads
    };
    let first = change_reads([5.0, 0.0, 0.0]);
    // The node blocks on the path were written by the commit before, and
    // the cache holds them: the device reads at least the path fewer.
    let second = change_reads([10.0, 0.0, 0.0]);
    assert!(second + depth <= first, "{second} reads after {first}, a path of {depth} node blocks");
}
