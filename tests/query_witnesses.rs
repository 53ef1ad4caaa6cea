//! Claim: the traversal decides objects both ways and every decision holds
//! for the true geometry: an object confirmed by a face of its box, by a
//! surface cell of its voxel bound, or by a subtree box inside the query
//! meets the query, and one ruled out by a box or a bound misses it; so
//! answers equal brute force, also for objects that exactly touch the query
//! (a face on the query's face, a corner on its corner). Each decision's
//! level matches its proof: boxes at level 1, voxel bounds at 2 .. M-1,
//! geometry at M.

mod common;

use common::{box_mesh, lod_db, triangle};
use mktree::geom::Aabb;
use mktree::lod::LodParams;
use mktree::query::{
    ObjectLevel, Proof, QueryAnswer, QueryOptions, Region, brute_force_region, query_region,
};
use mktree::scene::{Mesh, Object, Scene};
use proptest::prelude::*;

/// Every decision's level fits its proof.
fn levels_fit_proofs(a: &QueryAnswer, m: u8) {
    for d in &a.decided {
        let ok = match d.proof {
            Proof::BoxMisses | Proof::InsideNode | Proof::Face => d.level == 1,
            Proof::VoxelsMiss | Proof::Cell => (2..m).contains(&d.level),
            Proof::Exact => d.level == m,
            Proof::Candidate => d.level < m,
        };
        assert!(ok, "{d:?} in a file of M = {m}");
    }
}

fn decided(a: &QueryAnswer, id: u32) -> ObjectLevel {
    *a.decided.iter().find(|d| d.object.0 == id).unwrap_or_else(|| panic!("object {id} not decided"))
}

/// An L-shaped strip of thin triangles from (0, 0, 0) along x to (300, 0, 0),
/// then along y to (300, 300, 0): its box's far corner (0, 300) region is empty.
fn l_shape() -> Mesh {
    let p = |x: f64, y: f64, z: f64| mktree::geom::Point::new(x, y, z);
    let pts = [
        p(0.0, 0.0, 0.0),
        p(300.0, 0.0, 0.0),
        p(300.0, 0.0, 10.0),
        p(300.0, 300.0, 0.0),
        p(300.0, 300.0, 10.0),
        p(0.0, 0.0, 10.0),
    ];
    Mesh::from_world(&pts, vec![[0, 1, 2], [0, 2, 5], [1, 3, 4], [1, 4, 2]]).unwrap()
}

fn scene() -> Scene {
    Scene::new(vec![
        Object::new("box", box_mesh([0.0, 0.0, 0.0], [100.0, 100.0, 100.0])),
        Object::new("plate", triangle([200.0, 0.0, 50.0], [260.0, 0.0, 50.0], [200.0, 60.0, 50.0])),
        Object::new("ell", l_shape()),
        Object::new("far", box_mesh([900.0, 900.0, 900.0], [950.0, 950.0, 950.0])),
    ])
}

#[test]
fn a_query_holding_a_face_confirms_without_geometry() {
    let scene = scene();
    let db = lod_db(&scene, 3, 1024, 1, LodParams::default());
    let r = db.begin_read().unwrap();
    // Holds the box's upper z face (z = 100) whole, not the box.
    let q = Aabb::from_array([-1.0, -1.0, 50.0, 101.0, 101.0, 150.0]);
    let a = query_region(&r, &Region::Box(q), &QueryOptions::default(), None).unwrap();
    assert_eq!(a.objects, brute_force_region(&scene, &Region::Box(q)));
    assert_eq!(decided(&a, 0).proof, Proof::Face);
    assert_eq!(a.stats.reads.geometry, 0, "a face proved it: no geometry read");
    levels_fit_proofs(&a, 3);
}

#[test]
fn objects_touching_the_query_exactly_are_answers() {
    let scene = scene();
    let db = lod_db(&scene, 3, 1024, 1, LodParams::default());
    let r = db.begin_read().unwrap();
    for q in [
        [100.0, 0.0, 0.0, 150.0, 100.0, 100.0], // the box's x face on the query's face
        [100.0, 100.0, 100.0, 120.0, 120.0, 120.0], // corner to corner
        [150.0, -10.0, 50.0, 200.0, 10.0, 60.0], // the plate's corner on the query's face
        [230.0, 30.0, 50.0, 240.0, 40.0, 50.0], // a flat query inside the plate
        [101.0, 0.0, 0.0, 150.0, 100.0, 100.0], // a gap of 1 mm: no contact
    ] {
        let q = Aabb::from_array(q);
        let a = query_region(&r, &Region::Box(q), &QueryOptions::default(), None).unwrap();
        assert_eq!(a.objects, brute_force_region(&scene, &Region::Box(q)), "{q:?}");
        levels_fit_proofs(&a, 3);
    }
}

#[test]
fn a_surface_cell_held_by_the_query_confirms_and_an_empty_one_rules_out() {
    let scene = scene();
    let db = lod_db(
        &scene,
        4,
        1024,
        1,
        LodParams { store_all: true, eps: Some(vec![20.0]), ..LodParams::default() },
    );
    let r = db.begin_read().unwrap();
    // Around the ell's corner at (300, 0): holds cells of its surface, no face of its box.
    let hit = Aabb::from_array([250.0, -20.0, -20.0, 320.0, 50.0, 30.0]);
    let a = query_region(&r, &Region::Box(hit), &QueryOptions::default(), None).unwrap();
    assert_eq!(a.objects, brute_force_region(&scene, &Region::Box(hit)));
    assert_eq!(decided(&a, 2).proof, Proof::Cell, "{:?}", a.decided);
    // In the empty corner of the ell's box: its bound rules it out.
    let miss = Aabb::from_array([20.0, 200.0, 2.0, 80.0, 280.0, 8.0]);
    let a = query_region(&r, &Region::Box(miss), &QueryOptions::default(), None).unwrap();
    assert_eq!(a.objects, brute_force_region(&scene, &Region::Box(miss)));
    assert_eq!(decided(&a, 2).proof, Proof::VoxelsMiss, "{:?}", a.decided);
    levels_fit_proofs(&a, 4);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    /// Queries snapped to the objects' own coordinates (so faces and
    /// corners touch exactly) answer as brute force does, and every
    /// decision's level fits its proof.
    #[test]
    fn touching_queries_equal_brute_force(
        lo in prop::array::uniform3(prop::sample::select(vec![-10.0f64, 0.0, 50.0, 100.0, 200.0, 250.0, 260.0, 300.0])),
        hi in prop::array::uniform3(prop::sample::select(vec![0.0f64, 10.0, 50.0, 60.0, 100.0, 200.0, 300.0, 1000.0])),
        store_all in any::<bool>(),
        m in 2u8..5,
    ) {
        let scene = scene();
        let db = lod_db(&scene, m, 1024, 1, LodParams { store_all, eps: (m > 3).then(|| vec![40.0; usize::from(m) - 3]), ..LodParams::default() });
        let r = db.begin_read().unwrap();
        let q = Aabb::from_array([lo[0].min(hi[0]), lo[1].min(hi[1]), lo[2].min(hi[2]), lo[0].max(hi[0]), lo[1].max(hi[1]), lo[2].max(hi[2])]);
        let a = query_region(&r, &Region::Box(q), &QueryOptions::default(), None).unwrap();
        prop_assert_eq!(&a.objects, &brute_force_region(&scene, &Region::Box(q)));
        levels_fit_proofs(&a, m);
    }
}
