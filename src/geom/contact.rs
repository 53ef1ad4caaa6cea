//! The contact rule of every query. Objects and query shapes are closed
//! point sets; two of them touch when they share a point (distance 0), so a
//! shared face, edge or vertex is a contact. With a clearance d > 0 they are
//! in contact when their distance is at most d.
//!
//! Touching is decided exactly on the f64 coordinates, with no tolerance:
//! every test below reduces to the signs of orientation determinants, which
//! Shewchuk's adaptive predicates (`robust`) compute exactly. A test is a
//! function of the pair, never of which one is the probe, so contact is
//! symmetric. Distances (d > 0) are parry's, with the pair taken in one
//! order, so they too are symmetric bit for bit.
//!
//! A [`Facet`] is a triangle with its plane worked out once: a point's side
//! of it is a floating-point dot product, taken when its sign is certain by
//! Shewchuk's error bound for the same expression, and the exact predicate
//! otherwise. Segments against a triangle's edges are filtered the same
//! way. (Measuring a clash test's pairs was 54% orientation tests; with
//! the filter it took a third of the time. Every sign is the exact one, so
//! contact is decided as before; a crossing point placed from two sides'
//! values may move by an ulp, though none did on the models measured.)

use super::{Aabb, Point, Vector, distance_triangle_triangle};
use robust::{Coord, Coord3D, orient2d, orient3d};

/// Which side of the plane through `a, b, c` the point `d` lies on: the
/// sign is exact (0 on the plane); `-((b - a) x (c - a)) . (d - a)` up to a
/// positive factor.
pub(crate) fn side3(a: &Point, b: &Point, c: &Point, d: &Point) -> f64 {
    // Four points with two alike (a shared corner), or on one axis-aligned
    // plane (faces of boxes, plates), are coplanar: the adaptive predicate
    // would take its slowest path to say so.
    if a == d || b == d || c == d || a == b || b == c || c == a {
        return 0.0;
    }
    if (0..3).any(|i| a[i] == b[i] && a[i] == c[i] && a[i] == d[i]) {
        return 0.0;
    }
    let k = |p: &Point| Coord3D { x: p.x, y: p.y, z: p.z };
    orient3d(k(a), k(b), k(c), k(d))
}

/// Shewchuk's `o3derrboundA`, (7 + 56 e) e with e = 2^-53: a 3x3
/// determinant of rounded coordinate differences, expanded by 2x2 minors
/// in floating point, is within this times its permanent of the exact one.
const O3D_ERRBOUND_A: f64 = (7.0 + 56.0 * HALF_ULP) * HALF_ULP;
const HALF_ULP: f64 = f64::EPSILON / 2.0;

/// A triangle ready for many exact tests: its plane's normal and the
/// magnitudes that bound the normal's rounding, and the axis along which it
/// has area.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Facet {
    /// The corners.
    pub t: [Point; 3],
    /// `(t1 - t0) x (t2 - t0)`, in floating point.
    n: Vector,
    /// Per component of `n`, the sum of its two products' magnitudes.
    m: Vector,
    /// [`flat_axis`] of the corners.
    flat: Option<usize>,
}

impl Facet {
    pub(crate) fn new(t: &[Point; 3]) -> Facet {
        let (n, m) = normal(&(t[1] - t[0]), &(t[2] - t[0]));
        Facet { t: *t, n, m, flat: flat_axis(t) }
    }

    /// [`side3`] of `x` against the corners: the same sign, exact, and the
    /// same value up to rounding (`crossings` interpolates between two).
    pub(crate) fn side(&self, x: &Point) -> f64 {
        certain(&self.n, &self.m, &(x - self.t[0]))
            .unwrap_or_else(|| side3(&self.t[0], &self.t[1], &self.t[2], x))
    }

    /// The axis along which the triangle has area (`None`: a segment or point).
    pub(crate) fn flat(&self) -> Option<usize> {
        self.flat
    }
}

/// `u x v` in floating point, and per component the sum of its two
/// products' magnitudes (what bounds its rounding).
fn normal(u: &Vector, v: &Vector) -> (Vector, Vector) {
    let n = Vector::new(u.y * v.z - u.z * v.y, u.z * v.x - u.x * v.z, u.x * v.y - u.y * v.x);
    let m = Vector::new(
        (u.y * v.z).abs() + (u.z * v.y).abs(),
        (u.z * v.x).abs() + (u.x * v.z).abs(),
        (u.x * v.y).abs() + (u.y * v.x).abs(),
    );
    (n, m)
}

