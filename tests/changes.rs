//! Inserts, updates and deletes on a committed tree, and compaction: after
//! any sequence of changes `check` finds no fault, and box queries give by
//! key exactly what brute force over the changed objects gives.

mod common;

use std::collections::BTreeMap;
use std::sync::Arc;

use common::{arb_scene, box_mesh, mem_db};
use mktree::bulk::{BuildParams, LeafRule, Method};
use mktree::db::{CreateOptions, Database, check};
use mktree::geom::Aabb;
use mktree::lod::LodParams;
use mktree::query::{Region, brute_force_region};
use mktree::scene::{Key, KeyError, Object, Scene};
use mktree::store::device::MemDevice;
use proptest::prelude::*;

/// The objects a database should hold, by key.
type Model = BTreeMap<Key, Object>;

fn model_of(scene: &Scene) -> Model {
    scene.objects().iter().enumerate().map(|(i, o)| (Key::Int(i as u64), o.clone())).collect()
}

/// Checks the file, then compares box queries with brute force over `model`.
fn agrees(db: &Database, model: &Model, queries: &[Aabb]) -> Result<(), TestCaseError> {
    let report = check(db).map_err(|e| TestCaseError::fail(e.to_string()))?;
    prop_assert!(report.faults.is_empty(), "{:?}", report.faults);
    prop_assert_eq!(report.objects as usize, model.len());
    let keys: Vec<&Key> = model.keys().collect();
    let scene = Scene::new(model.values().cloned().collect());
    let txn = db.begin_read().unwrap();
    for q in queries {
        let mut expected: Vec<Key> =
            brute_force_region(&scene, &Region::Box(*q)).iter().map(|id| keys[id.index()].clone()).collect();
        expected.sort();
        let mut found = match txn.root() {
            Some(_) => txn.query_box(q).unwrap().keys,
            None => Vec::new(),
        };
        found.sort();
        prop_assert_eq!(found, expected, "query {:?}", q);
    }
    Ok(())
}

fn cube(x: f64, y: f64, z: f64, s: f64) -> Object {
    Object::new(format!("c{x}"), box_mesh([x, y, z], [x + s, y + s, z + s]))
}

#[derive(Debug, Clone)]
enum Change {
    Insert([f64; 3], f64),
    Remove(usize),
    Move(usize, [f64; 3]),
}

fn arb_change() -> impl Strategy<Value = Change> {
    let at = prop::array::uniform3(0.0f64..1000.0);
    prop_oneof![
        (at.clone(), 1.0f64..120.0).prop_map(|(p, s)| Change::Insert(p, s)),
        any::<usize>().prop_map(Change::Remove),
        (any::<usize>(), at).prop_map(|(i, p)| Change::Move(i, p)),
    ]
}

fn queries() -> Vec<Aabb> {
    let q = |lo: [f64; 3], s: f64| Aabb::new(lo.into(), [lo[0] + s, lo[1] + s, lo[2] + s].into());
    vec![
        q([0.0; 3], 1200.0),
        q([100.0, 100.0, 100.0], 300.0),
        q([500.0, 0.0, 400.0], 250.0),
        q([900.0; 3], 90.0),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 96, ..ProptestConfig::default() })]

    /// Random inserts, moves and deletes over a few transactions keep every
    /// `check` rule and answer box queries as brute force does.
    #[test]
    fn random_changes_keep_every_rule_and_the_answers(
        scene in arb_scene(40),
        method in prop::sample::select(vec![Method::Moa, Method::Refine, Method::Laa]),
        leaf in 2u32..8,
        txns in prop::collection::vec(prop::collection::vec(arb_change(), 1..12), 1..4),
    ) {
        let params = BuildParams { method, leaf: LeafRule::Objects(leaf), ..BuildParams::paper() };
        let options = CreateOptions { block_size: 4096, ..CreateOptions::default() };
        let (db, _) = mem_db(&scene, &params, options);
        let mut model = model_of(&scene);
        let mut next = 1_000_000u64;
        for changes in txns {
            let mut w = db.begin_write().unwrap();
            for c in changes {
                match c {
                    Change::Insert(p, s) => {
                        let key = w.insert(cube(p[0], p[1], p[2], s).with_key(next)).unwrap();
                        prop_assert_eq!(&key, &Key::Int(next));
                        model.insert(key, cube(p[0], p[1], p[2], s));
                        next += 1;
                    }
                    Change::Remove(i) if !model.is_empty() => {
                        let key = model.keys().nth(i % model.len()).cloned().unwrap();
                        let gone = w.remove(&key).unwrap();
                        prop_assert_eq!(gone.map(|o| o.mesh), model.remove(&key).map(|o| o.mesh));
                    }
                    Change::Move(i, p) if !model.is_empty() => {
                        let key = model.keys().nth(i % model.len()).cloned().unwrap();
                        let moved = cube(p[0], p[1], p[2], 30.0);
                        w.update(moved.clone().with_key(key.clone())).unwrap();
                        model.insert(key, moved);
                    }
                    _ => {}
                }
            }
            w.commit().unwrap();
            agrees(&db, &model, &queries())?;
        }
    }
}

