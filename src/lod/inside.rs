//! Whether a point lies inside the solid a closed mesh bounds: the parity of
//! a ray's crossings, orientation-free (closed meshes need not be oriented).

use crate::geom::{Point, Vector};

/// Fixed, deterministic ray directions, far from the axes so grid-aligned
/// geometry rarely meets a ray at an edge; the next is tried when one is ambiguous.
const DIRECTIONS: [[f64; 3]; 6] = [
    [0.5773, 0.4129, 0.7031],
    [-0.3187, 0.8419, 0.4357],
    [0.7213, -0.5431, 0.2951],
    [-0.6101, -0.3347, -0.7183],
    [0.1973, 0.6679, -0.7177],
    [0.8861, 0.1607, -0.4349],
];

/// True when `p` lies inside the closed triangle set `tris` by ray parity.
/// Points on the surface may go either way: callers only ask about points
/// at least a tolerance away from it, or treat the surface as distance 0.
pub(crate) fn inside(tris: &[[Point; 3]], p: &Point) -> bool {
    // Every direction ambiguous (never seen): call it outside, which only
    // leaves a cell unfilled; surface cells hold the containment anyway.
    DIRECTIONS.iter().find_map(|d| parity(tris, p, &Vector::new(d[0], d[1], d[2]))).unwrap_or(false)
}

/// Odd crossings = inside; None when the ray grazes an edge, a vertex, or a
/// triangle's plane, where counting is unreliable.
fn parity(tris: &[[Point; 3]], p: &Point, d: &Vector) -> Option<bool> {
    const EPS: f64 = 1e-9;
    let mut crossings = 0u32;
    for [a, b, c] in tris {
        let e1 = b - a;
        let e2 = c - a;
        let h = d.cross(&e2);
        let det = e1.dot(&h);
        let scale = e1.norm() * e2.norm();
        if scale == 0.0 {
            continue;
        }
        let s = p - a;
        if det.abs() <= EPS * scale {
            // Parallel: ambiguous only when the ray runs in the triangle's plane.
            let n = e1.cross(&e2);
            if n.dot(&s).abs() <= EPS * n.norm() * (s.norm() + scale.sqrt()) {
                return None;
            }
            continue;
        }
        let inv = 1.0 / det;
        let u = s.dot(&h) * inv;
        let q = s.cross(&e1);
        let v = d.dot(&q) * inv;
        let t = e2.dot(&q) * inv;
        let w = 1.0 - u - v;
        if u < -EPS || v < -EPS || w < -EPS || t < -EPS * scale.sqrt() {
            continue;
        }
        if u <= EPS || v <= EPS || w <= EPS || t <= EPS * scale.sqrt() {
            return None;
        }
        crossings += 1;
    }
    Some(crossings % 2 == 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cube() -> Vec<[Point; 3]> {
        let unit = crate::geom::Aabb::from_array([0.0, 0.0, 0.0, 1.0, 1.0, 1.0]);
        crate::scene::Mesh::of_box(&unit).unwrap().triangle_points().collect()
    }

    #[test]
    fn the_centre_of_a_cube_is_inside_and_points_beside_it_are_not() {
        let c = cube();
        assert!(inside(&c, &Point::new(0.5, 0.5, 0.5)));
        // On the diagonal plane of two triangles' shared edge: still decided.
        assert!(inside(&c, &Point::new(0.25, 0.25, 0.5)));
        assert!(!inside(&c, &Point::new(1.5, 0.5, 0.5)));
        assert!(!inside(&c, &Point::new(-0.5, -0.5, -0.5)));
    }
}
