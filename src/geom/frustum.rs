//! View frusta: the six planes of a perspective camera, tested against boxes
//! and triangles exactly by the separating axis theorem (two convex sets
//! are disjoint if and only if their projections on one of the candidate
//! axes are: each set's face normals and the cross products of their edges).

use super::{Aabb, Point, ShapeError, Vector};

/// A perspective camera: the frustum's defining numbers. Up is +z.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// The camera's position, mm.
    pub eye: Point,
    /// The point it looks at, mm.
    pub target: Point,
    /// Vertical field of view, degrees, in (0, 180).
    pub fov_deg: f64,
    /// Width over height, > 0.
    pub aspect: f64,
    /// Distances along the view direction, 0 < near < far.
    pub near: f64,
    /// The far distance, mm.
    pub far: f64,
}

/// A closed view frustum (a convex hexahedron).
#[derive(Debug, Clone, PartialEq)]
pub struct Frustum {
    /// Near rectangle then far rectangle, each counter-clockwise.
    corners: [Point; 8],
    /// Outward face normals: near, far, then the four sides.
    normals: [Vector; 6],
    /// Edge directions: the rectangles' two, then the four lateral edges.
    edges: [Vector; 6],
}

impl Frustum {
    /// The frustum of `camera`; refuses non-finite numbers, a field of view
    /// outside (0, 180), a non-positive aspect, near >= far, and a view
    /// direction along z (up is +z, so it would leave "right" undefined).
    pub fn from_camera(c: &Camera) -> Result<Frustum, ShapeError> {
        let what = "a frustum";
        let numbers = [c.fov_deg, c.aspect, c.near, c.far];
        if !c.eye.iter().chain(c.target.iter()).chain(&numbers).all(|x| x.is_finite()) {
            return Err(ShapeError::NotFinite { what });
        }
        let bad = |detail: &str| Err(ShapeError::Invalid { what, detail: detail.into() });
        if !(c.fov_deg > 0.0 && c.fov_deg < 180.0) {
            return bad("the field of view is in (0, 180) degrees");
        }
        if c.aspect <= 0.0 || c.near <= 0.0 || c.near >= c.far {
            return bad("aspect > 0 and 0 < near < far");
        }
        let f = (c.target - c.eye)
            .try_normalize(0.0)
            .ok_or(ShapeError::Invalid { what, detail: "the eye is the target".into() })?;
        let Some(r) = f.cross(&Vector::z()).try_normalize(1e-12) else {
            return bad("the view direction is vertical (up is +z)");
        };
        let u = r.cross(&f);
        let t = (c.fov_deg.to_radians() / 2.0).tan();
        let rect = |d: f64| {
            let (h, w) = (d * t, d * t * c.aspect);
            let m = c.eye + f * d;
            [m - r * w - u * h, m + r * w - u * h, m + r * w + u * h, m - r * w + u * h]
        };
        let (n, fa) = (rect(c.near), rect(c.far));
        let corners = [n[0], n[1], n[2], n[3], fa[0], fa[1], fa[2], fa[3]];
        let lateral = |i: usize| fa[i] - n[i];
        // A side's outward normal: its lateral edge crossed with the near
        // edge it starts from, oriented away from the frustum's centre.
        let centre = Point::from((0..8).fold(Vector::zeros(), |s, i| s + corners[i].coords) / 8.0);
        let side = |i: usize| {
            let j = (i + 1) % 4;
            let nrm = (n[j] - n[i]).cross(&lateral(i)).normalize();
            if nrm.dot(&(n[i] - centre)) < 0.0 { -nrm } else { nrm }
        };
        Ok(Frustum {
            corners,
            normals: [-f, f, side(0), side(1), side(2), side(3)],
            edges: [r, u, lateral(0), lateral(1), lateral(2), lateral(3)],
        })
    }

    /// The eight corners, near rectangle first.
    pub fn corners(&self) -> &[Point; 8] {
        &self.corners
    }

    /// The smallest box holding the frustum.
    pub fn aabb(&self) -> Aabb {
        Aabb::from_points(&self.corners)
    }

    /// True when the closed frustum and the closed box share a point.
    pub fn intersects_aabb(&self, b: &Aabb) -> bool {
        let box_corners: Vec<Point> = (0..8)
            .map(|i| {
                Point::new(
                    if i & 1 == 0 { b.min.x } else { b.max.x },
                    if i & 2 == 0 { b.min.y } else { b.max.y },
                    if i & 4 == 0 { b.min.z } else { b.max.z },
                )
            })
            .collect();
        let axes = [Vector::x(), Vector::y(), Vector::z()];
        self.overlaps(&box_corners, &axes, &axes)
    }