#[test]
fn a_tree_grows_from_an_empty_file_one_object_at_a_time() {
    let db = Database::create_on(Arc::new(MemDevice::new()), CreateOptions::default()).unwrap();
    let mut model = Model::new();
    for t in 0..5 {
        let mut w = db.begin_write().unwrap();
        for i in 0..30 {
            let (x, y) = (f64::from(t * 30 + i) * 20.0 % 1000.0, f64::from(t) * 150.0);
            // No key: the next integer key.
            let key = w.insert(cube(x, y, 0.0, 15.0)).unwrap();
            model.insert(key, cube(x, y, 0.0, 15.0));
        }
        w.commit().unwrap();
        agrees(&db, &model, &queries()).unwrap();
    }
    let keys: Vec<Key> = model.keys().cloned().collect();
    assert_eq!(keys.first(), Some(&Key::Int(0)));
    assert_eq!(keys.last(), Some(&Key::Int(149)));
    // The library's default parameters, recorded for the later changes.
    let info = db.begin_read().unwrap().info().unwrap();
    assert_eq!(info.params, Some(BuildParams::for_blocks(info.block_size)));
}

#[test]
fn deleting_every_object_commits_an_empty_file_that_takes_new_objects() {
    let scene = common::grid_scene(4);
    let (db, _) = mem_db(&scene, &BuildParams::paper(), CreateOptions::default());
    let mut w = db.begin_write().unwrap();
    for i in 0..scene.len() as u64 {
        assert!(w.remove(&Key::Int(i)).unwrap().is_some());
    }
    assert!(w.remove(&Key::Int(0)).unwrap().is_none(), "a key removed twice is not there");
    w.commit().unwrap();
    let txn = db.begin_read().unwrap();
    assert!(txn.info().is_none(), "no tree");
    drop(txn);
    let report = check(&db).unwrap();
    assert!(report.faults.is_empty(), "{:?}", report.faults);
    assert_eq!(
        report.free_blocks + 2,
        u64::from(report.file_blocks),
        "every block but the header and the free list is free"
    );
    let mut w = db.begin_write().unwrap();
    w.insert(cube(0.0, 0.0, 0.0, 1.0).with_key(Key::bytes("again").unwrap())).unwrap();
    w.commit().unwrap();
    agrees(&db, &[(Key::bytes("again").unwrap(), cube(0.0, 0.0, 0.0, 1.0))].into(), &queries()).unwrap();
}

#[test]
fn bad_changes_are_typed_errors_and_leave_the_transaction_usable() {
    let scene = common::grid_scene(3);
    let (db, _) = mem_db(&scene, &BuildParams::paper(), CreateOptions::default());
    let mut w = db.begin_write().unwrap();
    let taken = w.insert(cube(0.0, 0.0, 0.0, 1.0).with_key(0u64));
    assert!(matches!(taken, Err(mktree::Error::Key(KeyError::Exists { .. }))), "{taken:?}");
    let missing = w.update(cube(0.0, 0.0, 0.0, 1.0).with_key(Key::bytes("nobody").unwrap()));
    assert!(matches!(missing, Err(mktree::Error::Key(KeyError::NotFound { .. }))), "{missing:?}");
    let far = Object::new("far", box_mesh([1e300, 0.0, 0.0], [1e300, 1.0, 1.0])).with_key(0u64);
    assert!(w.update(far).is_err(), "out of the file's range");
    assert!(w.object(&Key::Int(0)).unwrap().is_some(), "a refused update keeps the old object");
    let long = cube(0.0, 0.0, 0.0, 1.0).with_key(Key::bytes("long").unwrap()).with_payload(vec![
        0u8;
        Object::MAX_PAYLOAD
            + 1
    ]);
    assert!(matches!(w.insert(long), Err(mktree::Error::Key(KeyError::PayloadTooLong { .. }))));
    assert!(w.bulk_load(&scene, &BuildParams::paper(), &|_| {}).is_err(), "one tree per transaction");
    w.commit().unwrap();
    let mut model = model_of(&scene);
    model.insert(Key::Int(0), scene.objects()[0].clone());
    agrees(&db, &model, &queries()).unwrap();
}