/// `side3(a, b, c, d)` from `normal(b - a, c - a)` and `w = d - a`, all
/// rounded differences, when its sign is certain (else `None`). The
/// determinant of rows `b - a`, `c - a`, `d - a` expanded along the last:
/// Shewchuk's orient3d expression with `a` as origin, so his bound holds,
/// with his proviso: no product underflows (coordinates' differences above
/// about 1e-145), as for `robust`'s own stages.
fn certain(n: &Vector, m: &Vector, w: &Vector) -> Option<f64> {
    let det = w.x * n.x + w.y * n.y + w.z * n.z;
    let permanent = w.x.abs() * m.x + w.y.abs() * m.y + w.z.abs() * m.z;
    // side3's sign is that of -((b - a) x (c - a)) . (d - a).
    (det.abs() > O3D_ERRBOUND_A * permanent).then_some(-det)
}

/// Which side of the line through `a, b` the point `c` lies on, all seen
/// along axis `along` (its coordinate dropped): the sign is exact, and is the
/// sign of component `along` of `(b - a) x (c - a)`.
pub(crate) fn side2(along: usize, a: &Point, b: &Point, c: &Point) -> f64 {
    let (i, j) = ((along + 1) % 3, (along + 2) % 3);
    // Three points with two alike, or on one axis-aligned line, are
    // collinear (as for `side3`).
    let alike = |p: &Point, q: &Point| p[i] == q[i] && p[j] == q[j];
    if alike(a, b) || alike(b, c) || alike(c, a) || [i, j].iter().any(|&i| a[i] == b[i] && a[i] == c[i]) {
        return 0.0;
    }
    let k = |p: &Point| Coord { x: p[i], y: p[j] };
    orient2d(k(a), k(b), k(c))
}

/// Every value > 0, or every value < 0.
pub(crate) fn strictly_one_side(v: &[f64]) -> bool {
    v.iter().all(|&x| x > 0.0) || v.iter().all(|&x| x < 0.0)
}

/// Some value > 0 and some < 0.
fn on_both_sides(v: &[f64]) -> bool {
    v.iter().any(|&x| x > 0.0) && v.iter().any(|&x| x < 0.0)
}

/// The triangle's three edges.
fn edges(t: &[Point; 3]) -> [(&Point, &Point); 3] {
    [(&t[0], &t[1]), (&t[1], &t[2]), (&t[2], &t[0])]
}

/// The axis along which `t` projects to a triangle with area (`None` when
/// its corners are collinear: a segment or a point).
pub(crate) fn flat_axis(t: &[Point; 3]) -> Option<usize> {
    (0..3).find(|&a| side2(a, &t[0], &t[1], &t[2]) != 0.0)
}

/// Closed segments `pq` and `rs` meet, seen along axis `along`.
fn segments_meet_2d(along: usize, p: &Point, q: &Point, r: &Point, s: &Point) -> bool {
    let o = [side2(along, r, s, p), side2(along, r, s, q), side2(along, p, q, r), side2(along, p, q, s)];
    if strictly_one_side(&o[..2]) || strictly_one_side(&o[2..]) {
        return false;
    }
    if o.iter().any(|&x| x != 0.0) {
        return true;
    }
    // On one line (or points): they meet where their extents do.
    [(along + 1) % 3, (along + 2) % 3]
        .iter()
        .all(|&a| p[a].min(q[a]) <= r[a].max(s[a]) && r[a].min(s[a]) <= p[a].max(q[a]))
}

/// Closed segments `pq` and `rs` (either may be a point) share a point:
/// they are coplanar and meet in each of the three axis projections (one of
/// which is one-to-one on their plane, or line).
fn segments_meet(p: &Point, q: &Point, r: &Point, s: &Point) -> bool {
    side3(p, q, r, s) == 0.0 && (0..3).all(|a| segments_meet_2d(a, p, q, r, s))
}

/// `x` lies in the closed triangle `t`, all seen along axis `along` (along
/// which `t` has area).
pub(crate) fn inside_2d(along: usize, t: &[Point; 3], x: &Point) -> bool {
    !on_both_sides(&edges(t).map(|(a, b)| side2(along, a, b, x)))
}

