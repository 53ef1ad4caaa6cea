//! The distances best-first queries order the one traversal by (rstar's
//! `nearest_neighbor.rs`, over the MKtree's boxes): for each box, a lower
//! bound of the distance of anything inside it; for an object's exact
//! geometry, its distance. The traversal yields an object when its exact
//! distance is the least in its queue, so objects come in order of distance.
//!
//! The order holds in floating point, not only on paper: a box's bound is
//! computed on the box grown by a margin that grows with the box, so it is
//! never above the bound of a box inside it; and an object's distance is
//! never below the bound of its triangles' boxes (each triangle's distance
//! is held at or above its box's bound, a change within rounding). Every
//! value is a function of the query and the stored coordinates alone, so
//! brute force over a scene computes the same numbers.

use super::QueryError;
use super::select::Selection;
use crate::geom::{Aabb, Point, Ray, distance_point_triangle};
use crate::scene::Mesh;

/// A best-first query's distance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Rank {
    /// From the point to the nearest point of an object's surface (its
    /// triangles; 0 on it, and inside a closed object too).
    Nearest(Point),
    /// Along the ray, followed to `reach`: where it first meets the surface.
    Ray { ray: Ray, reach: f64 },
}

/// A lower bound of the distance from `p` to anything in `b`: the distance
/// to `b` grown by 1e-9 of its coordinates' and `p`'s magnitude (a margin
/// no smaller for a box holding `b`).
fn point_box_distance(p: &Point, b: &Aabb) -> f64 {
    if b.is_empty() {
        return f64::INFINITY;
    }
    let m = b.min.iter().chain(b.max.iter()).chain(p.iter()).fold(0.0f64, |m, c| m.max(c.abs()));
    let g = b.grown(1e-9 * m);
    (0..3)
        .map(|i| {
            let d = (g.min[i] - p[i]).max(p[i] - g.max[i]).max(0.0);
            d * d
        })
        .sum::<f64>()
        .sqrt()
}

impl Rank {
    /// A lower bound of the distance of anything in `b`; `None` when
    /// nothing in it can be met.
    pub(crate) fn box_distance(&self, b: &Aabb) -> Option<f64> {
        match self {
            Rank::Nearest(p) => Some(point_box_distance(p, b)),
            Rank::Ray { ray, reach } => ray.span_in(b, *reach).map(|s| s.0),
        }
    }

    /// The distance of `mesh`'s surface, `None` when it is not met; counts
    /// the triangles tested.
    pub(crate) fn mesh_distance(&self, mesh: &Mesh, n: &mut u64) -> Option<f64> {
        let mut best: Option<f64> = None;
        for t in mesh.triangle_points() {
            let tb = Aabb::from_points(&t);
            let d = match self {
                Rank::Nearest(p) => {
                    let bound = point_box_distance(p, &tb);
                    if best.is_some_and(|b| bound > b) {
                        continue;
                    }
                    *n += 1;
                    Some(distance_point_triangle(p, &t).max(bound))
                }
                Rank::Ray { ray, reach } => {
                    if ray.span_in(&tb, *reach).is_none_or(|s| best.is_some_and(|b| s.0 > b)) {
                        continue;
                    }
                    *n += 1;
                    ray.hit_triangle(&t, *reach)
                }
            };
            best = match (best, d) {
                (Some(b), Some(d)) => Some(b.min(d)),
                (b, d) => b.or(d),
            };
        }
        best
    }
}

/// A best-first query as a selection: what may be met is what has a
/// distance; nothing is held or confirmed before its exact distance is known.
impl Selection for Rank {
    fn check_input(&self) -> Result<(), QueryError> {
        match self {
            Rank::Nearest(p) => super::range::check_point("a nearest query's point", p),
            Rank::Ray { ray, .. } => super::range::check_point("a ray's origin", &ray.origin()),
        }
    }
    fn may_meet_box(&self, b: &Aabb) -> bool {
        self.box_distance(b).is_some()
    }
    fn holds_box(&self, _: &Aabb) -> bool {
        false
    }
    fn confirms_voxels(&self, _: &crate::lod::Voxels) -> bool {
        false
    }
    fn meets_mesh(&self, mesh: &Mesh, n: &mut u64) -> bool {
        self.mesh_distance(mesh, n).is_some()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_box_bound_is_never_above_the_bound_of_a_box_inside_it() {
        let p = Point::new(-3.0, 7.5, 1e6);
        let inner = Aabb::from_array([1.0, 2.0, 3.0, 4.0, 5.0, 6.0]);
        let outer = Aabb::from_array([0.5, 2.0, 2.0, 4.0, 9.0, 6.0]);
        assert!(point_box_distance(&p, &outer) <= point_box_distance(&p, &inner));
        assert_eq!(point_box_distance(&Point::new(2.0, 3.0, 4.0), &inner), 0.0);
        assert_eq!(point_box_distance(&p, &Aabb::EMPTY), f64::INFINITY);
    }
}
