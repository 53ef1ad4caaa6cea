//! Rays: a half-line from an origin along a direction, followed up to a
//! distance (its own maximum, or past everything a query can meet).
//!
//! What is exact: whether the ray meets a closed triangle (touching an edge
//! or a vertex counts, the rule of `contact.rs`) is decided exactly, with
//! orientation predicates, for the closed segment from the origin to the
//! f64 point [`Ray::end`] (the point at the distance followed, rounded to
//! f64: so the segment's direction is the ray's to within that rounding).
//! The distance t of a hit is computed in floating point, then held inside
//! the span in which the ray crosses the triangle's box as [`Ray::span_in`]
//! measures it. Box tests are conservative: a box is grown by a margin of
//! 1e-9 of its coordinates' and the origin's magnitude before the slab
//! test, so a box the segment meets is never missed, and a box's entry
//! distance is never above the entry of a box inside it, nor above the
//! distance of a hit on a triangle inside it.

use super::contact::side3;
use super::{Aabb, Point, ShapeError, Vector, intersects_triangle_triangle};

/// A ray in world millimetres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ray {
    origin: Point,
    /// Unit length.
    direction: Vector,
    max_distance: Option<f64>,
}

impl Ray {
    /// The ray from `origin` along `direction` (not zero; scaled to unit
    /// length), up to `max_distance` (>= 0) when given; all finite.
    pub fn new(origin: Point, direction: Vector, max_distance: Option<f64>) -> Result<Ray, ShapeError> {
        let finite = origin.iter().chain(direction.iter()).chain(max_distance.iter()).all(|c| c.is_finite());
        if !finite {
            return Err(ShapeError::NotFinite { what: "a ray" });
        }
        let norm = direction.norm();
        if norm == 0.0 || !norm.is_finite() {
            return Err(ShapeError::Invalid { what: "a ray", detail: "its direction is zero".into() });
        }
        if let Some(d) = max_distance.filter(|&d| d < 0.0) {
            return Err(ShapeError::Invalid { what: "a ray", detail: format!("max distance {d} < 0") });
        }
        Ok(Ray { origin, direction: direction / norm, max_distance })
    }

    /// The origin.
    pub fn origin(&self) -> Point {
        self.origin
    }

    /// The direction, unit length.
    pub fn direction(&self) -> Vector {
        self.direction
    }

    /// The distance beyond which nothing counts, when given.
    pub fn max_distance(&self) -> Option<f64> {
        self.max_distance
    }

    /// The point at distance `t`.
    pub fn at(&self, t: f64) -> Point {
        self.origin + self.direction * t
    }

    /// The distance a query follows the ray among objects inside `scene`:
    /// its maximum, or else past the farthest corner of `scene`.
    pub fn reach(&self, scene: &Aabb) -> f64 {
        self.max_distance.unwrap_or_else(|| {
            let far = scene.corners().iter().map(|c| (c - self.origin).norm()).fold(0.0, f64::max);
            if far.is_finite() { far * (1.0 + 1e-6) + 1.0 } else { 0.0 }
        })
    }

    /// The end of the segment whose hits are decided exactly: the point at
    /// distance `reach`, rounded to f64.
    pub fn end(&self, reach: f64) -> Point {
        self.at(reach)
    }

    /// 1e-9 of the magnitude of `b`'s coordinates and the origin's: growing
    /// boxes by it keeps slab tests conservative, and it grows with the box
    /// (a box inside `b` gets no larger margin).
    fn margin(&self, b: &Aabb) -> f64 {
        let m =
            b.min.iter().chain(b.max.iter()).chain(self.origin.iter()).fold(0.0f64, |m, c| m.max(c.abs()));
        1e-9 * m
    }

    /// The distances `(t0, t1)`, within `[0, reach]`, between which the ray
    /// is inside `b` grown by its margin; `None` when it misses.
    pub fn span_in(&self, b: &Aabb, reach: f64) -> Option<(f64, f64)> {
        if b.is_empty() {
            return None;
        }
        let g = b.grown(self.margin(b));
        let (mut t0, mut t1) = (0.0f64, reach);
        for i in 0..3 {
            let (o, d) = (self.origin[i], self.direction[i]);
            if d == 0.0 {
                if o < g.min[i] || o > g.max[i] {
                    return None;
                }
                continue;
            }
            let (near, far) = if d > 0.0 { (g.min[i], g.max[i]) } else { (g.max[i], g.min[i]) };
            t0 = t0.max((near - o) / d);
            t1 = t1.min((far - o) / d);
        }
        (t0 <= t1).then_some((t0, t1))
    }

    /// The distance at which the ray, followed to `reach`, first meets the
    /// closed triangle `t` (touching counts), or `None` (see the module
    /// notes for what is exact).
    pub fn hit_triangle(&self, t: &[Point; 3], reach: f64) -> Option<f64> {
        let (lo, hi) = self.span_in(&Aabb::from_points(t), reach)?;
        let (o, e) = (self.origin, self.end(reach));
        if !intersects_triangle_triangle(&[o, e, e], t) {
            return None;
        }
        Some((entry(&o, &e, t) * reach).min(hi).max(lo))
    }
}

