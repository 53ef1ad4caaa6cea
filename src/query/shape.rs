//! What a traversal tests at each level: a query shape against a box
//! (b(S_n,1), B(S_n,1)), a voxel set (levels 2 .. M-1, through its world
//! boxes) and, at level M, an object's triangles. Box, sphere and frustum
//! tests are exact; a posed mesh with clearance d tests boxes grown by d
//! (which hold every point within d of the box), so it is conservative
//! below M and exact at M, where triangle distances are parry's.

use crate::geom::{
    Aabb, Frustum, Point, Pose, ShapeError, Sphere, distance_triangle_triangle, intersects_triangle_box,
    intersects_triangle_triangle,
};
use crate::lod::Voxels;
use crate::scene::Mesh;

/// A region query's shape.
#[derive(Debug, Clone, PartialEq)]
pub enum Region {
    Box(Aabb),
    Sphere(Sphere),
    Frustum(Box<Frustum>),
}

/// What the traversal asks of a query at each level. Below M a test may say
/// yes wrongly, never no wrongly; at M (`meets_mesh`) it is exact.
pub(crate) trait Probe {
    /// The shape (grown by its clearance) may meet the closed box.
    fn meets_box(&self, b: &Aabb) -> bool;
    /// The shape meets the exact surface of `mesh`; counts triangle tests.
    fn meets_mesh(&self, mesh: &Mesh, triangles_tested: &mut u64) -> bool;
    /// The shape may meet the voxel set: its world boxes, grown by the
    /// voxelization tolerance the set was built with.
    fn meets_voxels(&self, v: &Voxels) -> bool {
        let tol = v.grid().tolerance();
        self.meets_box(&v.grid().bounds().grown(tol))
            && v.world_boxes().iter().any(|b| self.meets_box(&b.grown(tol)))
    }
}

impl Probe for Region {
    fn meets_box(&self, b: &Aabb) -> bool {
        match self {
            Region::Box(q) => q.intersects(b),
            Region::Sphere(s) => s.intersects_aabb(b),
            Region::Frustum(f) => f.intersects_aabb(b),
        }
    }

    fn meets_mesh(&self, mesh: &Mesh, n: &mut u64) -> bool {
        if !self.meets_box(&mesh.aabb()) {
            return false;
        }
        mesh.triangle_points().any(|t| {
            *n += 1;
            match self {
                Region::Box(q) => intersects_triangle_box(&t, q),
                Region::Sphere(s) => s.intersects_triangle(&t),
                Region::Frustum(f) => f.intersects_triangle(&t),
            }
        })
    }
}

/// A query object in world position: its triangles and their boxes, and the
/// clearance d within which a scene object counts as touching it.
#[derive(Debug, Clone, PartialEq)]
pub struct Triangles {
    triangles: Vec<[Point; 3]>,
    boxes: Vec<Aabb>,
    aabb: Aabb,
    clearance: f64,
}

impl Triangles {
    /// `mesh` under `pose` (rotated about its box centre, then moved), with
    /// clearance `clearance` (finite, >= 0).
    pub fn posed(mesh: &Mesh, pose: &Pose, clearance: f64) -> Result<Triangles, ShapeError> {
        if !(clearance.is_finite() && clearance >= 0.0) {
            return Err(ShapeError::Invalid { what: "a clearance", detail: format!("{clearance} mm") });
        }
        let c = mesh.aabb().center();
        let triangles: Vec<[Point; 3]> =
            mesh.triangle_points().map(|t| t.map(|p| pose.apply(&c, &p))).collect();
        let boxes: Vec<Aabb> = triangles.iter().map(|t| Aabb::from_points(t).grown(clearance)).collect();
        let aabb = boxes.iter().fold(Aabb::EMPTY, |a, b| a.union(b));
        Ok(Triangles { triangles, boxes, aabb, clearance })
    }

    /// The box holding every point within the clearance of the object.
    pub fn aabb(&self) -> Aabb {
        self.aabb
    }

    /// The clearance d, mm.
    pub fn clearance(&self) -> f64 {
        self.clearance
    }
}

/// A relative margin for the conservative tests of a mesh probe: parry's
/// GJK decides contact within a tolerance, so a bound that an exact contact
/// only grazes must still count as met.
fn slack(b: &Aabb) -> f64 {
    let a = b.to_array();
    1e-9 * a.iter().fold(1.0f64, |m, c| m.max(c.abs()))
}

impl Probe for Triangles {
    fn meets_box(&self, b: &Aabb) -> bool {
        let g = b.grown(self.clearance + slack(b));
        g.intersects(&self.aabb)
            && self
                .triangles
                .iter()
                .zip(&self.boxes)
                .any(|(t, tb)| tb.intersects(&g) && intersects_triangle_box(t, &g))
    }

    fn meets_mesh(&self, mesh: &Mesh, n: &mut u64) -> bool {
        let d = self.clearance;
        if !mesh.aabb().intersects(&self.aabb) {
            return false;
        }
        mesh.triangle_points().any(|t| {
            let tb = Aabb::from_points(&t);
            tb.intersects(&self.aabb)
                && self.triangles.iter().zip(&self.boxes).any(|(q, qb)| {
                    if !qb.intersects(&tb) {
                        return false;
                    }
                    *n += 1;
                    if d == 0.0 {
                        intersects_triangle_triangle(q, &t)
                    } else {
                        distance_triangle_triangle(q, &t) <= d
                    }
                })
        })
    }
}
