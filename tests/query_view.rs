//! Claim: a view's cut covers everything the camera sees (every object an
//! exact frustum query finds is shown, exact or inside a stand-in), each
//! thing shown is exact or has an error that, projected from its box's
//! nearest visible point (computed exactly, by clipping the box to the
//! frustum), is at most τ pixels, and each stand-in is really within its
//! error of the object it stands for. Pieces come front to back. Under a
//! block budget the cut reads at most the budget, still covers everything
//! visible, and reports the largest error it kept; a budget that suffices
//! gives the unbudgeted cut.

mod common;

use std::collections::BTreeSet;

use common::{arb_scene, lod_db};
use mktree::bulk::Hierarchy;
use mktree::db::read_hierarchy;
use mktree::geom::{Aabb, Frustum, Point, Vector, distance_point_triangle};
use mktree::lod::LodParams;
use mktree::query::{
    Bound, CutNode, Region, Shape, View, ViewCut, ViewOptions, brute_force_region, navigate_view,
};
use mktree::scene::generate::{GenOptions, Preset, generate_scene};
use mktree::scene::{ObjectId, Scene};
use proptest::prelude::*;

/// The objects of the subtree of `id`.
fn subtree(h: &Hierarchy, id: usize, out: &mut BTreeSet<ObjectId>) {
    let n = &h.nodes[id];
    match (n.children(), n.objects()) {
        (Some(c), _) => c.iter().for_each(|c| subtree(h, c.index(), out)),
        (None, Some(o)) => out.extend(o.iter().copied()),
        (None, None) => {}
    }
}

/// The node a piece names: by its id, or as its parent's child.
fn node_of(h: &Hierarchy, p: &CutNode) -> usize {
    match (p.node.id, p.node.parent) {
        (Some(id), _) => id as usize,
        (None, Some(parent)) => {
            h.nodes[parent as usize].children().expect("a parent")[usize::from(p.node.child)].index()
        }
        (None, None) => 0,
    }
}

/// A convex polygon clipped to the half-space n·x <= c.
fn clip(poly: &[Point], n: &Vector, c: f64) -> Vec<Point> {
    let mut out = Vec::new();
    for i in 0..poly.len() {
        let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
        let (da, db) = (n.dot(&a.coords) - c, n.dot(&b.coords) - c);
        if da <= 0.0 {
            out.push(a);
        }
        if (da < 0.0 && db > 0.0) || (da > 0.0 && db < 0.0) {
            out.push(a + (b - a) * (da / (da - db)));
        }
    }
    out
}

/// The distance from `p` to a convex planar polygon.
fn point_polygon(p: &Point, poly: &[Point]) -> f64 {
    let mut best = f64::INFINITY;
    // As triangles of a fan: the polygon is their union.
    for i in 1..poly.len().saturating_sub(1) {
        best = best.min(distance_point_triangle(p, &[poly[0], poly[i], poly[i + 1]]));
    }
    if poly.len() <= 2 {
        for q in poly {
            best = best.min((q - p).norm());
        }
    }
    best
}

/// A convex solid as its faces (polygons) and its half-spaces (n·x <= c).
struct Solid {
    faces: Vec<Vec<Point>>,
    halves: Vec<(Vector, f64)>,
}

fn box_solid(b: &Aabb) -> Solid {
    let c = b.corners();
    // Corners: bit 0 x, bit 1 y, bit 2 z (Aabb::corners' order is checked below).
    let faces = [[0, 2, 6, 4], [1, 3, 7, 5], [0, 1, 5, 4], [2, 3, 7, 6], [0, 1, 3, 2], [4, 5, 7, 6]]
        .iter()
        .map(|f| f.iter().map(|&i| c[i]).collect())
        .collect();
    let halves = (0..3)
        .flat_map(|a| {
            let mut e = Vector::zeros();
            e[a] = 1.0;
            [(-e, -b.min[a]), (e, b.max[a])]
        })
        .collect();
    Solid { faces, halves }
}

fn frustum_solid(f: &Frustum) -> Solid {
    let c = f.corners();
    let centre = Point::from(c.iter().fold(Vector::zeros(), |s, p| s + p.coords) / 8.0);
    let faces: Vec<Vec<Point>> =
        [[0, 1, 2, 3], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]]
            .iter()
            .map(|f| f.iter().map(|&i| c[i]).collect())
            .collect();
    let halves = faces
        .iter()
        .map(|f| {
            let n = (f[1] - f[0]).cross(&(f[2] - f[0])).normalize();
            let n = if n.dot(&(centre - f[0])) > 0.0 { -n } else { n };
            (n, n.dot(&f[0].coords))
        })
        .collect();
    Solid { faces, halves }
}