    /// True when `p` lies in the frustum shrunk by a rounding margin (1e-9
    /// of the coordinates' magnitude): between the planes of every pair of
    /// opposite faces, which for a convex solid is inside it.
    pub fn contains_point(&self, p: &Point) -> bool {
        let mag = self.corners.iter().flat_map(|c| c.iter()).fold(0.0f64, |m, c| m.max(c.abs()));
        self.normals.iter().all(|n| {
            let len = n.norm();
            if len == 0.0 {
                return true;
            }
            let proj = |q: &Point| q.coords.dot(n) / len;
            let (lo, hi) =
                self.corners.iter().map(proj).fold((f64::MAX, f64::MIN), |(a, b), x| (a.min(x), b.max(x)));
            let x = proj(p);
            let slack = 1e-9 * mag;
            x >= lo + slack && x <= hi - slack
        })
    }

    /// True when the closed frustum and the closed triangle share a point.
    pub fn intersects_triangle(&self, t: &[Point; 3]) -> bool {
        let e = [t[1] - t[0], t[2] - t[1], t[0] - t[2]];
        self.overlaps(t, &[e[0].cross(&e[1])], &e)
    }

    /// SAT against a convex set given by its points, face normals and edges.
    fn overlaps(&self, points: &[Point], normals: &[Vector], edges: &[Vector]) -> bool {
        let crosses = edges.iter().flat_map(|a| self.edges.iter().map(move |b| a.cross(b)));
        let mut axes = self.normals.iter().copied().chain(normals.iter().copied()).chain(crosses);
        !axes.any(|a| separates(&a, &self.corners, points))
    }
}

/// True when `axis` separates the two point sets' projections. A null axis
/// (parallel edges, a degenerate triangle's normal) separates nothing.
fn separates(axis: &Vector, a: &[Point], b: &[Point]) -> bool {
    if axis.norm_squared() == 0.0 {
        return false;
    }
    let range = |p: &[Point]| {
        p.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), q| {
            let x = axis.dot(&q.coords);
            (lo.min(x), hi.max(x))
        })
    };
    let ((a0, a1), (b0, b1)) = (range(a), range(b));
    a1 < b0 || b1 < a0
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> Camera {
        Camera {
            eye: Point::origin(),
            target: Point::new(10.0, 0.0, 0.0),
            fov_deg: 90.0,
            aspect: 1.0,
            near: 1.0,
            far: 10.0,
        }
    }

    #[test]
    fn boxes_in_front_inside_behind_and_beside() {
        let f = Frustum::from_camera(&camera()).unwrap();
        let b = |a| Aabb::from_array(a);
        assert!(f.intersects_aabb(&b([4.0, -1.0, -1.0, 5.0, 1.0, 1.0])));
        assert!(!f.intersects_aabb(&b([-5.0, -1.0, -1.0, -2.0, 1.0, 1.0])), "behind the eye");
        assert!(!f.intersects_aabb(&b([11.0, -1.0, -1.0, 12.0, 1.0, 1.0])), "past far");
        // At x = 2 the half-width is 2 (fov 90): y in [2.5, 3] is outside,
        // although the box overlaps the frustum's bounding box.
        assert!(!f.intersects_aabb(&b([1.9, 2.5, -0.1, 2.0, 3.0, 0.1])));
        assert!(f.aabb().intersects(&b([1.9, 2.5, -0.1, 2.0, 3.0, 0.1])));
        let p = Point::new;
        assert!(f.intersects_triangle(&[p(5.0, 0.0, 0.0), p(50.0, 0.0, 0.0), p(5.0, 1.0, 0.0)]));
        assert!(!f.intersects_triangle(&[p(2.0, 3.0, 0.0), p(2.0, 4.0, 0.0), p(2.5, 3.0, 0.0)]));
    }

    #[test]
    fn bad_cameras_are_refused() {
        let c = camera();
        assert!(Frustum::from_camera(&Camera { fov_deg: 180.0, ..c }).is_err());
        assert!(Frustum::from_camera(&Camera { near: 10.0, ..c }).is_err());
        assert!(Frustum::from_camera(&Camera { target: Point::new(0.0, 0.0, 5.0), ..c }).is_err());
        assert!(Frustum::from_camera(&Camera { eye: Point::new(f64::NAN, 0.0, 0.0), ..c }).is_err());
    }
}