/// The fraction along segment `oe` of its first point in the closed
/// triangle `t`, which it meets (floating point, in `[0, 1]`).
fn entry(o: &Point, e: &Point, t: &[Point; 3]) -> f64 {
    let [a, b, c] = t;
    if side3(a, b, c, o) != 0.0 || side3(a, b, c, e) != 0.0 {
        // The segment crosses the triangle's plane at one point.
        let n = (b - a).cross(&(c - a));
        let (fo, fe) = (n.dot(&(o - a)), n.dot(&(e - a)));
        let d = fo - fe;
        return if d != 0.0 { (fo / d).clamp(0.0, 1.0) } else { 0.0 };
    }
    // In the triangle's plane (or the triangle is a segment or a point): the
    // segment starts inside, or enters through an edge.
    if intersects_triangle_triangle(&[*o, *o, *o], t) {
        return 0.0;
    }
    [(a, b), (b, c), (c, a)]
        .into_iter()
        .filter(|(p, q)| intersects_triangle_triangle(&[*o, *e, *e], &[**p, **q, **q]))
        .map(|(p, q)| segment_entry(o, e, p, q))
        .fold(1.0, f64::min)
}

/// The fraction along segment `oe` of its first point on segment `pq`,
/// which it meets (floating point, in `[0, 1]`).
fn segment_entry(o: &Point, e: &Point, p: &Point, q: &Point) -> f64 {
    let (u, w) = (e - o, q - p);
    let c = u.cross(&w);
    let cc = c.norm_squared();
    if cc > 1e-24 * u.norm_squared() * w.norm_squared() {
        return ((p - o).cross(&w).dot(&c) / cc).clamp(0.0, 1.0);
    }
    // On one line: where the nearer end of pq lies along oe.
    let uu = u.norm_squared();
    if uu == 0.0 {
        return 0.0;
    }
    ((p - o).dot(&u) / uu).min((q - o).dot(&u) / uu).clamp(0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn p(x: f64, y: f64, z: f64) -> Point {
        Point::new(x, y, z)
    }

    fn down_from(x: f64, y: f64) -> Ray {
        Ray::new(p(x, y, 10.0), Vector::new(0.0, 0.0, -1.0), None).unwrap()
    }

    #[test]
    fn a_ray_through_an_edge_or_a_vertex_hits_and_one_ulp_beside_misses() {
        let t = [p(0.0, 0.0, 0.0), p(4.0, 0.0, 0.0), p(0.0, 4.0, 0.0)];
        let hit = |r: &Ray| r.hit_triangle(&t, 20.0);
        assert_eq!(hit(&down_from(1.0, 1.0)), Some(10.0));
        assert_eq!(hit(&down_from(2.0, 2.0)), Some(10.0), "on the hypotenuse");
        assert_eq!(hit(&down_from(4.0, 0.0)), Some(10.0), "a vertex");
        assert_eq!(hit(&down_from(2.0, 0.0)), Some(10.0), "an edge");
        assert_eq!(hit(&down_from(2.0, 2f64.next_up())), None);
        assert_eq!(hit(&down_from(2.0, -0.0f64.next_up())), None, "just beside the edge y = 0");
        // Too short to reach it, or pointing away.
        assert_eq!(down_from(1.0, 1.0).hit_triangle(&t, 9.5), None);
        let up = Ray::new(p(1.0, 1.0, 10.0), Vector::new(0.0, 0.0, 1.0), None).unwrap();
        assert_eq!(up.hit_triangle(&t, 20.0), None);
    }

    #[test]
    fn a_ray_in_a_triangles_plane_enters_through_its_edge() {
        let t = [p(2.0, 0.0, 0.0), p(6.0, 0.0, 0.0), p(2.0, 4.0, 0.0)];
        let r = Ray::new(p(0.0, 1.0, 0.0), Vector::new(1.0, 0.0, 0.0), None).unwrap();
        assert_eq!(r.hit_triangle(&t, 10.0), Some(2.0));
        let inside = Ray::new(p(3.0, 1.0, 0.0), Vector::new(1.0, 0.0, 0.0), None).unwrap();
        assert_eq!(inside.hit_triangle(&t, 10.0), Some(0.0));
        // A triangle that is a segment across the ray.
        let seg = [p(5.0, 1.0, -1.0), p(5.0, 1.0, 1.0), p(5.0, 1.0, 1.0)];
        assert_eq!(r.hit_triangle(&seg, 10.0), Some(5.0));
    }

    #[test]
    fn bad_rays_are_refused() {
        assert!(Ray::new(Point::origin(), Vector::zeros(), None).is_err());
        assert!(Ray::new(Point::origin(), Vector::x(), Some(-1.0)).is_err());
        assert!(Ray::new(p(f64::NAN, 0.0, 0.0), Vector::x(), None).is_err());
        assert!(Ray::new(Point::origin(), Vector::new(f64::MAX, f64::MAX, 0.0), None).is_err());
    }

    proptest! {
        /// A hit lies in its triangle's box span, which lies in the span of
        /// any box holding the triangle: the order best-first queries need.
        #[test]
        fn hits_lie_within_the_spans_of_the_boxes_around_them(
            o in prop::array::uniform3(-10.0f64..10.0),
            d in prop::array::uniform3(-1.0f64..1.0),
            t in prop::array::uniform3(prop::array::uniform3(-5.0f64..5.0)),
            grow in 0.0f64..3.0,
        ) {
            let Ok(r) = Ray::new(o.into(), d.into(), None) else { return Ok(()) };
            let t = t.map(Point::from);
            let outer = Aabb::from_points(&t).grown(grow);
            let reach = r.reach(&outer);
            if let Some(hit) = r.hit_triangle(&t, reach) {
                let (t0, t1) = r.span_in(&outer, reach).expect("the box around a hit is met");
                prop_assert!(t0 <= hit && hit <= t1, "{t0} <= {hit} <= {t1}");
            }
        }
    }
}