/// The exact distance from `eye` to the nearest point of box `b` inside the
/// frustum: the boundary of the intersection is the box's faces clipped to
/// the frustum and the frustum's faces clipped to the box.
fn nearest_visible(eye: &Point, b: &Aabb, f: &Frustum) -> f64 {
    let (bs, fs) = (box_solid(b), frustum_solid(f));
    let mut best = f64::INFINITY;
    for (faces, halves) in [(&bs.faces, &fs.halves), (&fs.faces, &bs.halves)] {
        for face in faces {
            let poly = halves.iter().fold(face.clone(), |p, (n, c)| clip(&p, n, *c));
            if !poly.is_empty() {
                best = best.min(point_polygon(eye, &poly));
            }
        }
    }
    best
}

/// The farthest a sample of `shape` lies from the triangles of `objects`.
fn stand_in_error(shape: &Shape, scene: &Scene, objects: &BTreeSet<ObjectId>) -> f64 {
    let samples: Vec<Point> = match shape {
        Shape::Box(b) => b.corners().to_vec(),
        Shape::Voxels(v) => v.cell_boxes().flat_map(|c| c.corners()).collect(),
        Shape::Mesh(m) => m.vertices().collect(),
    };
    samples
        .iter()
        .map(|p| {
            objects
                .iter()
                .flat_map(|o| scene.objects()[o.0 as usize].mesh.triangle_points())
                .map(|t| distance_point_triangle(p, &t))
                .fold(f64::INFINITY, f64::min)
        })
        .fold(0.0, f64::max)
}

/// Checks a cut against the scene: coverage, errors, order, reads.
fn check_cut(scene: &Scene, h: &Hierarchy, view: &View, cut: &ViewCut, budget: Option<u64>, tau: f64) {
    let frustum = Frustum::from_camera(&view.camera()).unwrap();
    let visible = brute_force_region(scene, &Region::Frustum(Box::new(frustum.clone())));
    let mut covered = BTreeSet::new();
    for p in &cut.nodes {
        let mut stands_for = BTreeSet::new();
        match p.bound {
            Bound::NodeBox | Bound::GroupBound => {
                let id = node_of(h, p);
                assert_eq!(h.nodes[id].aabb, p.aabb, "piece {:?} names its node", p.node);
                subtree(h, id, &mut stands_for);
            }
            Bound::ObjectBounds | Bound::Exact => stands_for.extend(p.objects.iter().copied()),
        }
        if p.bound == Bound::Exact {
            for o in &p.objects {
                assert!(visible.binary_search(o).is_ok(), "object {o:?} shown exact is not visible");
            }
        }
        for s in &p.shapes {
            let target: BTreeSet<ObjectId> = s.object.map_or(stands_for.clone(), |o| [o].into());
            let d = nearest_visible(&view.eye, &s.aabb, &frustum);
            assert!(d.is_finite(), "a shown box outside the frustum");
            assert!(d >= p.distance_mm * (1.0 - 1e-9), "the piece's distance {} is above {d}", p.distance_mm);
            let px = view.projected_px(s.eps_mm, d);
            assert!(
                px <= p.error_px * (1.0 + 1e-9) + 1e-12,
                "error {px} px above the piece's {}",
                p.error_px
            );
            if budget.is_none() {
                assert!(px <= tau * (1.0 + 1e-9), "error {px} px above tau {tau} ({:?})", p.bound);
            }
            let e = stand_in_error(&s.shape, scene, &target);
            assert!(
                e <= s.eps_mm * (1.0 + 1e-9) + 1e-9,
                "a stand-in {e} mm from its objects, eps {}",
                s.eps_mm
            );
        }
        covered.extend(stands_for);
    }
    for o in &visible {
        assert!(covered.contains(o), "visible object {o:?} is not in the cut");
    }
    for w in cut.nodes.windows(2) {
        assert!(w[0].distance_mm <= w[1].distance_mm, "not front to back");
    }
    let max = cut.nodes.iter().map(|n| n.error_px).fold(0.0, f64::max);
    assert_eq!(cut.max_error_px, max);
    if let Some(b) = budget {
        assert!(cut.stats.reads.total() <= b, "{} reads over a budget of {b}", cut.stats.reads.total());
    }
}

