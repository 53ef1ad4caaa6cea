//! A build reports its progress: once at the start with the work estimate,
//! as it goes, and once at the end with every object placed; LAA reports
//! how deep its trials looked; and the estimate grows with the look-ahead.

use std::sync::Mutex;

use mktree::bulk::{BuildParams, BuildProgress, LeafRule, LookAhead, Method, build, estimate_work};
use mktree::geom::Aabb;

/// 3000 boxes on a jittered 15 x 20 x 10 lattice.
fn lattice() -> Vec<Aabb> {
    (0..3000)
        .map(|i| {
            let (x, y, z) = (f64::from(i % 15), f64::from((i / 15) % 20), f64::from(i / 300));
            let j = f64::from((i * 37) % 11) / 10.0;
            Aabb::from_array([
                10.0 * x + j,
                10.0 * y,
                10.0 * z + j,
                10.0 * x + 6.0 + j,
                10.0 * y + 7.0,
                10.0 * z + 5.0,
            ])
        })
        .collect()
}

fn reports(boxes: &[Aabb], params: &BuildParams) -> Vec<BuildProgress> {
    let seen = Mutex::new(Vec::new());
    build(boxes, None, params, &|p| seen.lock().unwrap().push(p)).unwrap();
    seen.into_inner().unwrap()
}

#[test]
fn progress_starts_with_the_estimate_and_ends_with_every_object_placed() {
    let boxes = lattice();
    for method in Method::ALL {
        let params = BuildParams { method, leaf: LeafRule::Objects(20), ..BuildParams::paper() };
        let seen = reports(&boxes, &params);
        let (first, last) = (seen[0], seen[seen.len() - 1]);
        assert!(seen.len() > 10, "{method}: {} reports", seen.len());
        assert_eq!((first.objects_placed, first.work_done), (0, 0));
        assert_eq!(first.work_estimate, estimate_work(boxes.len(), None, &params));
        assert_eq!((last.objects_placed, last.objects_total), (3000, 3000));
        assert!(last.work_done > 0);
        assert!(seen.len() < 5_000, "{method}: {} reports: throttled", seen.len());
    }
}

#[test]
fn laa_reports_the_look_level_it_reached() {
    let boxes = lattice();
    let base = BuildParams { method: Method::Laa, leaf: LeafRule::Objects(20), ..BuildParams::paper() };
    let reached = |look_ahead| {
        let seen = reports(&boxes, &BuildParams { look_ahead, ..base.clone() });
        seen[seen.len() - 1].look_level_reached
    };
    assert_eq!(reached(LookAhead::Levels(0)), 0);
    assert_eq!(reached(LookAhead::Levels(2)), 2);
    let max = reached(LookAhead::Max);
    assert!(max > 2, "max look-ahead reached {max} levels");
    let moa = reports(&boxes, &BuildParams { method: Method::Moa, ..base.clone() });
    assert_eq!(moa[moa.len() - 1].look_level_reached, 0);
}

#[test]
fn the_estimate_grows_with_the_look_ahead_and_shrinks_with_the_page() {
    let p = |method, look_ahead, mem_page| BuildParams {
        method,
        look_ahead,
        leaf: LeafRule::Objects(mem_page),
        ..BuildParams::paper()
    };
    let w = |params: &BuildParams| estimate_work(1_000_000, None, params);
    assert!(w(&p(Method::Laa, LookAhead::Max, 100)) > w(&p(Method::Laa, LookAhead::Levels(2), 100)));
    assert!(w(&p(Method::Laa, LookAhead::Levels(2), 100)) > w(&p(Method::Moa, LookAhead::Max, 100)));
    assert!(w(&p(Method::Moa, LookAhead::Max, 500)) < w(&p(Method::Moa, LookAhead::Max, 100)));
    let bytes = BuildParams { leaf: LeafRule::Bytes { capacity: 1000 }, ..BuildParams::paper() };
    let sizes = vec![100u64; 1000];
    assert_eq!(
        estimate_work(1000, Some(&sizes), &bytes),
        estimate_work(1000, None, &p(Method::Moa, LookAhead::Max, 10))
    );
}

#[test]
fn a_bulk_load_reports_each_stage_in_order_from_none_done_to_all_done() {
    use mktree::bulk::{LoadProgress, Stage};
    use mktree::scene::generate::{GenOptions, Preset, generate_scene};
    use mktree::store::device::MemDevice;
    use mktree::{CreateOptions, Database};

    let scene = generate_scene(&GenOptions { preset: Preset::Tanker2, objects: None, seed: 0 }).unwrap();
    let db = Database::create_on(std::sync::Arc::new(MemDevice::new()), CreateOptions::default()).unwrap();
    let mut w = db.begin_write().unwrap();
    let seen = Mutex::new(Vec::<LoadProgress>::new());
    w.bulk_load(&scene, &BuildParams::default(), &|p| seen.lock().unwrap().push(p)).unwrap();
    w.commit().unwrap();
    let seen = seen.into_inner().unwrap();
    let mut stages: Vec<Stage> = seen.iter().map(|p| p.stage).collect();
    stages.dedup();
    let order = [
        Stage::Tree,
        Stage::Layout,
        Stage::Levels,
        Stage::Choose,
        Stage::Geometry,
        Stage::Groups,
        Stage::Nodes,
        Stage::Keys,
    ];
    assert_eq!(stages, order, "each stage once, in order");
    for stage in order {
        let of: Vec<&LoadProgress> = seen.iter().filter(|p| p.stage == stage).collect();
        let (first, last) = (of[0], of[of.len() - 1]);
        assert_eq!(first.done, 0, "{stage:?} starts at 0");
        assert!(last.total > 0 && last.done == last.total, "{stage:?} ends done: {last:?}");
        // Reports from several threads may arrive out of order, never past
        // the total, which only the tree stage's estimate lets move.
        let fixed = |p: &LoadProgress| stage == Stage::Tree || p.total == last.total;
        assert!(of.iter().all(|p| p.done <= p.total && fixed(p)), "{stage:?}: {of:?}");
    }
    // The tree stage counts object visits, trials included: every object is
    // visited at every level above its leaf, and refine's trials add more.
    let tree_last = seen.iter().rfind(|p| p.stage == Stage::Tree).unwrap();
    assert!(tree_last.total > 2 * scene.len() as u64, "{tree_last:?}");
}
