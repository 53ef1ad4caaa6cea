//! The application's keys: unique, given back by lookups that read only the
//! key index's path (and, for a mesh, the leaf's node block and the
//! object's geometry), never a walk of the tree; `check` holds the index to
//! the tree.

mod common;

use common::{box_mesh, mem_db};
use mktree::Error;
use mktree::bulk::{BuildParams, LeafRule};
use mktree::db::{CreateOptions, Reads, check};
use mktree::geom::{Aabb, Point, Ray, Vector};
use mktree::query::{Near, QueryOptions, Region};
use mktree::scene::{Key, KeyError, Mesh, Object, ObjectId, Scene};
use mktree::store::format::frame::BlockType;
use proptest::prelude::*;

/// `n` boxes keyed by `key(i)`, each with a payload naming it.
fn keyed(n: usize, key: impl Fn(usize) -> Key) -> Scene {
    Scene::new(
        (0..n)
            .map(|i| {
                let lo = [(i % 20) as f64 * 60.0, (i / 20) as f64 * 60.0, (i % 7) as f64 * 10.0];
                Object::new(format!("o{i}"), box_mesh(lo, [lo[0] + 40.0, lo[1] + 45.0, lo[2] + 30.0]))
                    .with_key(key(i))
                    .with_payload(format!("row {i}").into_bytes())
            })
            .collect(),
    )
}

fn guid(i: usize) -> Key {
    Key::bytes(format!("2O2Fr$t4X7Zf8NOew3F{i:03}")).unwrap()
}

fn small_blocks() -> CreateOptions {
    CreateOptions { block_size: 1024, ..CreateOptions::default() }
}

fn params() -> BuildParams {
    BuildParams { leaf: LeafRule::Objects(8), ..BuildParams::paper() }
}

#[test]
fn every_key_finds_its_object_box_payload_and_mesh() {
    let scene = keyed(300, guid);
    let (db, _) = mem_db(&scene, &params(), small_blocks());
    assert!(check(&db).unwrap().ok(), "{:?}", check(&db).unwrap().faults);
    let r = db.begin_read().unwrap();
    for (i, o) in scene.objects().iter().enumerate() {
        let key = guid(i);
        let rec = r.get(&key).unwrap().expect("a stored key is found");
        assert_eq!(rec.id, ObjectId(i as u32));
        assert_eq!(rec.key, key);
        assert_eq!(rec.payload, format!("row {i}").into_bytes());
        assert_eq!(rec.aabb, o.aabb());
        assert_eq!(r.aabb(&key).unwrap(), Some(o.aabb()));
        let mesh = r.mesh(&key).unwrap().expect("a stored key has a mesh");
        assert_eq!(mesh.aabb(), o.aabb());
        assert_eq!(mesh.triangle_count(), o.mesh.triangle_count());
    }
    assert_eq!(r.get(&Key::bytes("not a key").unwrap()).unwrap(), None);
    assert_eq!(r.get(&Key::Int(3)).unwrap(), None, "integer keys are not byte keys");
    assert_eq!(r.mesh(&Key::bytes("").unwrap()).unwrap(), None);
}

/// A zigzag strip of `n` triangles along x from `x0`: far more than a
/// 1 KiB block holds, so it is stored in parts.
fn strip(x0: f64, n: u32) -> Mesh {
    let vertices: Vec<Point> = (0..n + 2)
        .map(|v| Point::new(x0 + f64::from(v) * 3.0, f64::from(v % 2) * 5.0, f64::from(v % 3)))
        .collect();
    Mesh::from_world(&vertices, (0..n).map(|t| [t, t + 1, t + 2]).collect()).unwrap()
}

