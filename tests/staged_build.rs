//! A scene staged on disk (`StagedScene`, meshes in a spill file) loads
//! the same tree, block for block apart from the recorded build time, and
//! gives the same answers as the in-memory `Scene` of the same objects:
//! generated ships and tankers, objects larger than a block (stored in
//! parts), application keys and payloads, and random scenes.

mod common;

use std::sync::Arc;

use common::forge::Image;
use mktree::bulk::{BuildParams, LeafRule, Method};
use mktree::db::{CreateOptions, Database, StagedScene};
use mktree::geom::Aabb;
use mktree::geom::Point;
use mktree::lod::LodParams;
use mktree::query::{QueryOptions, Region, brute_force_region, query_region};
use mktree::scene::generate::{GenOptions, Preset, generate_scene};
use mktree::scene::{Key, Mesh, Object, Scene};
use mktree::store::device::MemDevice;
use mktree::store::format::frame::BlockType;
use mktree::store::format::meta::Meta;
use proptest::prelude::*;

/// The file image of `scene` loaded by `load`, with the build time zeroed
/// (and every checksum over it resealed).
fn image(options: CreateOptions, load: impl FnOnce(&mut mktree::WriteTransaction)) -> Image {
    let dev = Arc::new(MemDevice::new());
    let db = Database::create_on(dev.clone(), options).expect("create");
    let mut w = db.begin_write().expect("begin_write");
    load(&mut w);
    w.commit().expect("commit");
    drop(db);
    let mut img = Image { bytes: dev.to_bytes(), bs: options.block_size as usize };
    let m = img.meta();
    let block = &mut img.bytes[m * img.bs..(m + 1) * img.bs];
    let mut meta = Meta::decode(m as u32, block).expect("meta");
    meta.build.build_seconds = 0.0;
    meta.encode(block);
    img.reseal(m, BlockType::Meta);
    img
}

fn staged(scene: &Scene) -> StagedScene {
    let mut s = StagedScene::create_in(&std::env::temp_dir()).expect("spill file");
    for o in scene.objects() {
        s.push(o.clone()).expect("staged");
    }
    s
}

/// Loads `scene` both ways and checks the images are equal.
fn same_both_ways(scene: &Scene, options: CreateOptions, params: &BuildParams) -> Image {
    same_both_ways_with(scene, options, params, &LodParams::default())
}

fn same_both_ways_with(
    scene: &Scene,
    options: CreateOptions,
    params: &BuildParams,
    lod: &LodParams,
) -> Image {
    let in_memory = image(options, |w| {
        w.set_lod_params(lod.clone());
        w.bulk_load(scene, params, &|_| {}).expect("bulk_load");
    });
    let mut s = staged(scene);
    let on_disk = image(options, |w| {
        w.set_lod_params(lod.clone());
        w.bulk_load_staged(&mut s, params, &|_| {}).expect("bulk_load_staged");
    });
    assert_eq!(in_memory.bytes.len(), on_disk.bytes.len(), "file lengths");
    let bs = in_memory.bs;
    let differ: Vec<usize> = (0..in_memory.bytes.len() / bs)
        .filter(|&b| in_memory.bytes[b * bs..(b + 1) * bs] != on_disk.bytes[b * bs..(b + 1) * bs])
        .collect();
    assert!(differ.is_empty(), "blocks {differ:?} differ");
    in_memory
}

/// A wavy sheet of 2 x `n` x `n` triangles at `x`: one object larger than
/// a small block.
fn sheet(x: f64, n: u32) -> Mesh {
    let side = n + 1;
    let vertices: Vec<Point> = (0..side * side)
        .map(|v| {
            let (i, j) = (f64::from(v % side), f64::from(v / side));
            Point::new(x + (i * 0.7).sin() * 3.0, i * 10.0, j * 10.0 + (i * j).cos())
        })
        .collect();
    let mut triangles = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let a = j * side + i;
            triangles.push([a, a + 1, a + side]);
            triangles.push([a + 1, a + side + 1, a + side]);
        }
    }
    Mesh::from_world(&vertices, triangles).expect("a sheet")
}

fn ship(objects: u64) -> Scene {
    generate_scene(&GenOptions { preset: Preset::Ship, objects: Some(objects), seed: 3 }).expect("ship")
}

#[test]
fn a_ship_loads_the_same_blocks() {
    same_both_ways(&ship(3000), CreateOptions::default(), &BuildParams::default());
}

#[test]
fn levels_of_detail_computed_from_spilled_meshes_are_the_same() {
    let scene = Scene::new(common::slanted_triangles(40));
    let lod = LodParams { store_all: true, ..LodParams::default() };
    let options = CreateOptions { block_size: 4096, lod_levels: 5 };
    let params = BuildParams { method: Method::Moa, leaf: LeafRule::Objects(4), ..BuildParams::default() };
    let img = same_both_ways_with(&scene, options, &params, &lod);
    assert!(img.leaves().iter().any(|&(_, r)| !img.leaf_bounds(r).is_empty()), "no bound stored");
}

