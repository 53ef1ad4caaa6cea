//! Claim: one contact rule for every query. Objects and query boxes are
//! closed sets, and two of them touch when they share a point (distance 0):
//! a shared face, edge or vertex counts, one rounding step apart does not.
//! Clash reports exactly the unordered pairs that collide of each object
//! reports, collide of a holds b exactly when collide of b holds a, and both
//! equal brute force: on exact contacts at decimal coordinates binary cannot
//! hold, on the tanker2 preset, and on random touching boxes (with and
//! without a clearance).

mod common;

use std::collections::BTreeSet;

use common::{box_mesh, lod_db, mem_db, triangle};
use mktree::bulk::BuildParams;
use mktree::db::{CreateOptions, Database};
use mktree::geom::{Aabb, Pose, Vector};
use mktree::lod::LodParams;
use mktree::query::{
    ClashOptions, CollideOptions, QueryOptions, Region, brute_force_clash, brute_force_collide,
    brute_force_region, clash, collide, object_meshes, query_region,
};
use mktree::scene::generate::{GenOptions, Preset, generate_scene};
use mktree::scene::{Mesh, Object, ObjectId, Scene};
use proptest::prelude::*;

type Pair = (ObjectId, ObjectId);

/// `meshes` as a scene, after 40 boxes far off so the tree has inner nodes
/// and quantized boxes; the meshes are the last objects.
fn with_filler(meshes: Vec<Mesh>) -> (Scene, Vec<ObjectId>) {
    let filler = (0..40).map(|i| {
        let lo = [100.0 + f64::from(i % 5) * 3.1, 100.0 + f64::from(i / 5) * 2.7, 50.3];
        box_mesh(lo, [lo[0] + 1.3, lo[1] + 0.9, lo[2] + 2.2])
    });
    let objects: Vec<Object> =
        filler.chain(meshes).enumerate().map(|(i, m)| Object::new(format!("o{i}"), m)).collect();
    let ids = (40..objects.len() as u32).map(ObjectId).collect();
    (Scene::new(objects), ids)
}

/// Collide of every object in `probes` at level M, as ordered pairs.
fn collide_pairs(db: &Database, probes: &[ObjectId], d: f64) -> BTreeSet<Pair> {
    let r = db.begin_read().unwrap();
    let meshes = object_meshes(&r, probes).unwrap();
    let mut pairs = BTreeSet::new();
    for (&a, mesh) in probes.iter().zip(&meshes) {
        let opts = CollideOptions { clearance: d, exclude: Some(a), ..Default::default() };
        let got = collide(&r, mesh, &Pose::default(), &opts, Some(r.cache())).unwrap();
        pairs.extend(got.objects.into_iter().map(|b| (a, b)));
    }
    pairs
}

fn clash_pairs(db: &Database, d: f64) -> BTreeSet<Pair> {
    let r = db.begin_read().unwrap();
    clash(&r, &ClashOptions { lod: None, clearance: d }, None).unwrap().pairs.into_iter().collect()
}

/// Ordered pairs as unordered ones, lower id first.
fn unordered(pairs: &BTreeSet<Pair>) -> BTreeSet<Pair> {
    pairs.iter().map(|&(a, b)| (a.min(b), a.max(b))).collect()
}

/// Ordered pairs (a, b) of `pairs` whose reverse is missing.
fn one_way(pairs: &BTreeSet<Pair>) -> Vec<Pair> {
    pairs.iter().filter(|(a, b)| !pairs.contains(&(*b, *a))).copied().collect()
}

/// Clash equals the union of collide over every object and brute force;
/// collide is symmetric and equals brute force for every object; and every
/// level below M answers a superset. Returns the pairs.
fn check_everything(scene: &Scene, db: &Database, d: f64) -> BTreeSet<Pair> {
    let all: Vec<ObjectId> = (0..scene.len() as u32).map(ObjectId).collect();
    let exact: BTreeSet<Pair> = brute_force_clash(scene, d).unwrap().into_iter().collect();
    let collided = collide_pairs(db, &all, d);
    assert_eq!(one_way(&collided), vec![], "collide is symmetric");
    assert_eq!(unordered(&collided), exact, "collide over every object is brute force");
    assert_eq!(clash_pairs(db, d), exact, "clash is brute force");
    let r = db.begin_read().unwrap();
    for (&a, mesh) in all.iter().zip(&object_meshes(&r, &all).unwrap()) {
        let oracle = brute_force_collide(scene, mesh, &Pose::default(), d, Some(a)).unwrap();
        let mine: Vec<ObjectId> = collided.iter().filter(|p| p.0 == a).map(|p| p.1).collect();
        assert_eq!(mine, oracle, "collide of {a}");
        for k in 1..db.lod_levels() {
            let q = QueryOptions { lod: Some(k), ..Default::default() };
            let opts = CollideOptions { query: q, clearance: d, exclude: Some(a) };
            let got = collide(&r, mesh, &Pose::default(), &opts, None).unwrap().objects;
            assert!(
                oracle.iter().all(|o| got.contains(o)),
                "collide of {a} at level {k} misses some of {oracle:?}"
            );
        }
    }
    for k in 1..db.lod_levels() {
        let got = clash(&r, &ClashOptions { lod: Some(k), clearance: d }, None).unwrap().pairs;
        assert!(exact.iter().all(|p| got.contains(p)), "clash at level {k} misses a pair");
    }
    exact
}