#[test]
fn objects_stored_in_parts_are_found_by_key_with_their_whole_box() {
    let mut objects: Vec<Object> =
        (0..4).map(|i| Object::new(format!("s{i}"), strip(f64::from(i) * 2000.0, 300))).collect();
    objects.extend((0..40).map(|i| {
        let lo = [f64::from(i) * 60.0, 40.0, 0.0];
        Object::new(format!("b{i}"), box_mesh(lo, [lo[0] + 40.0, 80.0, 30.0]))
    }));
    let scene = Scene::new(objects.into_iter().enumerate().map(|(i, o)| o.with_key(guid(i))).collect());
    let (db, _) = mem_db(&scene, &params(), small_blocks());
    assert!(check(&db).unwrap().ok(), "{:?}", check(&db).unwrap().faults);
    let r = db.begin_read().unwrap();
    for (i, o) in scene.objects().iter().enumerate() {
        let rec = r.get(&guid(i)).unwrap().expect("a stored key is found");
        assert_eq!((rec.id, rec.aabb), (ObjectId(i as u32), o.aabb()), "object {i}");
        let mesh = r.mesh(&guid(i)).unwrap().expect("a stored key has a mesh");
        assert_eq!((mesh.triangle_count(), mesh.aabb()), (o.mesh.triangle_count(), o.aabb()), "object {i}");
    }
}

#[test]
fn a_lookup_reads_the_index_path_and_a_mesh_its_tree_path_and_geometry() {
    // 1 KiB blocks make a key index of several levels.
    let scene = keyed(600, guid);
    let (db, _) = mem_db(&scene, &params(), small_blocks());
    let r = db.begin_read().unwrap();
    let height = (1..10)
        .find(|&h| {
            let mut reads = Reads::new(None);
            r.get_with(&guid(0), &mut reads).unwrap();
            reads.stats.keys == h
        })
        .expect("a few levels");
    assert!(height >= 2, "600 keys of 1 KiB blocks take more than one level");
    for i in [0, 299, 599] {
        let mut reads = Reads::new(None);
        r.get_with(&guid(i), &mut reads).unwrap().unwrap();
        assert_eq!((reads.stats.keys, reads.stats.total()), (height, height), "every key is as deep");
        let mut reads = Reads::new(None);
        r.mesh_with(&guid(i), &mut reads).unwrap().unwrap();
        // The index, the node blocks from the root to the leaf (the entry's
        // path, format-spec/keys.md), and the one geometry block a box takes.
        let path_blocks = reads.stats.node;
        let levels = u64::from(r.info().unwrap().depth) + 1;
        assert!((1..=levels).contains(&path_blocks), "{path_blocks} node blocks for {levels} levels");
        assert_eq!((reads.stats.keys, reads.stats.geometry), (height, 1));
    }
}

#[test]
fn answers_give_the_keys_from_the_leaves_at_no_read_of_their_own() {
    let scene = keyed(200, guid);
    let (db, _) = mem_db(&scene, &params(), small_blocks());
    let r = db.begin_read().unwrap();
    let region = Aabb::from_array([0.0, 0.0, 0.0, 500.0, 300.0, 100.0]);
    let a = r.query_box(&region).unwrap();
    assert!(!a.objects.is_empty());
    assert_eq!(a.keys, a.objects.iter().map(|o| guid(o.index())).collect::<Vec<_>>());
    assert_eq!(a.stats.reads.keys, 0, "a query reads no key index block");
    for hit in r.select(&Region::Box(region), &QueryOptions::default(), None).unwrap() {
        let hit = hit.unwrap();
        assert_eq!(hit.key, guid(hit.object.index()));
    }
    let near: Vec<Near> =
        r.nearest(Point::new(0.0, 0.0, 0.0), None).unwrap().take(5).map(|n| n.unwrap()).collect();
    assert!(near.iter().all(|n| n.key == guid(n.object.index())));
    let ray = Ray::new(Point::new(-10.0, 20.0, 15.0), Vector::new(1.0, 0.0, 0.0), None).unwrap();
    let hit = r.first_hit(&ray, None).unwrap().expect("the row of boxes is hit");
    assert_eq!(hit.key, guid(hit.object.index()));
}

