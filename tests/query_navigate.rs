//! Claim: a navigation walk answers each step as a lone frustum query does,
//! and its pool, kept across steps, only saves reads: a step reads no more
//! than the same query from a cold pool, and a path that stands still reads
//! nothing after its first step when the pool holds what it needs.

mod common;

use common::lod_db;
use mktree::geom::{Camera, Frustum, Point};
use mktree::lod::LodParams;
use mktree::query::{QueryOptions, Region, brute_force_region, navigate, query_region};
use mktree::scene::generate::{GenOptions, Preset, generate_scene};

#[test]
fn a_walk_through_tanker1_answers_each_step_and_its_pool_saves_reads() {
    let scene = generate_scene(&GenOptions { preset: Preset::Tanker1, objects: None, seed: 0 }).unwrap();
    let db = lod_db(&scene, 4, 4096, 10, LodParams::default());
    let r = db.begin_read().unwrap();
    let b = scene.aabb();
    let c = b.center();
    let cameras: Vec<Camera> = (0..12)
        .map(|i| {
            let x = b.min.x + b.extent().x * (i.min(9) as f64) / 10.0;
            let eye = Point::new(x, c.y, c.z);
            Camera {
                eye,
                target: eye + nalgebra::Vector3::x() * 1000.0,
                fov_deg: 60.0,
                aspect: 1.5,
                near: 10.0,
                far: 1500.0,
            }
        })
        .collect();
    let steps = navigate(&r, &cameras, &QueryOptions::default(), 1000).unwrap();
    assert_eq!(steps.len(), cameras.len());
    for (s, cam) in steps.iter().zip(&cameras) {
        let region = Region::Frustum(Box::new(Frustum::from_camera(cam).unwrap()));
        assert_eq!(s.objects, brute_force_region(&scene, &region), "step {}", s.step);
        let cold = query_region(&r, &region, &QueryOptions::default(), None).unwrap();
        assert!(s.reads.total() <= cold.stats.reads.total(), "step {}: the pool cost reads", s.step);
    }
    // Steps 10 and 11 repeat step 9's camera: everything is in the pool.
    assert_eq!(steps[10].reads.total(), 0);
    assert_eq!(steps[11].reads.total(), 0);
    assert!(steps[11].reads.cache_hits > 0);
    let total: u64 = steps.iter().map(|s| s.reads.total()).sum();
    let tiny: u64 =
        navigate(&r, &cameras, &QueryOptions::default(), 1).unwrap().iter().map(|s| s.reads.total()).sum();
    assert!(total < tiny, "a pool of 1000 blocks reads less ({total}) than one of 1 ({tiny})");
}