/// The pairs of the touching objects of `meshes` among the filler; each
/// mesh touches the first or not as `touches` says, and nothing else.
fn contact_case(what: &str, meshes: Vec<Mesh>, touches: bool) {
    let (scene, ids) = with_filler(meshes);
    for db in [
        lod_db(&scene, 3, 2048, 4, LodParams::default()),
        mem_db(&scene, &BuildParams::for_blocks(16 * 1024), CreateOptions::default()).0,
    ] {
        let pairs = check_everything(&scene, &db, 0.0);
        let want: BTreeSet<Pair> =
            if touches { ids[1..].iter().map(|&b| (ids[0], b)).collect() } else { BTreeSet::new() };
        assert_eq!(pairs, want, "{what}");
    }
}

/// Two boxes with faces at decimal millimetres binary cannot hold: a small
/// cube, and a long thin plate like tanker2's (where parry's GJK missed
/// contacts and answered differently by order). Each mesh stores its upper
/// corner as its lower one plus f32 offsets; returned with the mesh, it is
/// where the tests make things touch. A mesh's lower corner is stored
/// exactly (the anchor of its offsets), so an object whose lower corner is
/// set to a box's stored upper face touches it exactly.
fn boxes() -> [(Mesh, [f64; 3]); 2] {
    [box_mesh([0.1, 0.1, 0.1], [0.7, 0.7, 0.7]), box_mesh([0.1, 0.1, 1832.7], [4330.7, 14.1, 3651.3])].map(
        |m| {
            let top = m.aabb().max;
            (m, [top.x, top.y, top.z])
        },
    )
}

/// A point `f` of the way across box `a` on each axis (`f` > 1: beyond it).
fn across(a: &Mesh, f: [f64; 3]) -> [f64; 3] {
    let b = a.aabb();
    std::array::from_fn(|i| b.min[i] + (b.max[i] - b.min[i]) * f[i])
}

#[test]
fn boxes_sharing_part_of_a_face_touch() {
    for (a, [_, y, _]) in boxes() {
        // A slab on the upper y face, crossing the box's z range.
        let (lo, hi) = (across(&a, [0.6, 0.0, -0.5]), across(&a, [0.62, 3.0, 1.5]));
        contact_case("a face", vec![a, box_mesh([lo[0], y, lo[2]], hi)], true);
    }
}

#[test]
fn boxes_sharing_only_an_edge_touch() {
    for (a, [x, y, _]) in boxes() {
        let (lo, hi) = (across(&a, [0.0, 0.0, -0.5]), across(&a, [1.5, 3.0, 1.5]));
        contact_case("an edge", vec![a, box_mesh([x, y, lo[2]], hi)], true);
    }
}

#[test]
fn boxes_sharing_only_a_corner_touch() {
    for (a, [x, y, z]) in boxes() {
        let hi = across(&a, [1.5, 3.0, 1.5]);
        contact_case("a corner", vec![a, box_mesh([x, y, z], hi)], true);
    }
}

#[test]
fn triangles_with_a_corner_on_a_face_on_it_or_along_an_edge_touch() {
    for (a, [x, y, _]) in boxes() {
        // A corner on the upper y face, the rest beyond it.
        let (c, p, q) =
            (across(&a, [0.4, 0.0, 0.3]), across(&a, [0.5, 2.0, 0.6]), across(&a, [0.45, 3.0, 0.7]));
        let t = triangle([c[0], y, c[2]], p, q);
        contact_case("a corner on a face", vec![a.clone(), t], true);
        // A triangle lying on that face, and one along the box's edge.
        let (c, p, q) =
            (across(&a, [0.1, 0.0, 0.1]), across(&a, [0.9, 0.0, 0.2]), across(&a, [0.2, 0.0, 1.5]));
        let lying = triangle([c[0], y, c[2]], [p[0], y, p[2]], [q[0], y, q[2]]);
        let (c, p, q) =
            (across(&a, [0.0, 0.0, 0.2]), across(&a, [1.5, 3.0, 0.2]), across(&a, [0.0, 0.0, 0.7]));
        let edge = triangle([x, y, c[2]], p, [x, y, q[2]]);
        contact_case("on a face and along an edge", vec![a, lying, edge], true);
    }
}

