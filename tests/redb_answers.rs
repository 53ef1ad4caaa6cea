//! Claim: a tree kept in a redb table answers every query as the same tree
//! in mktree's own file does (box, collide, clash, nearest, ray: the same
//! objects, in the same order, with the same block reads), and both answer
//! as brute force over the scene does.

use std::sync::Arc;

use mktree::db::{CreateOptions, Database};
use mktree::geom::{Point, Pose, Ray, Vector};
use mktree::query::{
    ClashOptions, CollideOptions, QueryOptions, Region, brute_force_clash, brute_force_nearest,
    brute_force_ray, brute_force_region, clash, collide, query_region,
};
use mktree::redb::{DEFAULT_BLOCK_SIZE, TreeDefinition};
use mktree::scene::generate::{GenOptions, Preset, generate_scene};
use mktree::store::device::MemDevice;
use mktree::{Aabb, BuildParams, ObjectId, ReadTransaction, Scene};
use redb::ReadableDatabase;

const INDEX: TreeDefinition = TreeDefinition::new("index");

/// A seeded stream in [0, 1).
fn uniform(seed: &mut u64) -> f64 {
    *seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
    (*seed >> 11) as f64 / (1u64 << 53) as f64
}

fn both(scene: &Scene) -> (Database, redb::Database) {
    let params = BuildParams::default();
    let options = CreateOptions { block_size: DEFAULT_BLOCK_SIZE, ..CreateOptions::default() };
    let file = Database::create_on(Arc::new(MemDevice::new()), options).unwrap();
    let mut w = file.begin_write().unwrap();
    w.bulk_load(scene, &params, &|_| {}).unwrap();
    w.commit().unwrap();
    let db = redb::Builder::new().create_with_backend(redb::backends::InMemoryBackend::new()).unwrap();
    let txn = db.begin_write().unwrap();
    INDEX.write(&txn, |w| w.bulk_load(scene, &params, &|_| {}).map(|_| ())).unwrap();
    txn.commit().unwrap();
    (file, db)
}

fn boxes(scene: &Scene, n: usize, seed: u64) -> Vec<Aabb> {
    let s = scene.aabb().to_array();
    let mut seed = seed;
    (0..n)
        .map(|i| {
            let share = [0.01, 0.05, 0.2][i % 3];
            let mut b = [0.0; 6];
            for a in 0..3 {
                let side = (s[a + 3] - s[a]) * share;
                b[a] = s[a] + uniform(&mut seed) * (s[a + 3] - s[a] - side);
                b[a + 3] = b[a] + side;
            }
            Aabb::from_array(b)
        })
        .collect()
}