fn views_of(b: &Aabb) -> Vec<View> {
    let c = b.center();
    let e = b.extent();
    let eyes = [
        Point::new(b.min.x - 0.5 * e.x, c.y, c.z + 0.2 * e.z),
        Point::new(c.x, b.min.y - 0.3 * e.y, c.z),
        Point::new(b.min.x + 0.25 * e.x, c.y + 0.1 * e.y, c.z),
        Point::new(b.max.x + 0.1 * e.x, b.max.y, b.max.z),
    ];
    eyes.iter()
        .map(|&eye| {
            View { eye, target: c, fov_deg: 60.0, width_px: 320, height_px: 200, near_mm: 10.0, far_mm: 1.0 }
                .seeing_all_of(b)
        })
        .collect()
}

fn shapes(tolerance_px: f64, budget: Option<u64>) -> ViewOptions {
    ViewOptions { tolerance_px, budget, shapes: true }
}

#[test]
fn a_cut_of_tanker1_covers_what_is_visible_within_tau() {
    let scene = generate_scene(&GenOptions { preset: Preset::Tanker1, objects: None, seed: 3 }).unwrap();
    let db = lod_db(&scene, 4, 4096, 10, LodParams { store_all: true, ..LodParams::default() });
    let r = db.begin_read().unwrap();
    let h = read_hierarchy(&r).unwrap();
    let mut kinds = BTreeSet::new();
    for view in views_of(&scene.aabb()) {
        let mut reads = Vec::new();
        for tau in [0.0, 1.0, 8.0, 64.0] {
            let cut = r.view(&view, &shapes(tau, None), None).unwrap();
            check_cut(&scene, &h, &view, &cut, None, tau);
            kinds.extend(cut.nodes.iter().map(|n| (n.bound, n.level)));
            reads.push(cut.stats.reads.total());
        }
        assert!(reads.windows(2).all(|w| w[0] >= w[1]), "a coarser tolerance read more: {reads:?}");
    }
    // The cuts used group bounds (b(S_n,k) of nodes), voxel bounds and exact objects.
    assert!(kinds.iter().any(|k| k.0 == Bound::GroupBound && k.1 > 1), "{kinds:?}");
    assert!(kinds.iter().any(|k| k.0 == Bound::ObjectBounds && k.1 > 1), "{kinds:?}");
    assert!(kinds.contains(&(Bound::Exact, 4)), "{kinds:?}");
}

#[test]
fn a_budgeted_cut_fits_covers_everything_and_a_budget_that_suffices_changes_nothing() {
    let scene = generate_scene(&GenOptions { preset: Preset::Tanker1, objects: None, seed: 4 }).unwrap();
    let db = lod_db(&scene, 4, 4096, 10, LodParams { store_all: true, ..LodParams::default() });
    let r = db.begin_read().unwrap();
    let h = read_hierarchy(&r).unwrap();
    let view = views_of(&scene.aabb())[2];
    let free = r.view(&view, &shapes(1.0, None), None).unwrap();
    // A budgeted cut shows each node it reaches by its group bound while it
    // refines (so what the budget leaves is drawn coarse, not as boxes):
    // it reads the group blocks of nodes it refines past, which an
    // unbudgeted cut does not. `need` is what it reads when nothing stops it.
    let need = r.view(&view, &shapes(1.0, Some(u64::MAX)), None).unwrap().stats.reads.total();
    assert!(need >= free.stats.reads.total() && need > 4, "the view reads {need} blocks");
    let mut errors = Vec::new();
    for budget in [0, 1, 2, need / 2, need - 1] {
        let cut = r.view(&view, &shapes(1.0, Some(budget)), None).unwrap();
        check_cut(&scene, &h, &view, &cut, Some(budget), 1.0);
        errors.push(cut.max_error_px);
    }
    assert!(errors[0] > 1.0, "budget 0 keeps the root's box");
    assert!(errors.windows(2).all(|w| w[0] >= w[1]), "more budget, larger error: {errors:?}");
    let zero = r.view(&view, &shapes(1.0, Some(0)), None).unwrap();
    assert_eq!((zero.nodes.len(), zero.nodes[0].node.id), (1, Some(0)), "budget 0: the root's box");
    let enough = r.view(&view, &shapes(1.0, Some(need)), None).unwrap();
    let key = |c: &ViewCut| {
        c.nodes
            .iter()
            .map(|n| (n.node.id, n.node.parent, n.node.child, n.level, n.objects.clone()))
            .collect::<BTreeSet<_>>()
    };
    assert_eq!(key(&enough), key(&free));
    assert_eq!(enough.stats.reads.total(), need);
}