#[test]
fn one_rounding_step_apart_is_apart() {
    for (a, [x, y, z]) in boxes() {
        let (lo, hi) = (across(&a, [0.6, 0.0, -0.5]), across(&a, [0.62, 3.0, 1.5]));
        contact_case(
            "a face one step off",
            vec![a.clone(), box_mesh([lo[0], y.next_up(), lo[2]], hi)],
            false,
        );
        let hi = across(&a, [1.5, 3.0, 1.5]);
        contact_case("a corner one step off", vec![a.clone(), box_mesh([x.next_up(), y, z], hi)], false);
        let (c, p, q) =
            (across(&a, [0.4, 0.0, 0.3]), across(&a, [0.5, 2.0, 0.6]), across(&a, [0.45, 3.0, 0.7]));
        let t = triangle([c[0], y.next_up(), c[2]], p, q);
        contact_case("a triangle corner one step off a face", vec![a, t], false);
    }
}

#[test]
fn a_region_box_touching_a_face_an_edge_or_a_corner_finds_the_object() {
    for (a, [x, y, z]) in boxes() {
        let (lo, hi) = (a.aabb().min, across(&a, [1.5, 1.5, 1.5]));
        let mid = across(&a, [0.3, 0.3, 0.3]);
        let (scene, ids) = with_filler(vec![a]);
        let db = lod_db(&scene, 3, 2048, 4, LodParams::default());
        let r = db.begin_read().unwrap();
        let below = lo - Vector::repeat(0.5);
        for (q, touches) in [
            ([x, mid[1], mid[2], hi[0], hi[1], hi[2]], true),
            ([x, y, mid[2], hi[0], hi[1], hi[2]], true),
            ([x, y, z, hi[0], hi[1], hi[2]], true),
            ([below.x, below.y, below.z, lo.x, lo.y, lo.z], true),
            ([x.next_up(), mid[1], mid[2], hi[0], hi[1], hi[2]], false),
            ([x, y.next_up(), z, hi[0], hi[1], hi[2]], false),
            ([below.x, below.y, below.z, lo.x, lo.y, lo.z.next_down()], false),
        ] {
            let region = Region::Box(Aabb::from_array(q));
            let oracle = brute_force_region(&scene, &region);
            assert_eq!(oracle, if touches { ids.clone() } else { vec![] }, "brute force, {q:?}");
            for k in 1..=db.lod_levels() {
                let opts = QueryOptions { lod: Some(k), ..Default::default() };
                let got = query_region(&r, &region, &opts, None).unwrap();
                if k == db.lod_levels() {
                    assert_eq!(got.objects, oracle, "{q:?}");
                } else {
                    assert!(oracle.iter().all(|o| got.objects.contains(o)), "{q:?} at level {k}");
                }
            }
            assert_eq!(r.query_box(&Aabb::from_array(q)).unwrap().objects, oracle, "query_box {q:?}");
        }
    }
}

/// The measured failure: on tanker2, collide over all 3,900 objects found
/// 48 pairs clash missed, and 129 ordered pairs had no reverse (parry's GJK
/// on touching faces). With a clearance, too.
#[test]
fn tanker2_clash_is_the_union_of_a_symmetric_collide() {
    let scene = generate_scene(&GenOptions { preset: Preset::Tanker2, objects: None, seed: 0 }).unwrap();
    let (db, _) = mem_db(&scene, &BuildParams::for_blocks(16 * 1024), CreateOptions::default());
    let all: Vec<ObjectId> = (0..scene.len() as u32).map(ObjectId).collect();
    for d in [0.0, 50.0] {
        let collided = collide_pairs(&db, &all, d);
        let clashed = clash_pairs(&db, d);
        let missed: Vec<_> = unordered(&collided).difference(&clashed).copied().collect();
        let extra: Vec<_> = clashed.difference(&unordered(&collided)).copied().collect();
        assert_eq!(
            (missed.len(), extra.len(), one_way(&collided).len()),
            (0, 0, 0),
            "d {d}: missed {missed:?}, extra {extra:?}"
        );
        assert!(clashed.len() > 10_000, "tanker2 is full of touching parts: {}", clashed.len());
    }
}