fn compare(scene: &Scene, file: &ReadTransaction, table: &ReadTransaction, seed: u64) {
    assert_eq!(
        file.info().map(|i| (i.objects, i.node_blocks, i.geometry_blocks)),
        table.info().map(|i| (i.objects, i.node_blocks, i.geometry_blocks))
    );
    for b in boxes(scene, 30, seed) {
        let region = Region::Box(b);
        let f = query_region(file, &region, &QueryOptions::default(), None).unwrap();
        let t = query_region(table, &region, &QueryOptions::default(), None).unwrap();
        assert_eq!(t.objects, brute_force_region(scene, &region), "box {b:?}");
        assert_eq!((&t.objects, &t.keys, t.stats.reads), (&f.objects, &f.keys, f.stats.reads), "box {b:?}");
    }
    let mut s = seed;
    for _ in 0..6 {
        let id = ObjectId((uniform(&mut s) * scene.len() as f64) as u32);
        let mesh = &scene.objects()[id.index()].mesh;
        let pose = Pose::from_degrees([50.0, -20.0, 10.0], [0.0, 0.0, 15.0]).unwrap();
        let opts = CollideOptions { clearance: 25.0, exclude: Some(id), ..Default::default() };
        let f = collide(file, mesh, &pose, &opts, None).unwrap();
        let t = collide(table, mesh, &pose, &opts, None).unwrap();
        assert_eq!((&t.objects, t.stats.reads), (&f.objects, f.stats.reads), "collide {id}");
    }
    let opts = ClashOptions { lod: None, clearance: 0.0 };
    let (f, t) = (clash(file, &opts, None).unwrap(), clash(table, &opts, None).unwrap());
    assert_eq!(t.pairs, brute_force_clash(scene, 0.0).unwrap());
    assert_eq!((&t.pairs, t.stats.reads), (&f.pairs, f.stats.reads));
    let s_box = scene.aabb().to_array();
    let mut s = seed;
    for _ in 0..5 {
        let p = Point::new(
            s_box[0] + uniform(&mut s) * (s_box[3] - s_box[0]),
            s_box[1] + uniform(&mut s) * (s_box[4] - s_box[1]),
            s_box[2] + uniform(&mut s) * (s_box[5] - s_box[2]),
        );
        let f: Vec<_> = file.nearest(p, None).unwrap().take(5).collect::<Result<_, _>>().unwrap();
        let t: Vec<_> = table.nearest(p, None).unwrap().take(5).collect::<Result<_, _>>().unwrap();
        assert_eq!(t, f, "nearest to {p:?}");
        let exact: Vec<f64> = brute_force_nearest(scene, &p).iter().take(5).map(|n| n.distance).collect();
        assert_eq!(t.iter().map(|n| n.distance).collect::<Vec<_>>(), exact, "nearest to {p:?}");
        let ray = Ray::new(p, Vector::new(1.0, 0.3, -0.2), None).unwrap();
        let f: Vec<_> = file.ray(&ray, None).unwrap().collect::<Result<_, _>>().unwrap();
        let t: Vec<_> = table.ray(&ray, None).unwrap().collect::<Result<_, _>>().unwrap();
        assert_eq!(t, f, "ray from {p:?}");
        let exact: Vec<_> = brute_force_ray(scene, &ray).into_iter().map(|h| h.object).collect();
        assert_eq!(t.iter().map(|h| h.object).collect::<Vec<_>>(), exact, "ray from {p:?}");
    }
}

#[test]
fn a_tree_in_redb_answers_as_its_file_and_brute_force_do() {
    for (preset, seed) in [(Preset::Tanker1, 1), (Preset::Ship, 2)] {
        let objects = (preset == Preset::Ship).then_some(400);
        let scene = generate_scene(&GenOptions { preset, objects, seed }).unwrap();
        println!("{preset:?}, {} objects, seed {seed}", scene.len());
        let (file, db) = both(&scene);
        let table = INDEX.read(&db.begin_read().unwrap()).unwrap();
        compare(&scene, &file.begin_read().unwrap(), &table, seed);
    }
}

#[test]
fn keys_and_meshes_read_back_from_the_table() {
    let scene = generate_scene(&GenOptions { preset: Preset::Tanker1, objects: None, seed: 3 }).unwrap();
    let (_, db) = both(&scene);
    let r = INDEX.read(&db.begin_read().unwrap()).unwrap();
    for (i, o) in scene.objects().iter().enumerate().step_by(7) {
        let key = mktree::Key::Int(i as u64);
        assert_eq!(r.mesh(&key).unwrap().as_ref(), Some(&o.mesh), "object {i}");
    }
    assert_eq!(r.names().unwrap(), scene.objects().iter().map(|o| o.name.clone()).collect::<Vec<_>>());
}

#[test]
fn a_table_never_written_is_an_empty_tree() {
    let db = redb::Builder::new().create_with_backend(redb::backends::InMemoryBackend::new()).unwrap();
    let r = INDEX.read(&db.begin_read().unwrap()).unwrap();
    assert!(r.info().is_none());
    assert!(r.query_box(&Aabb::from_array([0.0, 0.0, 0.0, 1.0, 1.0, 1.0])).unwrap().objects.is_empty());
}
