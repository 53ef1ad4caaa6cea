//! Claim: a box query through the file returns exactly the objects whose
//! triangles meet the box, the same set as testing every object, for every
//! bulk-loading method, block size and leaf rule.

mod common;

use common::{arb_scene, grid_scene, mem_db};
use mktree::bulk::{BuildParams, LeafRule, LookAhead, Method};
use mktree::db::CreateOptions;
use mktree::geom::Aabb;
use mktree::query::{QueryOptions, Region, brute_force_region, query_region};
use proptest::prelude::*;

fn methods() -> Vec<BuildParams> {
    let p =
        |method, leaf| BuildParams { method, leaf, look_ahead: LookAhead::Levels(2), ..BuildParams::paper() };
    vec![
        p(Method::Moa, LeafRule::Objects(4)),
        p(Method::Laa, LeafRule::Objects(3)),
        p(Method::Median, LeafRule::Bytes { capacity: 1000 }),
        p(Method::Hilbert, LeafRule::Objects(5)),
        p(Method::Sah, LeafRule::Objects(2)),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]
    #[test]
    fn box_queries_equal_brute_force(
        scene in arb_scene(60),
        q in (prop::array::uniform3(-100.0f64..1100.0), prop::array::uniform3(0.0f64..500.0)),
        which in 0usize..5,
        block_size in prop::sample::select(vec![1024u32, 2048, 4096]),
    ) {
        let params = &methods()[which];
        let (db, _) = mem_db(&scene, params, CreateOptions { block_size, lod_levels: 3 });
        let query = Aabb::from_array([q.0[0], q.0[1], q.0[2], q.0[0] + q.1[0], q.0[1] + q.1[1], q.0[2] + q.1[2]]);
        let got = query_region(&db.begin_read().unwrap(), &Region::Box(query), &QueryOptions::default(), None).unwrap();
        prop_assert_eq!(got.objects, brute_force_region(&scene, &Region::Box(query)));
    }
}

#[test]
fn a_query_over_everything_returns_everything_from_the_node_blocks_alone() {
    let scene = grid_scene(500);
    let params = BuildParams { leaf: LeafRule::Objects(10), ..BuildParams::paper() };
    let (db, _) = mem_db(&scene, &params, CreateOptions { block_size: 1024, lod_levels: 2 });
    let r = db.begin_read().unwrap();
    let info = r.info().unwrap();
    let q = |b: Aabb| query_region(&r, &Region::Box(b), &QueryOptions::default(), None).unwrap();
    // The query holds the root's box: every object is answered by it, with no read below the root.
    let all = q(scene.aabb().grown(1.0));
    assert_eq!(all.objects.len(), 500);
    assert_eq!(all.stats.reads.geometry, 0);
    assert!(all.stats.reads.node <= u64::from(info.node_blocks));
    let none = q(Aabb::from_array([-500.0, -500.0, -500.0, -400.0, -400.0, -400.0]));
    assert!(none.objects.is_empty());
    assert_eq!(none.stats.reads.total(), 0, "the root's box, in the meta block, rules it out");
}

/// Scenes of wavy strips of 60 to 400 triangles: each is larger than a
/// 1,024-byte block, so the file stores it as parts.
fn arb_big_scene() -> impl Strategy<Value = mktree::scene::Scene> {
    let strip = (prop::array::uniform3(0.0f64..800.0), 30usize..200, 1.0f64..8.0, any::<u64>());
    prop::collection::vec(strip, 1..8).prop_map(|v| {
        mktree::scene::Scene::new(
            v.into_iter()
                .enumerate()
                .map(|(i, (o, n, step, seed))| {
                    let points: Vec<mktree::geom::Point> = (0..2 * n)
                        .map(|j| {
                            let t = (j / 2) as f64 * step;
                            let wave = ((seed % 7) as f64 + 1.0) * (t / 40.0).sin() * 10.0;
                            [o[0] + t, o[1] + wave + (j % 2) as f64 * 20.0, o[2] + (t / 30.0).cos() * 15.0]
                                .into()
                        })
                        .collect();
                    let tris = (0..2 * n as u32 - 2).map(|j| [j, j + 1, j + 2]).collect();
                    mktree::scene::Object::new(
                        format!("strip{i}"),
                        mktree::scene::Mesh::from_world(&points, tris).expect("a strip"),
                    )
                })
                .collect(),
        )
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]
    /// Objects larger than a block are stored as parts: box queries and
    /// `check` see each object once, and answers equal brute force.
    #[test]
    fn objects_stored_as_parts_answer_exactly(
        scene in arb_big_scene(),
        q in (prop::array::uniform3(-100.0f64..1100.0), prop::array::uniform3(0.0f64..300.0)),
    ) {
        let params = BuildParams { leaf: LeafRule::Objects(3), ..BuildParams::paper() };
        // 2 KiB blocks: the strips (1.4 to 9.6 KB) are still stored in up to
        // 6 parts, and 3 objects' parts always fit a node record. At 1 KiB,
        // a leaf of 3 strips in 10 parts each outgrows its record, which a
        // bulk load refuses (use smaller leaves or larger blocks).
        let (db, _) = mem_db(&scene, &params, CreateOptions { block_size: 2048, lod_levels: 3 });
        let report = mktree::db::check(&db).unwrap();
        prop_assert!(report.ok(), "{:?}", report.faults);
        let r = db.begin_read().unwrap();
        prop_assert_eq!(r.info().unwrap().triangles, scene.triangle_count() as u64);
        let query = Aabb::from_array([q.0[0], q.0[1], q.0[2], q.0[0] + q.1[0], q.0[1] + q.1[1], q.0[2] + q.1[2]]);
        let got = query_region(&r, &Region::Box(query), &QueryOptions::default(), None).unwrap();
        prop_assert_eq!(&got.objects, &brute_force_region(&scene, &Region::Box(query)));
        prop_assert_eq!(got.decided.len(), got.decided.iter().map(|d| d.object).collect::<std::collections::BTreeSet<_>>().len());
        let meshes = mktree::query::object_meshes(&r, &[mktree::scene::ObjectId(0)]).unwrap();
        prop_assert_eq!(meshes[0].triangle_count(), scene.objects()[0].mesh.triangle_count());
        prop_assert_eq!(meshes[0].aabb(), scene.objects()[0].mesh.aabb());
        // A collision probe made of parts, against objects made of parts.
        let pose = mktree::geom::Pose::from_degrees([q.1[0] / 10.0, 0.0, q.1[2] / 10.0], [0.0, 0.0, q.1[1] / 10.0]).unwrap();
        let opts = mktree::query::CollideOptions { clearance: q.1[0] / 100.0, ..Default::default() };
        let got = mktree::query::collide(&r, &meshes[0], &pose, &opts, None).unwrap();
        let want = mktree::query::brute_force_collide(&scene, &scene.objects()[0].mesh, &pose, opts.clearance, None).unwrap();
        prop_assert_eq!(got.objects, want);
    }
}