#[test]
fn compact_gives_back_the_blocks_repeated_loads_left_free() {
    let scene = common::grid_scene(6);
    let params = BuildParams::paper();
    let (db, dev) = mem_db(&scene, &params, CreateOptions::default());
    let once = db.begin_read().unwrap().info().unwrap().file_blocks;
    for _ in 0..2 {
        let mut w = db.begin_write().unwrap();
        w.bulk_load(&scene, &params, &|_| {}).unwrap();
        w.commit().unwrap();
    }
    let info = db.begin_read().unwrap().info().unwrap();
    assert!(info.free_blocks > 0 && info.file_blocks > once, "{info:?}");
    let c = db.compact().unwrap();
    assert_eq!(c.blocks_before, info.file_blocks);
    assert!(c.blocks_after < c.blocks_before, "{c:?}");
    let after = db.begin_read().unwrap().info().unwrap();
    assert_eq!(after.file_blocks, c.blocks_after);
    assert_eq!(dev.to_bytes().len() as u64, u64::from(c.blocks_after) * u64::from(after.block_size));
    // At most an empty free-list block more than a fresh load.
    assert!(after.file_blocks <= once + 1, "{} blocks, a fresh load takes {once}", after.file_blocks);
    assert_eq!(after.free_blocks, 0);
    agrees(&db, &model_of(&scene), &queries()).unwrap();
}

#[test]
fn compact_moves_the_tree_as_it_is() {
    // Every bound stored: a choice a layout with the default parameters
    // does not repeat. A compaction that laid the tree out again (as it did
    // before it moved blocks) dropped most of them.
    let scene = common::grid_scene(6);
    let dev = Arc::new(MemDevice::new());
    let db = Database::create_on(dev.clone(), CreateOptions::default()).unwrap();
    for _ in 0..2 {
        let mut w = db.begin_write().unwrap();
        w.set_lod_params(LodParams { store_all: true, ..LodParams::default() });
        w.bulk_load(&scene, &BuildParams::paper(), &|_| {}).unwrap();
        w.commit().unwrap();
    }
    let (info, lods) = {
        let r = db.begin_read().unwrap();
        (r.info().unwrap(), r.lod_info().unwrap())
    };
    let objects = u64::from(info.objects);
    assert!(
        lods.stored[1..3].iter().all(|&n| n >= objects),
        "every bound at levels 2 and 3: {:?}",
        lods.stored
    );
    let c = db.compact().unwrap();
    assert!(c.blocks_after < c.blocks_before && c.free_after == 0, "{c:?}");
    let r = db.begin_read().unwrap();
    assert_eq!(r.lod_info().unwrap(), lods, "the levels of detail stored");
    let after = r.info().unwrap();
    let shape = |i: &mktree::TreeInfo| {
        (i.nodes, i.leaves, i.depth, i.node_blocks, i.geometry_blocks, i.node_fill, i.geometry_fill)
    };
    assert_eq!(shape(&after), shape(&info), "the layout");
    assert_eq!(after.file_blocks, c.blocks_after);
    drop(r);
    agrees(&db, &model_of(&scene), &queries()).unwrap();
}

#[test]
fn compact_keeps_the_blocks_an_open_reader_reads() {
    let scene = common::grid_scene(5);
    let params = BuildParams::paper();
    let (db, _) = mem_db(&scene, &params, CreateOptions::default());
    let old = db.begin_read().unwrap();
    let mut w = db.begin_write().unwrap();
    w.bulk_load(&scene, &params, &|_| {}).unwrap();
    w.commit().unwrap();
    db.compact().unwrap();
    // The old snapshot still reads its own tree.
    let q = Aabb::new([0.0; 3].into(), [1000.0; 3].into());
    assert_eq!(old.query_box(&q).unwrap().objects.len(), scene.len());
    drop(old);
    agrees(&db, &model_of(&scene), &queries()).unwrap();
}