/// Refining a group bound reads the children's records and then their
/// group blocks; a budget that paid for the first but not the second would
/// show a child by its box, coarser than the bound it replaced, so a larger
/// budget could show a larger error (ship 10^6 at 50 reads did, before the
/// refinement reserved both).
#[test]
fn a_larger_budget_never_shows_a_larger_error() {
    let scene = generate_scene(&GenOptions { preset: Preset::Tanker1, objects: None, seed: 4 }).unwrap();
    let db = lod_db(&scene, 4, 4096, 10, LodParams::default());
    let r = db.begin_read().unwrap();
    for view in views_of(&scene.aabb()) {
        let need = r.view(&view, &shapes(1.0, Some(u64::MAX)), None).unwrap().stats.reads.total();
        let errors: Vec<f64> = (0..=need)
            .map(|budget| r.view(&view, &shapes(1.0, Some(budget)), None).unwrap().max_error_px)
            .collect();
        let rises: Vec<(usize, f64, f64)> = errors
            .windows(2)
            .enumerate()
            .filter(|(_, w)| w[1] > w[0])
            .map(|(b, w)| (b + 1, w[0], w[1]))
            .collect();
        assert!(rises.is_empty(), "budget, error before, error at that budget: {rises:?} of {need} reads");
    }
}

#[test]
fn a_walk_with_a_tolerance_reads_less_than_exact_and_its_pool_saves_reads() {
    let scene = generate_scene(&GenOptions { preset: Preset::Tanker1, objects: None, seed: 5 }).unwrap();
    let db = lod_db(&scene, 4, 4096, 10, LodParams::default());
    let r = db.begin_read().unwrap();
    let mut views = views_of(&scene.aabb());
    views.push(views[3]);
    let exact =
        navigate_view(&r, &views, &ViewOptions { tolerance_px: 0.0, budget: None, shapes: false }, 10_000)
            .unwrap();
    let loose =
        navigate_view(&r, &views, &ViewOptions { tolerance_px: 4.0, budget: None, shapes: false }, 10_000)
            .unwrap();
    for (e, l) in exact.iter().zip(&loose) {
        assert_eq!(e.max_error_px, 0.0);
        assert!(l.max_error_px <= 4.0);
        assert!(l.exact_objects() <= e.exact_objects());
    }
    // The last step repeats the one before it: the pool holds it all.
    assert_eq!(loose[4].stats.reads.total(), 0);
    assert!(loose[4].stats.reads.cache_hits > 0);
    // From a cold pool each frame, the tolerance saves reads.
    let cold = |tau: f64, v: &View| {
        r.view(v, &ViewOptions { tolerance_px: tau, budget: None, shapes: false }, None)
            .unwrap()
            .stats
            .reads
            .total()
    };
    let (e, l): (Vec<u64>, Vec<u64>) = views.iter().map(|v| (cold(0.0, v), cold(4.0, v))).unzip();
    assert!(e.iter().zip(&l).all(|(e, l)| l <= e), "{l:?} against {e:?}");
    assert!(l.iter().sum::<u64>() < e.iter().sum::<u64>(), "{l:?} against {e:?}");
}

#[test]
fn box_corners_are_numbered_x_then_y_then_z() {
    let c = Aabb::from_array([0.0, 0.0, 0.0, 1.0, 2.0, 3.0]).corners();
    assert_eq!(
        (c[1], c[2], c[4]),
        (Point::new(1.0, 0.0, 0.0), Point::new(0.0, 2.0, 0.0), Point::new(0.0, 0.0, 3.0))
    );
}