/// Closed segment `pq` meets the closed triangle `t`, which has area;
/// `sp`, `sq` are `side3` of `p` and `q` against `t`'s plane.
pub(crate) fn segment_meets_triangle(p: &Point, q: &Point, t: &[Point; 3], sp: f64, sq: f64) -> bool {
    if strictly_one_side(&[sp, sq]) {
        return false;
    }
    if sp == 0.0 && sq == 0.0 {
        let Some(along) = flat_axis(t) else { return false };
        return inside_2d(along, t, p)
            || inside_2d(along, t, q)
            || edges(t).iter().any(|(a, b)| segments_meet_2d(along, p, q, a, b));
    }
    // The line pq crosses the plane on the segment; it passes through the
    // triangle when no two of its edges see the line turn opposite ways.
    let pq = q - p;
    let turn = |a: &Point, b: &Point| {
        let (n, m) = normal(&pq, &(a - p));
        certain(&n, &m, &(b - p)).unwrap_or_else(|| side3(p, q, a, b))
    };
    !on_both_sides(&edges(t).map(|(a, b)| turn(a, b)))
}

/// True when the closed triangles share a point, decided exactly. A
/// zero-area triangle is the segment or point its corners span.
pub fn intersects_triangle_triangle(a: &[Point; 3], b: &[Point; 3]) -> bool {
    Aabb::from_points(a).intersects(&Aabb::from_points(b)) && facets_meet(&Facet::new(a), &Facet::new(b))
}

/// [`intersects_triangle_triangle`] of two facets (their boxes not checked).
pub(crate) fn facets_meet(fa: &Facet, fb: &Facet) -> bool {
    let (a, b) = (&fa.t, &fb.t);
    match (fa.flat(), fb.flat()) {
        (None, None) => edges(a).iter().any(|(p, q)| edges(b).iter().any(|(r, s)| segments_meet(p, q, r, s))),
        (None, Some(_)) => {
            edges(a).iter().any(|(p, q)| segment_meets_triangle(p, q, b, fb.side(p), fb.side(q)))
        }
        (Some(_), None) => {
            edges(b).iter().any(|(p, q)| segment_meets_triangle(p, q, a, fa.side(p), fa.side(q)))
        }
        (Some(along), Some(_)) => {
            let sb = b.each_ref().map(|x| fa.side(x));
            let sa = a.each_ref().map(|x| fb.side(x));
            if strictly_one_side(&sb) || strictly_one_side(&sa) {
                return false;
            }
            if sb.iter().all(|&x| x == 0.0) {
                // One plane: a corner of one inside the other, or edges crossing.
                return a.iter().any(|x| inside_2d(along, b, x))
                    || b.iter().any(|x| inside_2d(along, a, x))
                    || edges(a)
                        .iter()
                        .any(|(p, q)| edges(b).iter().any(|(r, s)| segments_meet_2d(along, p, q, r, s)));
            }
            // Planes cross: the triangles' common segment ends on an edge of one of them.
            const EDGES: [(usize, usize); 3] = [(0, 1), (1, 2), (2, 0)];
            EDGES.iter().any(|&(i, j)| segment_meets_triangle(&a[i], &a[j], b, sa[i], sa[j]))
                || EDGES.iter().any(|&(i, j)| segment_meets_triangle(&b[i], &b[j], a, sb[i], sb[j]))
        }
    }
}

