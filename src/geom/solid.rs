//! Two triangle meshes taken as solids, for the clash tests (docs/clash.md,
//! "How a pair is measured"): where they overlap, how far apart they are
//! and whether they are the same geometry.
//!
//! - [`overlap`]: whether the closed solids share a point, and the box of
//!   their intersection. The intersection of two closed polyhedra is a
//!   polyhedron whose corners are corners of one inside the other, or
//!   points where an edge of one crosses a face of the other; the box of
//!   those points is the box of the intersection. Crossings are found by
//!   the exact contact rule (`contact.rs`) and placed in floating point;
//!   "inside" is the generalized winding number (more than one half), so an
//!   open mesh is taken as the solid its winding number encloses. A mesh
//!   wholly inside the other, with no surface contact, overlaps it by its
//!   own box. The penetration of a hard clash is the box's smallest side.
//! - [`closest`]: the minimum distance between two triangle sets below a
//!   limit, with the two closest points (parry's triangle pairs).
//! - [`same_within`]: every vertex of each within a tolerance of the
//!   other's surface (duplicates).

use super::contact::{Facet, facets_meet, inside_2d, segment_meets_triangle, strictly_one_side};
use super::parry::closest_points_triangle_triangle;
use super::{Aabb, Point, SurfaceDistance};

/// How two meshes, as solids, overlap.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Overlap {
    /// The closed solids share a point (touching counts).
    pub contact: bool,
    /// The box of their intersection ([`Aabb::EMPTY`] without contact).
    pub region: Aabb,
}

impl Overlap {
    /// The smallest side of the intersection's box: 0 for a touch (a face,
    /// edge or point in common), more for a penetration; 0 without contact.
    pub fn depth(&self) -> f64 {
        if !self.contact || self.region.is_empty() {
            return 0.0;
        }
        let e = self.region.extent();
        e.x.min(e.y).min(e.z).max(0.0)
    }
}

/// The generalized winding number of `triangles` around `p` (Van
/// Oosterom and Strackee's solid angles, summed over 4 pi): about ±1
/// inside a closed mesh, 0 outside, either sign by the faces' orientation.
pub fn winding_number(p: &Point, triangles: &[[Point; 3]]) -> f64 {
    let mut sum = 0.0;
    for t in triangles {
        let (a, b, c) = (t[0] - p, t[1] - p, t[2] - p);
        let (la, lb, lc) = (a.norm(), b.norm(), c.norm());
        let det = a.dot(&b.cross(&c));
        let div = la * lb * lc + a.dot(&b) * lc + a.dot(&c) * lb + b.dot(&c) * la;
        sum += 2.0 * det.atan2(div);
    }
    sum / (4.0 * std::f64::consts::PI)
}

/// `p` lies inside the solid `triangles` enclose (winding number above one half).
fn inside(p: &Point, triangles: &[[Point; 3]]) -> bool {
    winding_number(p, triangles).abs() > 0.5
}

/// A triangle (`T`: its corners, or a [`Facet`]) with its box.
struct Boxed<T> {
    t: T,
    b: Aabb,
}

/// The triangles of `ts` whose boxes meet `window` grown by `d`, each made
/// into a `T` by `make`, sorted by their boxes' lower x.
fn near<'a, T>(
    ts: &'a [[Point; 3]],
    window: &Aabb,
    d: f64,
    make: impl Fn(&'a [Point; 3]) -> T,
) -> Vec<Boxed<T>> {
    let w = window.grown(d);
    let mut v: Vec<Boxed<T>> = ts
        .iter()
        .map(|t| (t, Aabb::from_points(t)))
        .filter(|(_, b)| b.intersects(&w))
        .map(|(t, b)| Boxed { t: make(t), b })
        .collect();
    v.sort_by(|x, y| x.b.min.x.total_cmp(&y.b.min.x));
    v
}

/// Every pair (i, j) of `a` and `b` (each sorted by lower x) whose boxes
/// lie within `d` of each other, by a sweep along x.
fn pairs<T>(a: &[Boxed<T>], b: &[Boxed<T>], d: f64, mut f: impl FnMut(&Boxed<T>, &Boxed<T>)) {
    let mut start = 0;
    for x in a {
        // Probes come by increasing lower x: a triangle wholly left of this
        // one is left of every later one.
        while start < b.len() && b[start].b.max.x + d < x.b.min.x {
            start += 1;
        }
        for y in &b[start..] {
            if y.b.min.x > x.b.max.x + d {
                break;
            }
            if x.b.within(&y.b, d) {
                f(x, y);
            }
        }
    }
}

