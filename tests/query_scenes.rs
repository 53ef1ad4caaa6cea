//! Claim: on whole scenes, the tanker2 preset and the real CAD scenes in
//! `../shared/data`, clash detection at k = M finds exactly brute force's
//! pairs (touching and within 50 mm), and collision, sphere and frustum
//! queries at k = M equal brute force and are supersets below. The real
//! scenes are slow in a debug build: `cargo test --test query_scenes -- --ignored`.
//! Without `../shared` (a plain clone), those tests say so and pass.

mod common;

use std::path::PathBuf;

use common::lod_db;
use mktree::geom::{Camera, Frustum, Pose, Sphere};
use mktree::lod::LodParams;
use mktree::query::{
    ClashOptions, CollideOptions, QueryOptions, Region, brute_force_clash, brute_force_collide,
    brute_force_region, clash, collide, query_region,
};
use mktree::scene::generate::{GenOptions, Preset, generate_scene};
use mktree::scene::import::{ImportOptions, load};
use mktree::scene::{ObjectId, Scene};

fn check_scene(scene: &Scene, queries: usize) {
    let db = lod_db(scene, 4, 16 * 1024, 30, LodParams::default());
    let r = db.begin_read().unwrap();
    for d in [0.0, 50.0] {
        let got = clash(&r, &ClashOptions { lod: None, clearance: d }, None).unwrap();
        assert_eq!(got.pairs, brute_force_clash(scene, d).unwrap(), "clash, d = {d}");
        assert!(got.stats.reads.total() <= u64::from(got.file_blocks));
    }
    let b = scene.aabb();
    let n = scene.len();
    for i in 0..queries {
        let id = ObjectId((i * 7919 % n) as u32);
        let mesh = &scene.objects()[id.index()].mesh;
        let pose = Pose::from_degrees([40.0, -25.0, 10.0 * i as f64], [0.0, 0.0, 3.0 * i as f64]).unwrap();
        let exact = brute_force_collide(scene, mesh, &pose, 20.0, Some(id)).unwrap();
        let at = |k| {
            let opts = CollideOptions {
                query: QueryOptions { lod: Some(k), budget: None, ..Default::default() },
                clearance: 20.0,
                exclude: Some(id),
            };
            collide(&r, mesh, &pose, &opts, None).unwrap().objects
        };
        assert_eq!(at(4), exact, "collision of object {id}");
        assert!(exact.iter().all(|o| at(2).contains(o)));
        let c = mesh.aabb().center();
        let sphere = Region::Sphere(Sphere::new(c, 0.05 * b.extent().norm()).unwrap());
        let cam = Camera {
            eye: c,
            target: b.center(),
            fov_deg: 50.0,
            aspect: 1.3,
            near: 50.0,
            far: 0.5 * b.extent().norm(),
        };
        let Ok(f) = Frustum::from_camera(&cam) else { continue };
        for region in [sphere, Region::Frustum(Box::new(f))] {
            let exact = brute_force_region(scene, &region);
            assert_eq!(query_region(&r, &region, &QueryOptions::default(), None).unwrap().objects, exact);
            let coarse = query_region(
                &r,
                &region,
                &QueryOptions { lod: Some(3), budget: None, ..Default::default() },
                None,
            )
            .unwrap();
            assert!(exact.iter().all(|o| coarse.objects.contains(o)));
        }
    }
}

#[test]
fn tanker2_clashes_and_queries_equal_brute_force() {
    let scene = generate_scene(&GenOptions { preset: Preset::Tanker2, objects: None, seed: 0 }).unwrap();
    check_scene(&scene, 10);
}

fn shared(name: &str) -> Option<Scene> {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data").join(name);
    if !path.is_file() {
        eprintln!("SKIPPED: {} is absent, so the query test for {name} did not run", path.display());
        return None;
    }
    Some(load(&path, &ImportOptions::default()).unwrap_or_else(|e| panic!("{e}")).scene)
}

#[test]
#[ignore = "slow: real CAD scenes with large objects; run with --ignored"]
fn real_scenes_clashes_and_queries_equal_brute_force() {
    for name in ["fzk-haus.obj", "engine.obj"] {
        if let Some(scene) = shared(name) {
            check_scene(&scene, 4);
        }
    }
}
