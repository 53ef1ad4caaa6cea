//! What a query asks of the bounds it meets (rstar's `SelectionFunction`,
//! here with the second question the MKtree's bounds can answer): may the
//! shape meet what a bound holds (or is it ruled out), and does the bound
//! prove that it does (a witness)? Every query kind implements [`Selection`]
//! and runs the one traversal of `traverse/`.
//!
//! Witnesses hold for the true geometry, not for rounded bounds: a box face
//! is tested as its quantized slab (which holds the true face), a voxel
//! cell grown by its tolerance (which holds the surface piece that set it).
//!
//! Every decision follows one contact rule (`geom::contact`): shapes and
//! objects are closed sets, and sharing a point (distance 0: a common face,
//! edge or vertex) is contact, decided exactly; with a clearance d, distance
//! at most d is. Bounds are closed and hold what they bound, so a "may
//! meet" never rules out a touching object.

use super::{QueryError, range};
use crate::geom::{
    Aabb, Frustum, Point, Pose, ShapeError, Sphere, distance_point_triangle, intersects_triangle_box,
    triangles_within,
};
use crate::lod::Voxels;
use crate::scene::Mesh;

/// A query shape as the traversal sees it. Below M a "may meet" may say yes
/// wrongly, never no wrongly; a "holds" or "confirms" may say no wrongly,
/// never yes wrongly; at M (`meets_mesh`) the test is exact.
pub trait Selection {
    /// The shape may meet something inside the closed box `b`.
    fn may_meet_box(&self, b: &Aabb) -> bool;
    /// Every point of `b` meets the shape, so any geometry inside `b` does.
    fn holds_box(&self, b: &Aabb) -> bool;
    /// The shape may meet the surface that voxel set `v` bounds.
    fn may_meet_voxels(&self, v: &Voxels) -> bool {
        let tol = v.grid().tolerance();
        self.may_meet_box(&v.grid().bounds().grown(tol)) && v.cell_boxes().any(|b| self.may_meet_box(&b))
    }
    /// Some cell of `v` (a set of surface cells) proves contact.
    fn confirms_voxels(&self, v: &Voxels) -> bool {
        v.cell_boxes().any(|c| self.holds_box(&c))
    }
    /// The shape meets the exact surface of `mesh` (closed sets: touching
    /// counts); counts triangle tests.
    fn meets_mesh(&self, mesh: &Mesh, triangles_tested: &mut u64) -> bool;
    /// A query that takes stand-ins (the view, `view.rs`): the largest
    /// [`stand_in_error`](Self::stand_in_error) it accepts. The traversal
    /// then settles a node box or an object's bound whose error is at most
    /// this instead of refining it, and reads every part of an object that
    /// meets the shape (a picture needs them all). `None` (every other
    /// query): no stand-ins.
    fn tolerance(&self) -> Option<f64> {
        None
    }
    /// How much the query minds what `b` holds being shown by a stand-in
    /// within `eps_mm` of it (both ways), in the query's own unit (the
    /// view: pixels on screen). With a budget the largest is refined first.
    fn stand_in_error(&self, _b: &Aabb, _eps_mm: f64) -> f64 {
        0.0
    }
    /// Refuses what the query states that no file can hold: a point outside
    /// the coordinate range, an inverted box, a length past
    /// [`MAX_LENGTH`](super::MAX_LENGTH) (`range.rs`). Every public query
    /// entry runs it before reading anything; the default states nothing.
    fn check_input(&self) -> Result<(), QueryError> {
        Ok(())
    }
}

/// A selection by reference is the selection (what `ReadTransaction::select` runs).
impl<T: Selection + ?Sized> Selection for &T {
    fn may_meet_box(&self, b: &Aabb) -> bool {
        (**self).may_meet_box(b)
    }
    fn holds_box(&self, b: &Aabb) -> bool {
        (**self).holds_box(b)
    }
    fn may_meet_voxels(&self, v: &Voxels) -> bool {
        (**self).may_meet_voxels(v)
    }
    fn confirms_voxels(&self, v: &Voxels) -> bool {
        (**self).confirms_voxels(v)
    }
    fn meets_mesh(&self, mesh: &Mesh, triangles_tested: &mut u64) -> bool {
        (**self).meets_mesh(mesh, triangles_tested)
    }
    fn tolerance(&self) -> Option<f64> {
        (**self).tolerance()
    }
    fn stand_in_error(&self, b: &Aabb, eps_mm: f64) -> f64 {
        (**self).stand_in_error(b, eps_mm)
    }
    fn check_input(&self) -> Result<(), QueryError> {
        (**self).check_input()
    }
}

/// A region query's shape.
#[derive(Debug, Clone, PartialEq)]
pub enum Region {
    /// The objects meeting a closed box.
    Box(Aabb),
    /// The objects meeting a closed ball.
    Sphere(Sphere),
    /// The objects meeting a closed view frustum.
    Frustum(Box<Frustum>),
}

impl Region {
    fn contains_point(&self, p: &Point) -> bool {
        match self {
            Region::Box(q) => q.contains_point(p),
            Region::Sphere(s) => s.contains_point(p),
            Region::Frustum(f) => f.contains_point(p),
        }
    }
}

impl Selection for Region {
    fn check_input(&self) -> Result<(), QueryError> {
        match self {
            Region::Box(q) => range::check_box("a box", q),
            Region::Sphere(s) => {
                range::check_point("a sphere's centre", &s.center())?;
                range::check_length("a sphere's radius", s.radius())
            }
            Region::Frustum(f) => {
                f.corners().iter().try_for_each(|c| range::check_point("a frustum's corner", c))
            }
        }
    }