/// Where closed segment `pq` crosses the facet (if it has area), added to `out`.
fn crossings(p: &Point, q: &Point, f: &Facet, out: &mut Aabb) {
    let Some(along) = f.flat() else { return };
    let t = &f.t;
    let (sp, sq) = (f.side(p), f.side(q));
    if strictly_one_side(&[sp, sq]) {
        return;
    }
    if sp == 0.0 && sq == 0.0 {
        // In the triangle's plane: the ends inside it and the crossings with its edges.
        for x in [p, q] {
            if inside_2d(along, t, x) {
                *out = out.including(x);
            }
        }
        for (r, s) in [(&t[0], &t[1]), (&t[1], &t[2]), (&t[2], &t[0])] {
            segment_crossing_2d(along, p, q, r, s, out);
        }
        return;
    }
    if !segment_meets_triangle(p, q, t, sp, sq) {
        return;
    }
    let x = if sp == 0.0 {
        *p
    } else if sq == 0.0 {
        *q
    } else {
        p + (q - p) * (sp / (sp - sq))
    };
    *out = out.including(&x);
}

/// The common points of coplanar segments `pq` and `rs`, seen along axis
/// `along` (placed in floating point), added to `out`.
fn segment_crossing_2d(along: usize, p: &Point, q: &Point, r: &Point, s: &Point, out: &mut Aabb) {
    let (i, j) = ((along + 1) % 3, (along + 2) % 3);
    let cross = |u: [f64; 2], v: [f64; 2]| u[0] * v[1] - u[1] * v[0];
    let d = |a: &Point, b: &Point| [b[i] - a[i], b[j] - a[j]];
    let (e, f) = (d(p, q), d(r, s));
    let den = cross(e, f);
    if den != 0.0 {
        let t = cross(d(p, r), f) / den;
        let u = cross(d(p, r), e) / den;
        if (0.0..=1.0).contains(&t) && (0.0..=1.0).contains(&u) {
            *out = out.including(&(p + (q - p) * t));
        }
        return;
    }
    if cross(d(p, r), e) != 0.0 {
        return; // parallel, apart
    }
    // On one line: the ends of each that lie on the other.
    let on =
        |a: &Point, b: &Point, x: &Point| (0..3).all(|k| a[k].min(b[k]) <= x[k] && x[k] <= a[k].max(b[k]));
    for (x, (a, b)) in [(p, (r, s)), (q, (r, s)), (r, (p, q)), (s, (p, q))] {
        if on(a, b, x) {
            *out = out.including(x);
        }
    }
}

/// How the solids `a` and `b` overlap: contact, and the box of their
/// intersection (see the module's notes).
pub fn overlap(a: &[[Point; 3]], b: &[[Point; 3]]) -> Overlap {
    let none = Overlap { contact: false, region: Aabb::EMPTY };
    let (ba, bb) = (Aabb::from_points(a.iter().flatten()), Aabb::from_points(b.iter().flatten()));
    if !ba.intersects(&bb) {
        return none;
    }
    let window = Aabb::new(ba.min.sup(&bb.min), ba.max.inf(&bb.max));
    let (na, nb) = (near(a, &window, 0.0, Facet::new), near(b, &window, 0.0, Facet::new));
    let mut contact = false;
    let mut region = Aabb::EMPTY;
    pairs(&na, &nb, 0.0, |x, y| {
        if !facets_meet(&x.t, &y.t) {
            return;
        }
        contact = true;
        for (s, f) in [(&x.t.t, &y.t), (&y.t.t, &x.t)] {
            for (p, q) in [(&s[0], &s[1]), (&s[1], &s[2]), (&s[2], &s[0])] {
                crossings(p, q, f, &mut region);
            }
        }
    });
    // Corners of each inside the other (the test reads the other whole).
    let corners_inside = |from: &[[Point; 3]], of: &[[Point; 3]], region: &mut Aabb| {
        let mut seen = Vec::new();
        for p in from.iter().flatten().filter(|p| window.contains_point(p)) {
            if seen.contains(p) {
                continue;
            }
            seen.push(*p);
            if inside(p, of) {
                *region = region.including(p);
            }
        }
    };
    if contact {
        corners_inside(a, b, &mut region);
        corners_inside(b, a, &mut region);
        return Overlap { contact, region };
    }
    // No surface contact: one inside the other, or apart.
    if let Some(p) = a.first().map(|t| t[0])
        && bb.contains_point(&p)
        && inside(&p, b)
    {
        return Overlap { contact: true, region: ba };
    }
    if let Some(p) = b.first().map(|t| t[0])
        && ba.contains_point(&p)
        && inside(&p, a)
    {
        return Overlap { contact: true, region: bb };
    }
    none
}