#[test]
fn every_method_loads_the_same_blocks() {
    let scene =
        generate_scene(&GenOptions { preset: Preset::Tanker1, objects: None, seed: 0 }).expect("tanker1");
    for method in [Method::Moa, Method::Laa, Method::Refine] {
        let params = BuildParams { method, ..BuildParams::default() };
        same_both_ways(&scene, CreateOptions::default(), &params);
    }
}

#[test]
fn objects_larger_than_a_block_are_stored_in_the_same_parts() {
    let mut objects = ship(300).into_objects();
    objects.extend((0..6).map(|i| Object::new(format!("sheet{i}"), sheet(f64::from(i) * 2000.0, 12 + i))));
    let scene = Scene::new(objects);
    let options = CreateOptions { block_size: 1024, lod_levels: 4 };
    let params = BuildParams { leaf: LeafRule::Objects(4), ..BuildParams::default() };
    let img = same_both_ways(&scene, options, &params);
    let entries: usize = img.leaves().iter().map(|&(_, r)| img.leaf_entries(r).len()).sum();
    assert!(entries > scene.len(), "no object was split into parts");
}

#[test]
fn keys_payloads_and_answers_are_the_same() {
    let scene = Scene::new(
        ship(800)
            .into_objects()
            .into_iter()
            .enumerate()
            .map(|(i, o)| match i % 3 {
                0 => o.with_key(Key::Int(7_000_000 - i as u64)).with_payload(vec![i as u8; i % 17]),
                1 => o.with_key(Key::bytes(format!("GUID-{i:05}").as_bytes()).expect("short")),
                _ => o,
            })
            .collect(),
    );
    same_both_ways(&scene, CreateOptions::default(), &BuildParams::default());
    let mut s = staged(&scene);
    let db = Database::create_on(Arc::new(MemDevice::new()), CreateOptions::default()).expect("create");
    let mut w = db.begin_write().expect("begin");
    w.bulk_load_staged(&mut s, &BuildParams::default(), &|_| {}).expect("load");
    w.commit().expect("commit");
    let r = db.begin_read().expect("read");
    for (i, o) in scene.objects().iter().enumerate().step_by(37) {
        let key = scene.key(mktree::ObjectId(i as u32)).expect("a key");
        let got = r.get(&key).expect("get").expect("found");
        assert_eq!(got.payload, o.payload);
        assert_eq!(r.mesh(&key).expect("mesh").expect("found"), o.mesh);
    }
    let q = Aabb::from_array([0.0, -5000.0, 0.0, 20_000.0, 5000.0, 8000.0]);
    let region = Region::Box(q);
    let exact = query_region(&r, &region, &QueryOptions::default(), None).expect("query");
    let mut got: Vec<Key> = exact.keys.clone();
    got.sort();
    let mut want: Vec<Key> =
        brute_force_region(&scene, &region).into_iter().map(|id| scene.key(id).expect("a key")).collect();
    want.sort();
    assert!(!want.is_empty(), "the query meets objects");
    assert_eq!(got, want);
}

#[test]
fn duplicate_keys_are_refused_when_staged() {
    let objects = common::slanted_triangles(3);
    let mut s = StagedScene::create_in(&std::env::temp_dir()).expect("spill file");
    for o in objects {
        s.push(o.with_key(Key::Int(9))).expect("staged");
    }
    let db = Database::create_on(Arc::new(MemDevice::new()), CreateOptions::default()).expect("create");
    let mut w = db.begin_write().expect("begin");
    let err = w.bulk_load_staged(&mut s, &BuildParams::default(), &|_| {}).expect_err("duplicate keys");
    assert!(matches!(err, mktree::Error::Key(mktree::KeyError::Duplicate { .. })), "{err}");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(12))]
    #[test]
    fn random_scenes_load_the_same_blocks(scene in common::arb_scene(60)) {
        let options = CreateOptions { block_size: 2048, lod_levels: 4 };
        let params = BuildParams { method: Method::Moa, leaf: LeafRule::Objects(5), ..BuildParams::default() };
        same_both_ways(&scene, options, &params);
    }
}

#[test]
fn the_spill_file_leaves_nothing_behind() {
    let dir = std::env::temp_dir().join(format!("mktree-staged-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    {
        let mut s = StagedScene::create_in(&dir).expect("spill file");
        for o in common::slanted_triangles(10) {
            s.push(o).expect("staged");
        }
        assert_eq!(s.len(), 10);
        assert!(s.spilled_bytes() > 0);
    }
    assert_eq!(std::fs::read_dir(&dir).expect("read dir").count(), 0);
    std::fs::remove_dir(&dir).expect("empty");
}