    fn may_meet_voxels(&self, v: &Voxels) -> bool {
        match self {
            // The cells in the query's range, not every cell.
            Region::Box(q) => v.may_meet(q),
            _ => {
                let tol = v.grid().tolerance();
                self.may_meet_box(&v.grid().bounds().grown(tol))
                    && v.cell_boxes().any(|b| self.may_meet_box(&b))
            }
        }
    }

    fn may_meet_box(&self, b: &Aabb) -> bool {
        match self {
            Region::Box(q) => q.intersects(b),
            Region::Sphere(s) => s.intersects_aabb(b),
            Region::Frustum(f) => f.intersects_aabb(b),
        }
    }

    fn holds_box(&self, b: &Aabb) -> bool {
        match self {
            Region::Box(q) => q.contains(b),
            // Convex regions hold a box when they hold its corners.
            _ => b.corners().iter().all(|c| self.contains_point(c)),
        }
    }

    fn confirms_voxels(&self, v: &Voxels) -> bool {
        match self {
            Region::Box(q) => v.holds_a_cell_in(q),
            _ => v.cell_boxes().any(|c| self.holds_box(&c)),
        }
    }

    fn meets_mesh(&self, mesh: &Mesh, n: &mut u64) -> bool {
        if !self.may_meet_box(&mesh.aabb()) {
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
/// clearance d within which a scene object counts as touching it. It meets
/// a scene object when a triangle of each are within d (touching at d = 0),
/// the same test whichever of the two is the query.
#[derive(Debug, Clone, PartialEq)]
pub struct Triangles {
    triangles: Vec<[Point; 3]>,
    boxes: Vec<Aabb>,
    bounds: Aabb,
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
        let boxes: Vec<Aabb> = triangles.iter().map(Aabb::from_points).collect();
        let bounds = boxes.iter().fold(Aabb::EMPTY, |a, b| a.union(b));
        Ok(Triangles { triangles, boxes, bounds, clearance })
    }

    /// The box holding every point within the clearance of the object.
    pub fn aabb(&self) -> Aabb {
        self.bounds.grown(self.clearance)
    }

    /// The clearance d, mm.
    pub fn clearance(&self) -> f64 {
        self.clearance
    }
}

/// A relative margin for the conservative tests of a mesh probe with a
/// clearance: parry measures distances within a rounding error, so a bound
/// that a contact at distance d only grazes must still count as met.
fn slack(b: &Aabb) -> f64 {
    let a = b.to_array();
    1e-9 * a.iter().fold(1.0f64, |m, c| m.max(c.abs()))
}

/// A box holding every point that may be in contact with `b` under a
/// clearance `d`: `b` itself at d = 0 (touching is decided exactly), else
/// `b` grown by d and the slack parry's distances need.
pub(crate) fn reach(b: &Aabb, d: f64) -> Aabb {
    if d == 0.0 { *b } else { b.grown(d + slack(b)) }
}

impl Selection for Triangles {
    fn check_input(&self) -> Result<(), QueryError> {
        range::check_length("a clearance", self.clearance)?;
        if self.triangles.is_empty() {
            return Ok(());
        }
        range::check_box("a posed mesh's box", &self.bounds)
    }

    fn may_meet_box(&self, b: &Aabb) -> bool {
        let g = reach(b, self.clearance);
        g.intersects(&self.bounds)
            && self
                .triangles
                .iter()
                .zip(&self.boxes)
                .any(|(t, tb)| tb.intersects(&g) && intersects_triangle_box(t, &g))
    }

    /// With a clearance d > 0: every point of `b` lies within d of the
    /// surface when its centre does by d less half its diagonal (and the
    /// slack parry's distances need).
    fn holds_box(&self, b: &Aabb) -> bool {
        let reach = self.clearance - b.extent().norm() / 2.0 - slack(b);
        if reach <= 0.0 || !b.within(&self.bounds, self.clearance) {
            return false;
        }
        let c = b.center();
        self.triangles.iter().any(|t| distance_point_triangle(&c, t) <= reach)
    }

    /// Some triangle pair within d by `triangles_within`, its boxes first
    /// within d by `Aabb::within`: both symmetric, and the outer box tests
    /// only drop pairs whose boxes are not within d, so the answer is the
    /// same with the mesh as the query and this object in the scene.
    fn meets_mesh(&self, mesh: &Mesh, n: &mut u64) -> bool {
        let d = self.clearance;
        if !mesh.aabb().within(&self.bounds, d) {
            return false;
        }
        mesh.triangle_points().any(|t| {
            let tb = Aabb::from_points(&t);
            tb.within(&self.bounds, d)
                && self.triangles.iter().zip(&self.boxes).any(|(q, qb)| {
                    if !qb.within(&tb, d) {
                        return false;
                    }
                    *n += 1;
                    triangles_within(q, &t, d)
                })
        })
    }
}

/// Everything: every node is entered, every object confirmed by its box
/// (what walks of the whole tree run: `check`, clash's enumeration).
#[derive(Debug, Clone, Copy, Default)]
pub struct Everything;

impl Selection for Everything {
    fn may_meet_box(&self, _: &Aabb) -> bool {
        true
    }
    fn holds_box(&self, _: &Aabb) -> bool {
        true
    }
    fn meets_mesh(&self, _: &Mesh, _: &mut u64) -> bool {
        true
    }
}
