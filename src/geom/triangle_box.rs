//! Exact triangle against box overlap by the separating axis theorem
//! (Akenine-Möller, "Fast 3D triangle-box overlap testing", 2001): the box's
//! three normals, the triangle's normal, and the nine cross products of box
//! and triangle edges. Degenerate triangles (segments, points) are handled by
//! the same axes.

use super::{Aabb, Point, Vector};

/// True when the closed triangle and the closed box share a point.
pub fn intersects_triangle_box(tri: &[Point; 3], b: &Aabb) -> bool {
    let c = b.center();
    let h = b.extent() / 2.0;
    let v = tri.map(|p| p - c);
    // Box normals: the triangle's box against the box.
    for i in 0..3 {
        let (lo, hi) = min_max([v[0][i], v[1][i], v[2][i]]);
        if lo > h[i] || hi < -h[i] {
            return false;
        }
    }
    let e = [v[1] - v[0], v[2] - v[1], v[0] - v[2]];
    // The triangle's plane against the box.
    let n = e[0].cross(&e[1]);
    if n.dot(&v[0]).abs() > h.dot(&n.abs()) {
        return false;
    }
    // Nine edge-edge axes.
    for axis in [Vector::x(), Vector::y(), Vector::z()] {
        for edge in &e {
            let a = axis.cross(edge);
            let (lo, hi) = min_max(v.map(|p| a.dot(&p)));
            let r = h.dot(&a.abs());
            if lo > r || hi < -r {
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

    proptest! {
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