/// A box on a grid of 0.25 mm steps from 5000.1 mm (not exact in binary,
/// but every step from it is, and so is every f32 offset of a mesh there:
/// faces that meet on the grid meet in the stored geometry).
fn grid_box(lo: [u16; 3], size: [u16; 3]) -> Aabb {
    let at = |n: u16| 5000.1 + f64::from(n) * 0.25;
    Aabb::new(lo.map(at).into(), std::array::from_fn::<_, 3, _>(|i| at(lo[i] + size[i])).into())
}

/// Grid boxes from cubes to long thin plates (as a ship's are): starts a
/// few steps apart, sides of 1 to 4,000 steps, so faces coincide often.
fn arb_grid_box() -> impl Strategy<Value = Aabb> {
    let side = prop::sample::select(vec![1u16, 2, 3, 56, 4000]);
    (prop::array::uniform3(0u16..6), prop::array::uniform3(side)).prop_map(|(lo, size)| grid_box(lo, size))
}

/// `x` lies in the interior of `y`.
fn inside(x: &Aabb, y: &Aabb) -> bool {
    (0..3).all(|i| y.min[i] < x.min[i] && x.max[i] < y.max[i])
}

/// The surfaces of closed boxes a and b meet when the boxes do and neither
/// lies in the other's interior.
fn surfaces_meet(a: &Aabb, b: &Aabb) -> bool {
    a.intersects(b) && !inside(a, b) && !inside(b, a)
}

/// The closed box q meets the surface of box b when it meets b and does not
/// lie in b's interior.
fn region_meets_surface(q: &Aabb, b: &Aabb) -> bool {
    q.intersects(b) && !inside(q, b)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]
    /// Boxes (and triangles across them) on a coarse grid share faces,
    /// edges and corners all the time: clash, collide and brute force agree,
    /// collide is symmetric, and for two boxes the answer is what boxes say.
    #[test]
    fn touching_grid_objects_agree_everywhere(
        objects in prop::collection::vec((arb_grid_box(), any::<bool>()), 2..10),
        queries in prop::collection::vec(arb_grid_box(), 1..4),
        m in 2u8..=4,
        cap in 1u32..4,
    ) {
        let meshes = objects.iter().map(|(b, solid)| {
            let (lo, hi) = (b.min, b.max);
            if *solid {
                Mesh::of_box(b).unwrap()
            } else {
                triangle([lo.x, lo.y, lo.z], [hi.x, lo.y, hi.z], [lo.x, hi.y, hi.z])
            }
        });
        let scene = Scene::new(meshes.enumerate().map(|(i, m)| Object::new(format!("o{i}"), m)).collect());
        let db = lod_db(&scene, m, 2048, cap, LodParams::default());
        let pairs = check_everything(&scene, &db, 0.0);
        for (i, (a, a_box)) in objects.iter().enumerate() {
            for (j, (b, b_box)) in objects.iter().enumerate().skip(i + 1) {
                if *a_box && *b_box {
                    let pair = (ObjectId(i as u32), ObjectId(j as u32));
                    prop_assert_eq!(pairs.contains(&pair), surfaces_meet(a, b), "{:?} {:?}", a, b);
                }
            }
        }
        let r = db.begin_read().unwrap();
        for q in &queries {
            let region = Region::Box(*q);
            let oracle = brute_force_region(&scene, &region);
            for (i, (b, solid)) in objects.iter().enumerate() {
                if *solid {
                    let found = oracle.contains(&ObjectId(i as u32));
                    prop_assert_eq!(found, region_meets_surface(q, b), "{:?} {:?}", q, b);
                }
            }
            let got = query_region(&r, &region, &QueryOptions::default(), None).unwrap();
            prop_assert_eq!(&got.objects, &oracle);
        }
    }

    /// With a clearance of whole grid steps, distances tie with it all the
    /// time: still clash, collide and brute force agree, and collide is
    /// symmetric.
    #[test]
    fn clearances_on_the_grid_agree_everywhere(
        objects in prop::collection::vec(arb_grid_box(), 2..8),
        d in prop::sample::select(vec![0.25, 0.5, 14.0]),
        m in 2u8..=4,
    ) {
        let boxes = objects.iter().map(|b| Mesh::of_box(b).unwrap());
        let scene = Scene::new(boxes.enumerate().map(|(i, m)| Object::new(format!("o{i}"), m)).collect());
        let db = lod_db(&scene, m, 2048, 2, LodParams::default());
        check_everything(&scene, &db, d);
    }
}