#[test]
fn the_nearest_visible_point_oracle_clips_to_the_frustum() {
    let view = View {
        eye: Point::origin(),
        target: Point::new(10.0, 0.0, 0.0),
        fov_deg: 90.0,
        width_px: 100,
        height_px: 100,
        near_mm: 1.0,
        far_mm: 100.0,
    };
    let f = Frustum::from_camera(&view.camera()).unwrap();
    // A box straddling the view's axis: its near face at x = 5.
    let d = nearest_visible(&view.eye, &Aabb::from_array([5.0, -1.0, -1.0, 6.0, 1.0, 1.0]), &f);
    assert!((d - 5.0).abs() < 1e-12);
    // A box beside the axis: the nearest visible point is on the side plane y = x.
    let d = nearest_visible(&view.eye, &Aabb::from_array([2.0, 3.0, -1.0, 4.0, 5.0, 1.0]), &f);
    assert!((d - (3.0f64 * 3.0 + 3.0 * 3.0).sqrt()).abs() < 1e-9, "{d}");
    assert!(view.nearest_visible_mm(&Aabb::from_array([2.0, 3.0, -1.0, 4.0, 5.0, 1.0])) <= d);
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]

    #[test]
    fn cuts_of_random_scenes_cover_the_view_within_tau(
        scene in arb_scene(40),
        eye in prop::array::uniform3(-500.0f64..1500.0),
        target in prop::array::uniform3(0.0f64..1000.0),
        tau in prop_oneof![Just(0.0), 0.5f64..50.0],
        budget in prop_oneof![Just(None), (0u64..12).prop_map(Some)],
    ) {
        let eye = Point::from(eye);
        let target = Point::from(target);
        let dir = target - eye;
        prop_assume!(dir.norm() > 1.0 && dir.cross(&Vector::z()).norm() > 1e-3 * dir.norm());
        let db = lod_db(&scene, 4, 1024, 4, LodParams { store_all: true, ..LodParams::default() });
        let r = db.begin_read().unwrap();
        let h = read_hierarchy(&r).unwrap();
        let view = View { eye, target, fov_deg: 50.0, width_px: 200, height_px: 150, near_mm: 5.0, far_mm: 1.0 }
            .seeing_all_of(&scene.aabb());
        let cut = r.view(&view, &shapes(tau, budget), None).unwrap();
        check_cut(&scene, &h, &view, &cut, budget, tau);
    }
}

/// A wavy sheet of `n` x `n` quads in the x-z plane (1000 mm square): more
/// bytes than a small geometry block, so it is stored as parts.
fn sheet(n: u32) -> mktree::scene::Mesh {
    let step = 1000.0 / f64::from(n);
    let mut verts = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let (x, z) = (f64::from(i) * step, f64::from(j) * step);
            verts.push(Point::new(x, 20.0 * ((x + z) / 90.0).sin(), z));
        }
    }
    let mut tris = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let a = j * (n + 1) + i;
            tris.extend([[a, a + 1, a + n + 2], [a, a + n + 2, a + n + 1]]);
        }
    }
    mktree::scene::Mesh::from_world(&verts, tris).unwrap()
}

#[test]
fn an_object_stored_as_parts_is_shown_whole() {
    use mktree::scene::Object;
    let mut objects = vec![Object::new("sheet", sheet(30))];
    for i in 0..6 {
        let lo = [200.0 * f64::from(i), 300.0, 100.0];
        objects.push(Object::new(format!("box{i}"), common::box_mesh(lo, [lo[0] + 80.0, 380.0, 180.0])));
    }
    let scene = Scene::new(objects);
    let db = lod_db(&scene, 4, 4096, 4, LodParams { store_all: true, ..LodParams::default() });
    let r = db.begin_read().unwrap();
    let h = read_hierarchy(&r).unwrap();
    let view = View {
        eye: Point::new(500.0, -3000.0, 500.0),
        target: Point::new(500.0, 0.0, 500.0),
        fov_deg: 60.0,
        width_px: 400,
        height_px: 300,
        near_mm: 10.0,
        far_mm: 1.0,
    }
    .seeing_all_of(&scene.aabb());
    let sheet_triangles = |cut: &ViewCut| -> (usize, usize) {
        let shown: Vec<&mktree::query::Shown> =
            cut.nodes.iter().flat_map(|n| &n.shapes).filter(|s| s.object == Some(ObjectId(0))).collect();
        let exact =
            shown.iter().map(|s| if let Shape::Mesh(m) = &s.shape { m.triangle_count() } else { 0 }).sum();
        (shown.len(), exact)
    };
    let exact = r.view(&view, &shapes(0.0, None), None).unwrap();
    check_cut(&scene, &h, &view, &exact, None, 0.0);
    let (parts, triangles) = sheet_triangles(&exact);
    assert!(parts > 1, "the sheet is stored as {parts} part(s)");
    assert_eq!(triangles, 1800, "every part of the sheet is drawn");
    // A budget that stops inside the sheet's parts shows the rest at their bounds.
    let need = exact.stats.reads.total();
    for budget in 1..need {
        let cut = r.view(&view, &shapes(0.0, Some(budget)), None).unwrap();
        check_cut(&scene, &h, &view, &cut, Some(budget), 0.0);
        // Under a node's box, or every part shown (exact or by its bound).
        let (shown, _) = sheet_triangles(&cut);
        assert!(shown == 0 || shown == parts, "budget {budget}: {shown} of the sheet's {parts} parts shown");
    }
}