#[test]
fn objects_without_a_key_are_keyed_by_their_id() {
    let scene =
        Scene::new((0..50).map(|i| Object::new("", box_mesh([i as f64; 3], [i as f64 + 2.0; 3]))).collect());
    let (db, _) = mem_db(&scene, &params(), CreateOptions::default());
    let r = db.begin_read().unwrap();
    for i in 0..50u32 {
        assert_eq!(r.get(&Key::Int(u64::from(i))).unwrap().unwrap().id, ObjectId(i));
    }
    assert_eq!(r.get(&Key::Int(50)).unwrap(), None);
}

#[test]
fn a_repeated_key_or_a_long_payload_is_a_typed_error_and_writes_nothing() {
    let mut scene = keyed(10, |i| Key::Int(i as u64 * 7));
    let objects: Vec<Object> = scene.objects().to_vec();
    scene = Scene::new(
        objects.into_iter().enumerate().map(|(i, o)| if i == 6 { o.with_key(14u64) } else { o }).collect(),
    );
    let db = mktree::db::Database::create_on(
        std::sync::Arc::new(mktree::store::device::MemDevice::new()),
        CreateOptions::default(),
    )
    .unwrap();
    let mut w = db.begin_write().unwrap();
    let err = w.bulk_load(&scene, &params(), &|_| {}).unwrap_err();
    assert!(
        matches!(&err, Error::Key(KeyError::Duplicate { key, first, second })
            if *key == Key::Int(14) && (first.0, second.0) == (2, 6)),
        "{err}"
    );
    let long = Scene::new(vec![Object::new("", box_mesh([0.0; 3], [1.0; 3])).with_payload(vec![0; 1025])]);
    let err = w.bulk_load(&long, &params(), &|_| {}).unwrap_err();
    assert!(matches!(err, Error::Key(KeyError::PayloadTooLong { len: 1025, .. })), "{err}");
    w.abort().unwrap();
    assert!(db.begin_read().unwrap().info().is_none());
}

#[test]
fn check_catches_a_key_index_that_disagrees_with_the_tree() {
    let scene = keyed(40, guid);
    let (db, dev) = mem_db(&scene, &params(), small_blocks());
    drop(db);
    let image = dev.to_bytes();
    let mut forged = common::forge::Image { bytes: image, bs: 1024 };
    // A key leaf's first entry's object id changed, the block re-sealed up the chain.
    let leaf = forged.blocks_of(BlockType::KeyLeaf)[0];
    // Entry 0: a 2 + 22 byte key, a 2 + 5 byte payload ("row 0"), then the id.
    let at = leaf * 1024 + 24 + 24 + 7;
    forged.bytes[at] ^= 1;
    forged.reseal(leaf, BlockType::KeyLeaf);
    let db = mktree::db::Database::open_on(std::sync::Arc::new(
        mktree::store::device::MemDevice::from_bytes(forged.bytes),
    ))
    .unwrap();
    let report = check(&db).unwrap();
    assert!(report.faults.iter().any(|f| f.contains("key")), "{:?}", report.faults);
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]

    #[test]
    fn any_unique_keys_are_all_found_and_no_other(
        keys in prop::collection::btree_set(
            prop_oneof![
                any::<u64>().prop_map(Key::Int),
                prop::collection::vec(any::<u8>(), 0..40).prop_map(|b| Key::bytes(b).unwrap()),
            ],
            1..120,
        ),
        probes in prop::collection::vec(any::<u64>(), 8),
    ) {
        let keys: Vec<Key> = keys.into_iter().collect();
        let scene = keyed(keys.len(), |i| keys[i].clone());
        let (db, _) = mem_db(&scene, &params(), small_blocks());
        prop_assert!(check(&db).unwrap().ok());
        let r = db.begin_read().unwrap();
        for (i, k) in keys.iter().enumerate() {
            prop_assert_eq!(r.get(k).unwrap().map(|x| x.id), Some(ObjectId(i as u32)));
        }
        for p in probes {
            let k = Key::Int(p);
            prop_assert_eq!(r.get(&k).unwrap().is_some(), keys.contains(&k));
        }
    }
}
