//! Claim: a box, sphere or frustum query through the levels of detail equals
//! brute force over every object at k = M, returns a superset at every
//! k < M (it never misses an object), and a budgeted query never reads more
//! blocks than its budget, confirms only true answers, and with a budget
//! large enough gives the unbudgeted answer.

mod common;

use common::{arb_scene, lod_db};
use mktree::geom::{Aabb, Camera, Frustum, Point, Sphere};
use mktree::lod::LodParams;
use mktree::query::{QueryOptions, Region, brute_force_region, query_region};
use proptest::prelude::*;

fn arb_region() -> impl Strategy<Value = Region> {
    let corner = prop::array::uniform3(-100.0f64..1100.0);
    let boxes = (corner.clone(), prop::array::uniform3(0.0f64..500.0)).prop_map(|(lo, s)| {
        Region::Box(Aabb::from_array([lo[0], lo[1], lo[2], lo[0] + s[0], lo[1] + s[1], lo[2] + s[2]]))
    });
    let spheres = (corner.clone(), 0.0f64..400.0)
        .prop_map(|(c, r)| Region::Sphere(Sphere::new(Point::from(c), r).expect("valid")));
    let frusta = (corner.clone(), corner, 10.0f64..120.0, 0.5f64..2.0, 1.0f64..50.0, 100.0f64..1500.0)
        .prop_filter_map("a valid camera", |(eye, target, fov_deg, aspect, near, far)| {
            let cam = Camera { eye: eye.into(), target: target.into(), fov_deg, aspect, near, far };
            Frustum::from_camera(&cam).ok().map(|f| Region::Frustum(Box::new(f)))
        });
    prop_oneof![boxes, spheres, frusta]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(40))]
    #[test]
    fn region_queries_are_exact_at_m_and_supersets_below(
        scene in arb_scene(50),
        region in arb_region(),
        m in 2u8..=5,
        cap in 1u32..6,
        store_all in any::<bool>(),
    ) {
        let db = lod_db(&scene, m, 2048, cap, LodParams { store_all, ..LodParams::default() });
        let r = db.begin_read().unwrap();
        let exact = brute_force_region(&scene, &region);
        for k in 1..=m {
            let got = query_region(&r, &region, &QueryOptions { lod: Some(k), budget: None, ..Default::default() }, None).unwrap();
            prop_assert!(got.maybe.is_empty() && got.unexplored_nodes == 0 && got.level_reached == k);
            if k == m {
                prop_assert_eq!(&got.objects, &exact, "k = M is exact");
            } else {
                for o in &exact {
                    prop_assert!(got.objects.contains(o), "level {} missed object {}", k, o);
                }
            }
            prop_assert_eq!(got.stats.confirmed.len(), usize::from(m));
        }
    }

    #[test]
    fn budgets_are_never_exceeded_and_confirm_only_true_answers(
        scene in arb_scene(50),
        region in arb_region(),
        budget in 0u64..12,
    ) {
        let db = lod_db(&scene, 4, 1024, 3, LodParams { store_all: true, ..LodParams::default() });
        let r = db.begin_read().unwrap();
        let exact = brute_force_region(&scene, &region);
        let got = query_region(&r, &region, &QueryOptions { lod: None, budget: Some(budget), ..Default::default() }, None).unwrap();
        prop_assert!(got.stats.reads.total() <= budget, "{} reads for a budget of {}", got.stats.reads.total(), budget);
        for o in &got.objects {
            prop_assert!(exact.contains(o), "confirmed {} is not an answer", o);
        }
        // What was not confirmed was either refuted or is still pending.
        let pending = got.unexplored_nodes > 0 || !got.maybe.is_empty();
        for o in &exact {
            prop_assert!(got.objects.contains(o) || got.maybe.contains(o) || got.unexplored_nodes > 0,
                "object {} lost: neither confirmed, maybe nor in an unexplored subtree", o);
        }
        if !pending {
            prop_assert_eq!(&got.objects, &exact);
            prop_assert_eq!(got.level_reached, 4);
        }
        let free = query_region(&r, &region, &QueryOptions::default(), None).unwrap();
        let ample = query_region(&r, &region, &QueryOptions { lod: None, budget: Some(free.stats.reads.total()), ..Default::default() }, None).unwrap();
        prop_assert_eq!(&ample.objects, &exact, "a budget of the unbudgeted reads suffices");
        prop_assert!(ample.maybe.is_empty() && ample.unexplored_nodes == 0);
    }
}
