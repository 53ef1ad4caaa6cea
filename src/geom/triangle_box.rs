//! Exact triangle against box overlap by the separating axis theorem
//! (Akenine-Möller, "Fast 3D triangle-box overlap testing", 2001): the box's
//! three normals, the triangle's normal, and the nine cross products of box
//! and triangle edges. A triangle that only touches the box (distance 0)
//! meets it, and one a rounding step away does not. Each axis is first
//! tried in floating point with a bound on its rounding; only an axis that
//! comes within its bound of touching is decided by exact signs
//! (`contact.rs`). Degenerate triangles (segments, points) are handled by
//! the same axes.

use super::contact::{side2, side3, strictly_one_side};
use super::{Aabb, Point, Vector};

/// True when the closed triangle and the closed box share a point (exact).
pub fn intersects_triangle_box(tri: &[Point; 3], b: &Aabb) -> bool {
    TriangleBoxTest::new(tri, b).intersects(b)
}

/// A triangle prepared for exact overlap tests against many boxes inside
/// one region (the cells a voxelizer tries): its axes, their projections
/// and their rounding bounds are computed once, so a box costs a dot
/// product per axis. Answers equal [`intersects_triangle_box`]'s.
pub struct TriangleBoxTest {
    tri: [Point; 3],
    /// Per coordinate, the triangle's extent (the box normals' test).
    lo: [f64; 3],
    hi: [f64; 3],
    /// Boxes inside it share the rounding bounds below.
    region: Aabb,
    /// The plane and edge axes that are not null, `count` of them.
    axes: [Axis; 10],
    count: usize,
}

/// One candidate separating axis: projections are taken about the
/// triangle's first corner.
#[derive(Clone, Copy, Default)]
struct Axis {
    a: [f64; 3],
    abs: [f64; 3],
    /// The triangle's projection about its first corner.
    min: f64,
    max: f64,
    /// A bound on how far rounding moves a gap on this axis, for any box of the region.
    err: f64,
}

