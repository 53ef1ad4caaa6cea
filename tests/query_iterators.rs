//! Claim: the traversal is a lazy iterator. `select` yields exactly the
//! objects `traverse` answers, with the same reads once drained, and a
//! caller that stops early reads no more; `nearest` yields every object by
//! its exact distance, non-decreasing, ties by id, as brute force measures
//! it; `ray` yields the objects a ray meets in order of t, its first hit the
//! least t over brute force's exact intersections; and `take(k)` of either
//! reads no more than the whole.

mod common;

use common::{arb_scene, grid_scene, lod_db};
use mktree::geom::{Aabb, Point, Ray, Sphere, Vector};
use mktree::lod::LodParams;
use mktree::query::{QueryOptions, Region, brute_force_nearest, brute_force_ray, traverse};
use proptest::prelude::*;

fn arb_point() -> impl Strategy<Value = Point> {
    prop::array::uniform3(-300.0f64..1400.0).prop_map(Point::from)
}

fn arb_ray() -> impl Strategy<Value = Ray> {
    let dir = prop::array::uniform3(-1.0f64..1.0).prop_filter("a direction", |d| d.iter().any(|&c| c != 0.0));
    // Axis-aligned directions too: they graze box faces and touch edges.
    let axis = (0usize..3, any::<bool>()).prop_map(|(i, up)| {
        let mut d = [0.0; 3];
        d[i] = if up { 1.0 } else { -1.0 };
        d
    });
    (arb_point(), prop_oneof![dir, axis], prop::option::of(0.0f64..2000.0))
        .prop_map(|(o, d, max)| Ray::new(o, Vector::from(d), max).expect("a valid ray"))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn select_yields_the_answer_and_stopping_early_reads_less(
        scene in arb_scene(40),
        lo in prop::array::uniform3(-100.0f64..1100.0),
        side in 0.0f64..700.0,
        m in 2u8..=4,
        cap in 1u32..6,
        stop in 0usize..6,
        budget in prop::option::of(0u64..12),
    ) {
        let db = lod_db(&scene, m, 2048, cap, LodParams::default());
        let r = db.begin_read().unwrap();
        let region = Region::Box(Aabb::from_array([lo[0], lo[1], lo[2], lo[0] + side, lo[1] + side, lo[2] + side]));
        for k in 1..=m {
            let opts = QueryOptions { lod: Some(k), budget, ..Default::default() };
            let whole = traverse(&r, &region, &opts, None).unwrap();
            let mut it = r.select(&region, &opts, None).unwrap();
            prop_assert_eq!(it.stats().reads.total(), 0, "nothing is read before the first hit is asked for");
            let mut got: Vec<_> = it.by_ref().map(|h| h.unwrap().object).collect();
            got.sort_unstable();
            prop_assert_eq!(&got, &whole.objects);
            prop_assert_eq!(it.stats().reads, whole.stats.reads);
            prop_assert_eq!(it.maybe(), &whole.maybe[..]);
            prop_assert_eq!(it.unexplored_nodes(), whole.unexplored_nodes);
            prop_assert_eq!(it.level_reached(), Some(whole.level_reached));

            let mut early = r.select(&region, &opts, None).unwrap();
            let first: Vec<_> = early.by_ref().take(stop).map(|h| h.unwrap()).collect();
            prop_assert!(early.stats().reads.total() <= whole.stats.reads.total());
            for h in &first {
                prop_assert!(whole.objects.contains(&h.object));
                prop_assert!(h.level <= k);
            }
        }
    }

    #[test]
    fn nearest_is_brute_force_in_order(
        scene in arb_scene(40),
        point in arb_point(),
        m in 2u8..=4,
        cap in 1u32..6,
        k in 1usize..6,
    ) {
        let db = lod_db(&scene, m, 2048, cap, LodParams::default());
        let r = db.begin_read().unwrap();
        let exact = brute_force_nearest(&scene, &point);
        let mut all = r.nearest(point, None).unwrap();
        let got: Vec<_> = all.by_ref().map(|x| x.unwrap()).collect();
        prop_assert_eq!(&got, &exact);
        prop_assert!(got.windows(2).all(|w| w[0].distance <= w[1].distance), "distances never decrease");
        let mut first = r.nearest(point, None).unwrap();
        let top: Vec<_> = first.by_ref().take(k).map(|x| x.unwrap()).collect();
        prop_assert_eq!(&top[..], &exact[..k.min(exact.len())]);
        prop_assert!(first.stats().reads.total() <= all.stats().reads.total());
    }

    #[test]
    fn ray_hits_are_brute_force_in_order(
        scene in arb_scene(40),
        ray in arb_ray(),
        m in 2u8..=4,
        cap in 1u32..6,
        store_all in any::<bool>(),
    ) {
        let db = lod_db(&scene, m, 2048, cap, LodParams { store_all, ..LodParams::default() });
        let r = db.begin_read().unwrap();
        let exact = brute_force_ray(&scene, &ray);
        let mut all = r.ray(&ray, None).unwrap();
        let got: Vec<_> = all.by_ref().map(|x| x.unwrap()).collect();
        prop_assert_eq!(&got, &exact);
        prop_assert!(got.windows(2).all(|w| w[0].t <= w[1].t), "t never decreases");
        let least = exact.iter().map(|h| h.t).fold(f64::INFINITY, f64::min);
        let first = r.first_hit(&ray, None).unwrap();
        prop_assert_eq!(first.as_ref().map(|h| h.t), exact.first().map(|h| h.t));
        if let Some(h) = first {
            prop_assert_eq!(h.t, least);
            prop_assert!(ray.max_distance().is_none_or(|d| h.t <= d));
        }
        let mut one = r.ray(&ray, None).unwrap();
        one.next();
        prop_assert!(one.stats().reads.total() <= all.stats().reads.total());
    }
}