/// The least distance between the triangle sets `a` and `b` if it is below
/// `limit`, with the closest point of each (`None` at `limit` or beyond).
pub fn closest(a: &[[Point; 3]], b: &[[Point; 3]], limit: f64) -> Option<(f64, Point, Point)> {
    let (ba, bb) = (Aabb::from_points(a.iter().flatten()), Aabb::from_points(b.iter().flatten()));
    if !ba.within(&bb, limit) {
        return None;
    }
    let (na, nb) = (near(a, &bb, limit, |t| t), near(b, &ba, limit, |t| t));
    let mut best: Option<(f64, Point, Point)> = None;
    pairs(&na, &nb, limit, |x, y| {
        let bound = best.map_or(limit, |b| b.0);
        if !x.b.within(&y.b, bound) {
            return;
        }
        let (d, p, q) = closest_points_triangle_triangle(x.t, y.t);
        if d < bound {
            best = Some((d, p, q));
        }
    });
    best
}

/// Every vertex of `a` lies within `tolerance` of `b`'s surface and every
/// vertex of `b` within `tolerance` of `a`'s: the same geometry, as
/// duplicates are (the boxes are checked first).
pub fn same_within(a: &[[Point; 3]], b: &[[Point; 3]], tolerance: f64) -> bool {
    let (ba, bb) = (Aabb::from_points(a.iter().flatten()), Aabb::from_points(b.iter().flatten()));
    if ba.is_empty() || bb.is_empty() {
        return false;
    }
    if (0..3).any(|i| (ba.min[i] - bb.min[i]).abs() > tolerance || (ba.max[i] - bb.max[i]).abs() > tolerance)
    {
        return false;
    }
    let covered = |from: &[[Point; 3]], to: &[[Point; 3]]| {
        let surface = SurfaceDistance::new(to.iter().copied());
        from.iter().flatten().all(|p| surface.distance(p) <= tolerance)
    };
    covered(a, b) && covered(b, a)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The 12 triangles of a box, faces outward.
    fn cube(lo: [f64; 3], hi: [f64; 3]) -> Vec<[Point; 3]> {
        let c = |i: usize| {
            Point::new(
                if i & 1 == 0 { lo[0] } else { hi[0] },
                if i & 2 == 0 { lo[1] } else { hi[1] },
                if i & 4 == 0 { lo[2] } else { hi[2] },
            )
        };
        let quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];
        quads.iter().flat_map(|q| [[c(q[0]), c(q[1]), c(q[2])], [c(q[0]), c(q[2]), c(q[3])]]).collect()
    }

    #[test]
    fn winding_is_one_inside_and_zero_outside() {
        let k = cube([0.0; 3], [1.0; 3]);
        assert!((winding_number(&Point::new(0.5, 0.5, 0.5), &k).abs() - 1.0).abs() < 1e-9);
        assert!(winding_number(&Point::new(1.5, 0.5, 0.5), &k).abs() < 1e-9);
    }

    #[test]
    fn overlapping_boxes_overlap_by_their_common_box() {
        let a = cube([0.0; 3], [10.0; 3]);
        let b = cube([7.0, 2.0, -5.0], [20.0, 8.0, 15.0]);
        let o = overlap(&a, &b);
        assert!(o.contact);
        let expect = Aabb::from_array([7.0, 2.0, 0.0, 10.0, 8.0, 10.0]);
        for i in 0..3 {
            assert!((o.region.min[i] - expect.min[i]).abs() < 1e-9, "{:?}", o.region);
            assert!((o.region.max[i] - expect.max[i]).abs() < 1e-9, "{:?}", o.region);
        }
        assert!((o.depth() - 3.0).abs() < 1e-9);
    }

    #[test]
    fn face_to_face_is_a_touch_of_depth_zero() {
        let a = cube([0.0; 3], [10.0; 3]);
        let b = cube([10.0, 2.0, 3.0], [20.0, 8.0, 7.0]);
        let o = overlap(&a, &b);
        assert!(o.contact);
        assert_eq!(o.depth(), 0.0);
        let apart = cube([10.5, 2.0, 3.0], [20.0, 8.0, 7.0]);
        assert!(!overlap(&a, &apart).contact);
    }

    #[test]
    fn a_box_inside_another_overlaps_by_its_own_box() {
        let a = cube([0.0; 3], [10.0; 3]);
        let b = cube([2.0; 3], [3.0, 4.0, 5.0]);
        for o in [overlap(&a, &b), overlap(&b, &a)] {
            assert!(o.contact);
            assert!((o.depth() - 1.0).abs() < 1e-12);
        }
    }

    #[test]
    fn a_bar_through_a_wall_penetrates_by_the_smaller_of_thickness_and_width() {
        let wall = cube([0.0, 0.0, 0.0], [200.0, 5000.0, 3000.0]);
        let bar = cube([-500.0, 1000.0, 1000.0], [700.0, 1120.0, 1150.0]);
        let o = overlap(&wall, &bar);
        assert!(o.contact);
        assert!((o.depth() - 120.0).abs() < 1e-9, "{}", o.depth());
    }

    #[test]
    fn closest_points_of_boxes_apart() {
        let a = cube([0.0; 3], [10.0; 3]);
        let b = cube([13.0, 0.0, 0.0], [20.0, 10.0, 10.0]);
        let (d, p, q) = closest(&a, &b, 5.0).expect("3 mm apart, below 5");
        assert!((d - 3.0).abs() < 1e-9);
        assert!((p.x - 10.0).abs() < 1e-9 && (q.x - 13.0).abs() < 1e-9);
        assert!(closest(&a, &b, 3.0).is_none(), "at the limit is not below it");
    }

    #[test]
    fn duplicates_within_a_tolerance() {
        let a = cube([0.0; 3], [10.0; 3]);
        let b = cube([0.0, 0.0, 0.001], [10.0, 10.0, 10.001]);
        assert!(same_within(&a, &b, 0.01));
        assert!(!same_within(&a, &b, 0.0001));
        assert!(!same_within(&a, &cube([0.0; 3], [10.0, 10.0, 5.0]), 0.01));
    }

    proptest! {
        /// Two boxes' overlap is their common box, found from their triangles;
        /// boxes apart have no contact; closest distance agrees with the boxes' gap.
        #[test]
        fn boxes_overlap_as_boxes_do(
            a in prop::array::uniform6(-8i32..8), b in prop::array::uniform6(-8i32..8),
        ) {
            let sorted = |v: [i32; 6]| {
                let lo = [v[0].min(v[3]), v[1].min(v[4]), v[2].min(v[5])].map(f64::from);
                let hi = [v[0].max(v[3]) + 1, v[1].max(v[4]) + 1, v[2].max(v[5]) + 1].map(f64::from);
                (lo, hi)
            };
            let ((al, ah), (bl, bh)) = (sorted(a), sorted(b));
            let (ka, kb) = (cube(al, ah), cube(bl, bh));
            let o = overlap(&ka, &kb);
            let common: Vec<(f64, f64)> = (0..3).map(|i| (al[i].max(bl[i]), ah[i].min(bh[i]))).collect();
            let meets = common.iter().all(|(l, h)| l <= h);
            prop_assert_eq!(o.contact, meets);
            if meets {
                for (i, (l, h)) in common.iter().enumerate() {
                    prop_assert!((o.region.min[i] - l).abs() < 1e-9 && (o.region.max[i] - h).abs() < 1e-9,
                        "axis {}: {:?} against {:?}", i, o.region, common);
                }
                prop_assert_eq!(o.contact, overlap(&kb, &ka).contact);
            } else {
                let gap = (0..3).map(|i| (al[i] - bh[i]).max(bl[i] - ah[i]).max(0.0)).map(|g| g * g).sum::<f64>().sqrt();
                let (d, _, _) = closest(&ka, &kb, 100.0).expect("within 100");
                prop_assert!((d - gap).abs() < 1e-9, "{} against {}", d, gap);
            }
        }
    }
}