fn dot(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

impl TriangleBoxTest {
    /// Prepares `tri` for boxes inside `region` (a box outside it is still
    /// answered exactly, only slower).
    pub fn new(tri: &[Point; 3], region: &Aabb) -> TriangleBoxTest {
        const U: f64 = f64::EPSILON / 2.0;
        let (lo, hi) = (
            [0, 1, 2].map(|i| min_max([tri[0][i], tri[1][i], tri[2][i]]).0),
            [0, 1, 2].map(|i| min_max([tri[0][i], tri[1][i], tri[2][i]]).1),
        );
        let o = tri[0];
        let w = [Vector::zeros(), tri[1] - o, tri[2] - o];
        // Per coordinate, a bound on every term a gap sums: the corners and
        // any box centre about `o`, and any box's reach about its centre.
        let centre = (region.min - o).abs().sup(&(region.max - o).abs());
        let size = w[1].abs().sup(&w[2].abs()) + centre + (region.max - region.min);
        // How far rounding may move a gap on an axis whose components are off
        // by `off`: corners, centre, products and sums are each off by a few
        // U of themselves; twice that, for both projections, is generous.
        let bound = |a: Vector, off: Vector| 2.0 * (off + a.abs() * (8.0 * U)).dot(&size);
        let mut test =
            TriangleBoxTest { tri: *tri, lo, hi, region: *region, axes: [Axis::default(); 10], count: 0 };
        let mut push = |a: Vector, err: f64| {
            let (min, max) = min_max(w.map(|p| a.dot(&p)));
            let abs = a.abs();
            test.axes[test.count] = Axis { a: [a.x, a.y, a.z], abs: [abs.x, abs.y, abs.z], min, max, err };
            test.count += 1;
        };
        // Edges from the coordinates themselves: a component is 0 exactly when
        // the coordinates agree, and otherwise off by at most U of itself.
        let e = [tri[1] - tri[0], tri[2] - tri[1], tri[0] - tri[2]];
        // The plane; each normal component is off by at most 5 U of its two products.
        let n = e[0].cross(&e[1]);
        let n_off = Vector::from_fn(|k, _| {
            let (i, j) = ((k + 1) % 3, (k + 2) % 3);
            5.0 * U * ((e[0][i] * e[1][j]).abs() + (e[0][j] * e[1][i]).abs())
        });
        // A null plane axis (a degenerate triangle) has no test, and one
        // along a box axis, exactly (both products of two components are
        // 0), is the box normal's test, done exactly above.
        let exact_zeros = (0..3).filter(|&k| n[k] == 0.0 && n_off[k] == 0.0).count();
        if exact_zeros < 2 {
            push(n, bound(n, n_off));
        }
        // The box axis other than i and j crossed with an edge: its components
        // i, j are (-edge_j, edge_i), each an edge component, so one bound
        // serves all nine.
        let longest = e[0].abs().sup(&e[1].abs()).sup(&e[2].abs()).max();
        let err = bound(Vector::repeat(longest), Vector::repeat(longest * U));
        for (i, j) in [(1, 2), (2, 0), (0, 1)] {
            for edge in &e {
                // An edge along that box axis gives a null axis, and an edge
                // along i or j one along j or i, the box normal's: no test.
                if edge[i] == 0.0 || edge[j] == 0.0 {
                    continue;
                }
                let mut a = Vector::zeros();
                (a[i], a[j]) = (-edge[j], edge[i]);
                push(a, err);
            }
        }
        test
    }

    /// True when the closed triangle and the closed box `b` share a point (exact).
    pub fn intersects(&self, b: &Aabb) -> bool {
        if b.is_empty() || (0..3).any(|i| self.lo[i] > b.max[i] || self.hi[i] < b.min[i]) {
            return false;
        }
        if !self.region.contains(b) {
            return TriangleBoxTest::new(&self.tri, b).intersects(b);
        }
        self.rounded_axes(b).unwrap_or_else(|| exact_axes(&self.tri, b))
    }

    /// The plane and edge axes in floating point, for a box of the region
    /// the box normals do not separate: `Some` answer when every axis
    /// separates or overlaps by more than its rounding can move it, `None`
    /// when one is too close to call.
    fn rounded_axes(&self, b: &Aabb) -> Option<bool> {
        let o = &self.tri[0];
        let (mut centre, mut outer, mut inner) = ([0.0; 3], [0.0; 3], [0.0; 3]);
        for i in 0..3 {
            let c = (b.min[i] + b.max[i]) * 0.5;
            // About c the box reaches at most `outer` and at least `inner` each way.
            let (l, h) = (c - b.min[i], b.max[i] - c);
            (outer[i], inner[i]) = if l > h { (l, h) } else { (h, l) };
            centre[i] = c - o[i];
        }
        let mut close = false;
        for axis in &self.axes[..self.count] {
            let d = dot(&axis.a, &centre);
            match apart(axis.min - d, axis.max - d, dot(&axis.abs, &outer), dot(&axis.abs, &inner), axis.err)
            {
                Some(true) => return Some(false),
                Some(false) => {}
                None => close = true,
            }
        }
        (!close).then_some(true)
    }
}

/// On one axis, a triangle projecting to [`lo`, `hi`] and a box reaching at most
/// `outer` and at least `inner` either way from 0, each off by up to `err`:
/// `Some(true)` when they are surely apart, `Some(false)` when they surely
/// overlap, `None` when too close to call (or not numbers: an overflow).
fn apart(lo: f64, hi: f64, outer: f64, inner: f64, err: f64) -> Option<bool> {
    if lo - outer > err || -outer - hi > err {
        return Some(true);
    }
    (lo - inner < -err && -inner - hi < -err).then_some(false)
}

/// The plane and edge axes by exact signs, where the box normals do not
/// separate (an edge axis is only tried on the side of its edge away from
/// the triangle: beyond the third corner is for the box normals).
fn exact_axes(tri: &[Point; 3], b: &Aabb) -> bool {
    // The triangle's plane. The side of a point is affine in it, so over the
    // box it is extreme at the corners the normal's signs pick (each sign an
    // exact 2D orientation); the plane misses the box when both extremes lie
    // strictly on one side.
    let [a, c, d] = tri;
    let normal = [0, 1, 2].map(|axis| side2(axis, a, c, d));
    let corner = |sign: f64| {
        Point::from(std::array::from_fn(|i| if normal[i] * sign > 0.0 { b.max[i] } else { b.min[i] }))
    };
    if strictly_one_side(&[side3(a, c, d, &corner(1.0)), side3(a, c, d, &corner(-1.0))]) {
        return false;
    }
    // Nine edge axes: seen along each box axis, the box is a rectangle and
    // the edge a line, with the side of a point affine in it. The axis
    // separates when the rectangle lies strictly on the side of the line
    // away from the third corner (either side when the triangle is seen
    // edge-on there); the far side of the third corner is another edge's
    // line or a box normal.
    for along in 0..3 {
        let (i, j) = ((along + 1) % 3, (along + 2) % 3);
        for (p, q, r) in
            [(&tri[0], &tri[1], &tri[2]), (&tri[1], &tri[2], &tri[0]), (&tri[2], &tri[0], &tri[1])]
        {
            // The gradient of side2(p, q, x) in (x_i, x_j) is (p_j - q_j, q_i - p_i).
            let extreme = |up: bool| {
                let mut x = b.min;
                x[i] = if (p[j] > q[j]) == up && p[j] != q[j] { b.max[i] } else { b.min[i] };
                x[j] = if (q[i] > p[i]) == up && q[i] != p[i] { b.max[j] } else { b.min[j] };
                side2(along, p, q, &x)
            };
            let third = side2(along, p, q, r);
            if (third >= 0.0 && extreme(true) < 0.0) || (third <= 0.0 && extreme(false) > 0.0) {
                return false;
            }
        }
    }
    true
}

fn min_max(x: [f64; 3]) -> (f64, f64) {
    (x[0].min(x[1]).min(x[2]), x[0].max(x[1]).max(x[2]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn p(x: f64, y: f64, z: f64) -> Point {
        Point::new(x, y, z)
    }

    #[test]
    fn separated_by_a_diagonal_plane_only() {
        let b = Aabb::from_array([0.0, 0.0, 0.0, 1.0, 1.0, 1.0]);
        // The boxes overlap, but the triangle (x + y >= 3.1) passes by the corner (1, 1).
        let t = [p(2.2, 0.9, 0.5), p(0.9, 2.2, 0.5), p(2.2, 2.2, 0.5)];
        assert!(!intersects_triangle_box(&t, &b));
        // Moved in to x + y >= 1.95, it contains the corner.
        let t = [p(1.9, 0.05, 0.5), p(0.05, 1.9, 0.5), p(1.9, 1.9, 0.5)];
        assert!(intersects_triangle_box(&t, &b));
    }

    #[test]
    fn a_big_triangle_through_the_box_and_a_touching_one() {
        let b = Aabb::from_array([0.0, 0.0, 0.0, 1.0, 1.0, 1.0]);
        let t = [p(-10.0, -10.0, 0.5), p(10.0, -10.0, 0.5), p(0.0, 10.0, 0.5)];
        assert!(intersects_triangle_box(&t, &b));
        let t = [p(1.0, 0.0, 0.0), p(2.0, 0.0, 0.0), p(2.0, 1.0, 0.0)];
        assert!(intersects_triangle_box(&t, &b), "closed sets touch at a vertex");
        let seg = [p(-1.0, 0.5, 0.5), p(2.0, 0.5, 0.5), p(2.0, 0.5, 0.5)];
        assert!(intersects_triangle_box(&seg, &b), "a degenerate triangle is a segment");
    }

    #[test]
    fn touching_is_meeting_and_one_step_off_is_not() {
        let b = Aabb::from_array([0.1, 0.1, 0.1, 0.7, 0.7, 0.7]);
        // A corner on the upper x face (coordinates binary cannot hold).
        let t = [p(0.7, 0.3, 0.3), p(1.3, 0.2, 0.9), p(1.1, 0.9, 0.2)];
        assert!(intersects_triangle_box(&t, &b));
        let t = [p(0.7f64.next_up(), 0.3, 0.3), p(1.3, 0.2, 0.9), p(1.1, 0.9, 0.2)];
        assert!(!intersects_triangle_box(&t, &b));
        // The triangle's plane x + y + z = 3 holds the corner (1, 1, 1) only.
        let b = Aabb::from_array([0.0, 0.0, 0.0, 1.0, 1.0, 1.0]);
        let t = [p(2.0, 0.5, 0.5), p(0.5, 2.0, 0.5), p(0.5, 0.5, 2.0)];
        assert!(intersects_triangle_box(&t, &b));
        let e = 2f64.powi(-50);
        let t = [p(2.0 + e, 0.5, 0.5), p(0.5, 2.0 + e, 0.5), p(0.5, 0.5, 2.0 + e)];
        assert!(!intersects_triangle_box(&t, &b));
        // An edge on the line x + y = 2, seen along z, through the edge x = y = 1.
        let t = [p(2.0, 0.0, 0.5), p(0.0, 2.0, 0.5), p(2.0, 2.0, 0.5)];
        assert!(intersects_triangle_box(&t, &b));
        let t = [p(2.0 + e, 0.0, 0.5), p(0.0, 2.0 + e, 0.5), p(2.0, 2.0, 0.5)];
        assert!(!intersects_triangle_box(&t, &b));
    }

    /// The box with opposite corners `[x0, y0, z0]` and `[x1, y1, z1]`, in any order.
    fn corners(v: [f64; 6]) -> Aabb {
        Aabb::from_points(&[p(v[0], v[1], v[2]), p(v[3], v[4], v[5])])
    }

    /// The box's surface as 12 triangles.
    fn faces(b: &Aabb) -> Vec<[Point; 3]> {
        let c = b.corners();
        let quads = [[0, 1, 3, 2], [4, 5, 7, 6], [0, 1, 5, 4], [2, 3, 7, 6], [0, 2, 6, 4], [1, 3, 7, 5]];
        quads.iter().flat_map(|q| [[c[q[0]], c[q[1]], c[q[2]]], [c[q[0]], c[q[2]], c[q[3]]]]).collect()
    }

    proptest! {
        /// Two exact tests agree to the last case: a triangle meets a closed
        /// box when a corner lies in it or it meets a face of it. Corners
        /// on a coarse grid of 0.1 steps make ties (touching) common.
        #[test]
        fn agrees_with_the_exact_triangle_test_on_the_faces(
            c in prop::array::uniform9(-1i32..5), b in prop::array::uniform6(0i32..4),
        ) {
            let c = c.map(|x| f64::from(x) * 0.1);
            let t = [p(c[0], c[1], c[2]), p(c[3], c[4], c[5]), p(c[6], c[7], c[8])];
            let b = corners(b.map(|x| f64::from(x) * 0.1));
            let via_faces = t.iter().any(|x| b.contains_point(x))
                || faces(&b).iter().any(|f| super::super::intersects_triangle_triangle(&t, f));
            prop_assert_eq!(intersects_triangle_box(&t, &b), via_faces);
        }

        /// The rounded axes, when they decide, decide as the exact ones: on
        /// grid and free corners, at any scale and offset, slivers included,
        /// for a triangle prepared for the box alone or for a larger region.
        #[test]
        fn rounded_axes_decide_as_the_exact_ones(
            c in prop::array::uniform9(-1i32..5), b in prop::array::uniform6(0i32..4),
            jitter in prop::array::uniform9(-1e-6f64..1e-6), scale in prop_oneof![Just(0.1), Just(1e4 + 0.1)],
            offset in prop_oneof![Just(0.0), Just(5000.3)], sliver in any::<bool>(), grown in 0i32..3,
        ) {
            let at = |x: i32, j: f64| offset + (f64::from(x) + j) * scale;
            let j = |i: usize| if sliver { jitter[i] } else { 0.0 };
            let corner = |v: usize| [0, 1, 2].map(|k| at(c[3 * v + k], j(3 * v + k)));
            let mut t = [0, 1, 2].map(|v| Point::from(corner(v)));
            if sliver {
                // The third corner on the first edge, off it by the jitter only.
                t[2] = t[0] + (t[1] - t[0]) * 0.5 + Vector::new(jitter[0], jitter[4], jitter[8]);
            }
            let b = corners(b.map(|x| at(x, 0.0)));
            let region = b.grown(f64::from(grown) * scale);
            let test = TriangleBoxTest::new(&t, &region);
            let normals_separate = (0..3).any(|i| test.lo[i] > b.max[i] || test.hi[i] < b.min[i]);
            if let Some(r) = test.rounded_axes(&b).filter(|_| !normals_separate) {
                prop_assert_eq!(r, exact_axes(&t, &b));
            }
            prop_assert_eq!(test.intersects(&b), intersects_triangle_box(&t, &b));
        }

        /// Against sampling: if any sampled point of the triangle lies in the
        /// box, the test must say they intersect.
        #[test]
        fn never_misses_a_sampled_contact(
            c in prop::array::uniform9(-2.0f64..3.0),
            u in 0.0f64..1.0, w in 0.0f64..1.0,
        ) {
            let t = [p(c[0], c[1], c[2]), p(c[3], c[4], c[5]), p(c[6], c[7], c[8])];
            let b = Aabb::from_array([0.0, 0.0, 0.0, 1.0, 1.0, 1.0]);
            let (u, w) = if u + w > 1.0 { (1.0 - u, 1.0 - w) } else { (u, w) };
            let q = t[0] + (t[1] - t[0]) * u + (t[2] - t[0]) * w;
            if b.contains_point(&q) {
                prop_assert!(intersects_triangle_box(&t, &b));
            }
        }
    }
}