/// On a grid of boxes, the first few of a large query read a fraction of
/// what the whole does.
#[test]
fn stopping_after_a_few_hits_reads_a_few_blocks() {
    let scene = grid_scene(400);
    let db = lod_db(&scene, 3, 2048, 4, LodParams::default());
    let r = db.begin_read().unwrap();
    let everything = Region::Sphere(Sphere::new(scene.aabb().center(), 1e5).unwrap());
    let whole = traverse(&r, &everything, &QueryOptions::default(), None).unwrap();
    assert_eq!(whole.objects.len(), 400);
    let mut it = r.select(&everything, &QueryOptions::default(), None).unwrap();
    assert_eq!(it.by_ref().take(3).count(), 3);
    assert!(
        it.stats().reads.total() * 4 < whole.stats.reads.total(),
        "{} of {}",
        it.stats().reads.total(),
        whole.stats.reads.total()
    );
    let mut near = r.nearest(Point::new(0.0, 0.0, 0.0), None).unwrap();
    let n = near.next().unwrap().unwrap();
    assert_eq!((n.object.0, n.key.as_int(), n.distance), (0, Some(0), 0.0), "the point is a corner of box 0");
    assert!(near.stats().reads.total() * 4 < whole.stats.reads.total());
}

/// A ray along a row of the grid meets its eight boxes in order, the
/// first at its face, and stops at its maximum.
#[test]
fn a_ray_along_a_row_meets_its_boxes_in_order() {
    let scene = grid_scene(400);
    let db = lod_db(&scene, 3, 2048, 4, LodParams::default());
    let r = db.begin_read().unwrap();
    let ray = Ray::new(Point::new(-100.0, 20.0, 40.0), Vector::x(), None).unwrap();
    let hits: Vec<_> = r.ray(&ray, None).unwrap().map(|h| h.unwrap()).collect();
    assert_eq!(hits.len(), 8);
    assert_eq!((hits[0].object.0, hits[0].t, hits[0].point), (0, 100.0, [0.0, 20.0, 40.0]));
    assert!(hits.windows(2).all(|w| w[0].t < w[1].t));
    assert_eq!(hits, brute_force_ray(&scene, &ray));
    let short = Ray::new(ray.origin(), Vector::x(), Some(99.0)).unwrap();
    assert_eq!(r.first_hit(&short, None).unwrap(), None);
    let touching = Ray::new(ray.origin(), Vector::x(), Some(100.0)).unwrap();
    assert_eq!(
        r.first_hit(&touching, None).unwrap().map(|h| h.object.0),
        Some(0),
        "reaching the face counts"
    );
}

#[test]
fn an_empty_database_yields_nothing() {
    let db = mktree::db::Database::create_on(
        std::sync::Arc::new(mktree::store::device::MemDevice::new()),
        Default::default(),
    )
    .unwrap();
    let r = db.begin_read().unwrap();
    assert!(r.nearest(Point::origin(), None).unwrap().next().is_none());
    let ray = Ray::new(Point::origin(), Vector::x(), None).unwrap();
    assert!(r.first_hit(&ray, None).unwrap().is_none());
    let region = Region::Box(Aabb::from_array([0.0; 6]));
    let mut it = r.select(&region, &QueryOptions::default(), None).unwrap();
    assert!(it.next().is_none());
    assert!(r.nearest(Point::new(f64::NAN, 0.0, 0.0), None).is_err());
}
