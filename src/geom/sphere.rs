//! Spheres: a region query's ball, tested exactly against boxes (the
//! distance from the centre to the box) and triangles (to the triangle).

use super::{Aabb, Point, ShapeError, distance_point_triangle};

/// A closed ball in world millimetres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sphere {
    center: Point,
    radius: f64,
}

impl Sphere {
    /// The ball of `radius` (>= 0) around `center`, all finite.
    pub fn new(center: Point, radius: f64) -> Result<Sphere, ShapeError> {
        if !center.iter().all(|c| c.is_finite()) || !radius.is_finite() {
            return Err(ShapeError::NotFinite { what: "a sphere" });
        }
        if radius < 0.0 {
            return Err(ShapeError::Invalid { what: "a sphere", detail: format!("radius {radius} < 0") });
        }
        Ok(Sphere { center, radius })
    }

    /// The centre.
    pub fn center(&self) -> Point {
        self.center
    }

    /// The radius, mm.
    pub fn radius(&self) -> f64 {
        self.radius
    }

    /// The smallest box holding the ball.
    pub fn aabb(&self) -> Aabb {
        Aabb::new(self.center, self.center).grown(self.radius)
    }

    /// True when the closed ball and the closed box share a point (exact:
    /// the squared distance from the centre to its clamp into the box).
    pub fn intersects_aabb(&self, b: &Aabb) -> bool {
        let d2: f64 = (0..3)
            .map(|i| {
                let c = self.center[i];
                let d = (b.min[i] - c).max(0.0).max(c - b.max[i]);
                d * d
            })
            .sum();
        d2 <= self.radius * self.radius
    }

    /// True when `p` lies in the ball shrunk by a rounding margin (1e-9 of
    /// the coordinates' magnitude): a yes holds for the exact ball.
    pub fn contains_point(&self, p: &Point) -> bool {
        let slack = 1e-9 * (self.center.iter().fold(0.0f64, |m, c| m.max(c.abs())) + self.radius);
        let r = self.radius - slack;
        r >= 0.0 && (p - self.center).norm_squared() <= r * r
    }

    /// True when the closed ball and the closed triangle share a point.
    pub fn intersects_triangle(&self, t: &[Point; 3]) -> bool {
        distance_point_triangle(&self.center, t) <= self.radius
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_ball_touches_a_box_corner_only_within_its_radius() {
        let b = Aabb::from_array([0.0, 0.0, 0.0, 1.0, 1.0, 1.0]);
        let s = Sphere::new(Point::new(2.0, 2.0, 1.0), 2f64.sqrt()).unwrap();
        assert!(s.intersects_aabb(&b));
        let s = Sphere::new(Point::new(2.0, 2.0, 1.0), 1.4).unwrap();
        assert!(!s.intersects_aabb(&b));
        assert!(Sphere::new(Point::origin(), -1.0).is_err());
        assert!(Sphere::new(Point::new(f64::NAN, 0.0, 0.0), 1.0).is_err());
    }
}