/// The contact rule for two triangles: with `d` = 0, they share a point
/// (exact); with `d` > 0, they share a point or lie within `d` (parry's
/// distance). Symmetric in the two triangles.
pub fn triangles_within(a: &[Point; 3], b: &[Point; 3], d: f64) -> bool {
    (d > 0.0 && distance_triangle_triangle(a, b) <= d) || intersects_triangle_triangle(a, b)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn p(x: f64, y: f64, z: f64) -> Point {
        Point::new(x, y, z)
    }

    fn both(a: &[Point; 3], b: &[Point; 3]) -> bool {
        let ab = intersects_triangle_triangle(a, b);
        assert_eq!(ab, intersects_triangle_triangle(b, a), "{a:?} {b:?} symmetric");
        ab
    }

    /// Pairs from tanker2 (seed 0) that parry's GJK called apart in one
    /// order and touching in the other: coplanar faces, vertex on face.
    #[test]
    fn coplanar_faces_of_tanker2_touch_both_ways() {
        let a = [p(4330.5, 0.0, 3651.4375), p(4330.5, 14.0, 3651.4375), p(14.0, 14.0, 3651.4375)];
        let b = [p(2830.5, 14.0, 14.0), p(2840.5, 14.0, 14.0), p(2840.5, 14.0, 5470.1875)];
        assert!(both(&a, &b));
        let a = [p(4330.5, 14.0, 1832.75), p(14.0, 14.0, 1832.75), p(14.0, 14.0, 3651.4375)];
        let b = [p(580.5, 14.0, 14.0), p(590.5, 14.0, 5470.1875), p(580.5, 14.0, 5470.1875)];
        assert!(both(&a, &b));
    }

    #[test]
    fn touching_at_a_vertex_an_edge_a_face_and_one_ulp_apart() {
        let o = 0.1;
        let flat = [p(o, o, o), p(o + 2.0, o, o), p(o, o + 2.0, o)];
        // A corner on the face's interior, the rest above it.
        let on = [p(o + 0.3, o + 0.3, o), p(o + 0.3, o + 0.7, o + 1.0), p(o + 0.9, o + 0.3, o + 1.0)];
        assert!(both(&flat, &on));
        let up = o.next_up();
        let above = [p(o + 0.3, o + 0.3, up), p(o + 0.3, o + 0.7, o + 1.0), p(o + 0.9, o + 0.3, o + 1.0)];
        assert!(!both(&flat, &above), "one ulp above is apart");
        // Sharing only a corner, in crossing planes.
        let corner = [p(o + 2.0, o, o), p(o + 3.0, o, o + 1.0), p(o + 3.0, o + 1.0, o + 1.0)];
        assert!(both(&flat, &corner));
        // Sharing part of an edge, coplanar, on opposite sides of it.
        let beside = [p(o + 0.5, o, o), p(o + 1.5, o, o), p(o + 1.0, o - 1.0, o)];
        assert!(both(&flat, &beside));
        let nudged = [p(o + 0.5, o.next_down(), o), p(o + 1.5, o.next_down(), o), p(o + 1.0, o - 1.0, o)];
        assert!(!both(&flat, &nudged), "one ulp off the edge is apart");
    }

    #[test]
    fn degenerate_triangles_are_their_segments_and_points() {
        let flat = [p(0.0, 0.0, 0.0), p(2.0, 0.0, 0.0), p(0.0, 2.0, 0.0)];
        let through = [p(0.5, 0.5, -1.0), p(0.5, 0.5, 1.0), p(0.5, 0.5, 0.0)];
        assert!(both(&flat, &through));
        let point = [p(1.0, 1.0, 0.0); 3];
        assert!(both(&flat, &point), "a point on the hypotenuse");
        let point = [p(1.0, 1.0f64.next_up(), 0.0); 3];
        assert!(!both(&flat, &point));
        let seg = [p(1.0, 1.0, -3.0), p(1.0, 1.0, 3.0), p(1.0, 1.0, 3.0)];
        assert!(both(&[p(1.0, 1.0, 2.0); 3], &seg), "a point on a segment");
        let crossing = [p(0.0, 1.0, 2.0), p(2.0, 1.0, 2.0), p(2.0, 1.0, 2.0)];
        assert!(both(&seg, &crossing), "two segments crossing");
        let skew = [p(0.0, 1.5, 2.0), p(2.0, 1.5, 2.0), p(1.0, 1.5, 2.0)];
        assert!(!both(&seg, &skew));
    }

    #[test]
    fn clearance_counts_touching_and_distance_at_most_d() {
        let a = [p(0.0, 0.0, 0.0), p(1.0, 0.0, 0.0), p(0.0, 1.0, 0.0)];
        let b = a.map(|q| q + nalgebra::Vector3::new(0.0, 0.0, 3.0));
        assert!(!triangles_within(&a, &b, 0.0) && !triangles_within(&a, &b, 2.5));
        assert!(triangles_within(&a, &b, 3.5) && triangles_within(&b, &a, 3.5));
        assert!(triangles_within(&a, &a, 0.0) && triangles_within(&a, &a, 1.0));
    }

    /// Corners on a coarse grid of 0.1 steps (many coplanar and touching
    /// pairs, coordinates not exact in binary) or anywhere in a cube.
    fn arb_triangle() -> impl Strategy<Value = [Point; 3]> {
        let coarse = prop::array::uniform3(prop::array::uniform3(0i32..4))
            .prop_map(|t| t.map(|c| p(f64::from(c[0]) * 0.1, f64::from(c[1]) * 0.1, f64::from(c[2]) * 0.1)));
        let free = prop::array::uniform3(prop::array::uniform3(-1.0f64..1.0))
            .prop_map(|t| t.map(|c| p(c[0], c[1], c[2])));
        prop_oneof![coarse, free]
    }

    /// Corners on a grid of 1/8 steps: points at quarter steps along a
    /// triangle's edges are exact there.
    fn arb_dyadic() -> impl Strategy<Value = [Point; 3]> {
        prop::array::uniform3(prop::array::uniform3(-16i32..16))
            .prop_map(|t| t.map(|c| p(f64::from(c[0]) / 8.0, f64::from(c[1]) / 8.0, f64::from(c[2]) / 8.0)))
    }

    /// A point on the plane of `t` (dyadic weights of its corners), nudged
    /// by `ulps` steps of its z.
    fn on_plane(t: &[Point; 3], s: u8, u: u8, ulps: i8) -> Point {
        let (s, u) = (f64::from(s) / 8.0, f64::from(u) / 8.0);
        let mut x = t[0] + (t[1] - t[0]) * s + (t[2] - t[0]) * u;
        for _ in 0..ulps.unsigned_abs() {
            x.z = if ulps > 0 { x.z.next_up() } else { x.z.next_down() };
        }
        x
    }

    proptest! {
        /// The filtered side of a point against a facet has the exact
        /// predicate's sign, on the plane, one ulp off it and anywhere.
        #[test]
        fn facet_sides_have_the_exact_sign(
            t in prop_oneof![arb_triangle(), arb_dyadic()],
            far in arb_triangle(),
            s in 0u8..=8, u in 0u8..=8, ulps in -2i8..=2,
        ) {
            let f = Facet::new(&t);
            for x in [on_plane(&t, s, u, ulps), far[0], t[1]] {
                let exact = side3(&t[0], &t[1], &t[2], &x);
                prop_assert_eq!(f.side(&x).signum(), exact.signum(), "{:?} {:?}", t, x);
                prop_assert_eq!(f.side(&x) == 0.0, exact == 0.0);
            }
        }

        /// A segment meets a triangle by the filtered turns exactly when it
        /// does by the exact predicate alone, near the triangle's edges too.
        #[test]
        fn filtered_turns_decide_as_the_exact_ones(
            t in prop_oneof![arb_triangle(), arb_dyadic()],
            s in 0u8..=8, u in 0u8..=8, ulps in -2i8..=2, up in arb_triangle(),
        ) {
            // A segment through a point near the plane, near or on an edge's line.
            let (mid, arm) = (on_plane(&t, s, u, ulps), up[0] - Point::origin());
            let (p, q) = (mid + arm, mid - arm);
            let plane = |x: &Point| side3(&t[0], &t[1], &t[2], x);
            let exact = {
                let (sp, sq) = (plane(&p), plane(&q));
                if strictly_one_side(&[sp, sq]) {
                    false
                } else if sp == 0.0 && sq == 0.0 {
                    segment_meets_triangle(&p, &q, &t, sp, sq)
                } else {
                    !on_both_sides(&edges(&t).map(|(a, b)| side3(&p, &q, a, b)))
                }
            };
            // As the contact tests call it: the plane's sides filtered too.
            let f = Facet::new(&t);
            prop_assert_eq!(segment_meets_triangle(&p, &q, &t, f.side(&p), f.side(&q)), exact);
        }

        /// Symmetric, and never against parry's distance: a touching pair is
        /// within its rounding of 0.
        #[test]
        fn exact_contact_agrees_with_distances(a in arb_triangle(), b in arb_triangle()) {
            let hit = both(&a, &b);
            let d = distance_triangle_triangle(&a, &b);
            prop_assert!(!hit || d < 1e-9, "touching, yet parry measures {d:e}");
        }

        /// A triangle with a corner on another (at an exact point of its
        /// face, edge or corner) touches it, whatever its other corners.
        #[test]
        fn a_corner_on_a_triangle_touches_it(
            a in arb_dyadic(), rest in arb_dyadic(), s in 0u8..=4, t in 0u8..=4,
        ) {
            let t = t.min(4 - s);
            let (s, t) = (f64::from(s) / 4.0, f64::from(t) / 4.0);
            let x = a[0] + (a[1] - a[0]) * s + (a[2] - a[0]) * t;
            prop_assert!(both(&a, &[x, rest[1], rest[2]]));
            prop_assert!(both(&a, &[x, x, rest[2]]), "a segment from the point");
            prop_assert!(both(&a, &[x; 3]), "the point alone");
        }
    }
}
