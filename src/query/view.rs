//! The view query (paper §1, "time-critical rendering"): a cut
//! through the tree that shows everything a camera sees, each part either
//! exact or by a stand-in whose error, seen from the camera, is at most τ
//! pixels. It runs the one traversal (`traverse/`) with a [`Selection`]
//! that takes stand-ins: a node whose box is close enough is settled
//! unread, an object whose finest stored bound is close enough has no
//! geometry read, and with a block budget the largest error is refined
//! first and what the budget leaves stands in at the level reached.
//!
//! What a level is in this file (format-spec/lod.md, group.md): level 1 is
//! a box (a node's, held by its parent's entry; an object's, in its leaf
//! record), levels 2 .. M-1 are voxel bounds, and level M is the exact
//! geometry. The cut holds:
//!
//! - a node at level 1, b(S_n,1): its box, read from its parent (no read of
//!   its own); its error is the box's diagonal, which bounds both ways the
//!   distance between the box and the objects inside it;
//! - a node at a level k < M by its group bound b(S_n,k), where the file
//!   stores one (`tree/group.rs`): the coarsest within τ settles the node,
//!   and with a budget a node is shown by its finest and refined from there
//!   only while the budget pays for its children's records and their group
//!   bounds together, and for refining in turn a child of the same block
//!   that would show coarser: a child the budget left unread would be shown
//!   by its box, or at a coarser level, than the bound it replaced;
//! - a leaf's visible objects at level k < M, B(S_n,k): each by its finest
//!   bound stored up to k, its voxel set (error: the largest cell's
//!   diagonal grown by the voxelization tolerance, lod.md) or else its box
//!   (error: its diagonal);
//! - a leaf's visible objects at level M: exact (error 0).
//!
//! The projected error of a length ε at distance d is the screen-space
//! error of 3D Tiles viewers, ε·h / (2 d tan(fov/2)) pixels for a viewport
//! h pixels high: the length seen face-on at the centre of the view. The
//! distance is that of the nearest visible point of the piece's box; the
//! query uses a lower bound of it (the distance to the box, its nearest
//! corner's depth and the near distance, whichever is largest), so the
//! error it reports is never below the true one. Off the axis of view
//! perspective stretches a length by up to 1/cos² of the angle off axis,
//! which this measure, like 3D Tiles', leaves out.

use std::collections::BTreeMap;

use serde::Serialize;

use super::QueryError;
use super::select::{Region, Selection};
use super::{NodeName, QueryOptions, Seen, Select, TraverseStats, Visitor};
use crate::geom::{Aabb, Camera, Frustum, Point, ShapeError, Vector};
use crate::lod::Voxels;
use crate::scene::{Mesh, ObjectId};
use crate::store::{BlockCache, StorageError};
use crate::tree::{ReadTransaction, Reads};

/// A perspective camera and its viewport. Up is +z, as for [`Camera`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct View {
    /// The camera's position, mm.
    pub eye: Point,
    /// The point it looks at, mm.
    pub target: Point,
    /// Vertical field of view, degrees, in (0, 180).
    pub fov_deg: f64,
    /// Viewport width, pixels.
    pub width_px: u32,
    /// Viewport height, pixels.
    pub height_px: u32,
    /// What the camera sees lies between these distances along the view
    /// direction, mm (0 < near < far).
    pub near_mm: f64,
    /// The far distance, mm.
    pub far_mm: f64,
}

impl View {
    /// The view with its far distance moved to `b`'s farthest corner, so
    /// nothing of `b` in front of the camera is cut off (at least twice near).
    pub fn seeing_all_of(self, b: &Aabb) -> View {
        let far = b.corners().iter().map(|c| (c - self.eye).norm()).fold(0.0f64, f64::max);
        View { far_mm: (far * (1.0 + 1e-9)).max(2.0 * self.near_mm), ..self }
    }

    /// The frustum's camera.
    pub fn camera(&self) -> Camera {
        Camera {
            eye: self.eye,
            target: self.target,
            fov_deg: self.fov_deg,
            aspect: f64::from(self.width_px) / f64::from(self.height_px.max(1)),
            near: self.near_mm,
            far: self.far_mm,
        }
    }

    /// Pixels per unit of length over distance at the centre of the view:
    /// h / (2 tan(fov/2)).
    pub fn focal_px(&self) -> f64 {
        f64::from(self.height_px) / (2.0 * (self.fov_deg.to_radians() / 2.0).tan())
    }

    /// The unit view direction (checked by [`Frustum::from_camera`]).
    fn forward(&self) -> Vector {
        (self.target - self.eye).normalize()
    }

    /// A lower bound of the distance from the eye to any visible point of
    /// `b`: the distance to `b`, its nearest corner's depth along the view
    /// direction (a point's distance is at least its depth) and the near
    /// distance, whichever is largest.
    pub fn nearest_visible_mm(&self, b: &Aabb) -> f64 {
        let e = self.eye;
        let to_box = (0..3)
            .map(|i| {
                let d = (b.min[i] - e[i]).max(e[i] - b.max[i]).max(0.0);
                d * d
            })
            .sum::<f64>()
            .sqrt();
        let f = self.forward();
        let depth = b.corners().iter().map(|c| (c - e).dot(&f)).fold(f64::INFINITY, f64::min);
        to_box.max(depth).max(self.near_mm)
    }

    /// The projected error, pixels, of a length `eps_mm` at `distance_mm`.
    pub fn projected_px(&self, eps_mm: f64, distance_mm: f64) -> f64 {
        if eps_mm == 0.0 { 0.0 } else { eps_mm * self.focal_px() / distance_mm }
    }

    fn check(&self) -> Result<(), ShapeError> {
        if self.width_px == 0 || self.height_px == 0 {
            return Err(ShapeError::Invalid { what: "a view", detail: "a viewport of 0 pixels".into() });
        }
        Ok(())
    }
}

/// The tolerance and block budget of a view.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ViewOptions {
    /// τ, pixels (finite, >= 0; 0 asks for exact geometry everywhere).
    pub tolerance_px: f64,
    /// At most this many block reads; `None` for no limit.
    pub budget: Option<u64>,
    /// Keep what each piece of the cut shows ([`CutNode::shapes`]), to draw it.
    pub shapes: bool,
}

/// What a piece of the cut shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Bound {
    /// b(S_n,1): the node's box.
    NodeBox,
    /// b(S_n,k), 2 <= k < M: the node's group bound, from its group block
    /// (format-spec/group.md); nothing below it is read.
    GroupBound,
    /// B(S_n,k), k < M: each visible object of a leaf by its finest bound
    /// stored up to k (its box at worst).
    ObjectBounds,
    /// Level M: a leaf's visible objects, exact.
    Exact,
}

/// A stand-in or an exact object, as drawn.
#[derive(Debug, Clone, PartialEq)]
pub enum Shape {
    /// A box.
    Box(Aabb),
    /// A voxel bound.
    Voxels(Voxels),
    /// The exact mesh.
    Mesh(Mesh),
}

/// One thing a piece of the cut shows: a node's box, or an object (a part
/// of one stored as parts) by its bound or exact.
#[derive(Debug, Clone, PartialEq)]
pub struct Shown {
    /// `None` for a node's box.
    pub object: Option<ObjectId>,
    /// The box its distance is measured to (a node's or part's box as stored).
    pub aabb: Aabb,
    /// How far the shape may be from what it stands for, both ways, mm.
    pub eps_mm: f64,
    /// The shape drawn.
    pub shape: Shape,
}

/// One piece of a cut: a node at a level.
#[derive(Debug, Clone, PartialEq)]
pub struct CutNode {
    /// The node: a node box's id (known unless it is a second child in a
    /// block the cut did not read), its parent and which child it is; for
    /// objects, the id of their leaf only (its parent is not looked up).
    pub node: NodeName,
    /// The level k shown: 1 for a box, M for exact.
    pub level: u8,
    /// What the piece shows.
    pub bound: Bound,
    /// The node's box, or the union of its shown objects' boxes.
    pub aabb: Aabb,
    /// The objects shown (sorted; empty for a node box, whose objects are not read).
    pub objects: Vec<ObjectId>,
    /// The largest error of what is shown, mm.
    pub eps_mm: f64,
    /// A lower bound of the distance to its nearest visible point, mm.
    pub distance_mm: f64,
    /// The largest projected error over what is shown, pixels.
    pub error_px: f64,
    /// With [`ViewOptions::shapes`]: what is shown.
    pub shapes: Vec<Shown>,
}

/// A view's answer: the cut, front to back.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewCut {
    /// Ordered by `distance_mm`, then node id and level.
    pub nodes: Vec<CutNode>,
    /// The largest projected error in the cut, pixels (at most τ unless the
    /// budget stopped refinement).
    pub max_error_px: f64,
    /// τ, pixels, as asked.
    pub tolerance_px: f64,
    /// The block budget, as asked.
    pub budget: Option<u64>,
    /// What the traversal did.
    pub stats: TraverseStats,
}

impl ViewCut {
    /// Objects shown exact (level M).
    pub fn exact_objects(&self) -> usize {
        self.nodes.iter().filter(|n| n.bound == Bound::Exact).map(|n| n.objects.len()).sum()
    }
}

/// The view as a selection: what meets the frustum, nothing held or
/// confirmed before its error is small enough (a picture needs every
/// visible part, not a proof of contact).
struct Sight {
    view: View,
    frustum: Region,
    tolerance: f64,
}

impl Selection for Sight {
    fn check_input(&self) -> Result<(), QueryError> {
        self.frustum.check_input()
    }
    fn may_meet_box(&self, b: &Aabb) -> bool {
        self.frustum.may_meet_box(b)
    }
    fn holds_box(&self, _: &Aabb) -> bool {
        false
    }
    fn may_meet_voxels(&self, v: &Voxels) -> bool {
        self.frustum.may_meet_voxels(v)
    }
    fn confirms_voxels(&self, _: &Voxels) -> bool {
        false
    }
    fn meets_mesh(&self, mesh: &Mesh, n: &mut u64) -> bool {
        self.frustum.meets_mesh(mesh, n)
    }
    fn tolerance(&self) -> Option<f64> {
        Some(self.tolerance)
    }
    fn stand_in_error(&self, b: &Aabb, eps_mm: f64) -> f64 {
        self.view.projected_px(eps_mm, self.view.nearest_visible_mm(b))
    }
}

/// Gathers the cut from what the traversal shows.
struct Cut<'v> {
    view: &'v View,
    m: u8,
    shapes: bool,
    /// Keyed by (leaf, level, bound); node boxes by their order of arrival.
    pieces: BTreeMap<(u32, u8, Bound, usize), CutNode>,
    boxes: usize,
}

impl Cut<'_> {
    fn piece(&mut self, key: (u32, u8, Bound, usize), node: NodeName) -> &mut CutNode {
        self.pieces.entry(key).or_insert_with(|| CutNode {
            node,
            level: key.1,
            bound: key.2,
            aabb: Aabb::EMPTY,
            objects: Vec::new(),
            eps_mm: 0.0,
            distance_mm: f64::INFINITY,
            error_px: 0.0,
            shapes: Vec::new(),
        })
    }

    /// Adds a shown piece of `aabb` within `eps` mm of what it shows.
    fn add(&mut self, key: (u32, u8, Bound, usize), node: NodeName, aabb: &Aabb, eps: f64) -> &mut CutNode {
        let d = self.view.nearest_visible_mm(aabb);
        let error = self.view.projected_px(eps, d);
        let p = self.piece(key, node);
        p.aabb = p.aabb.union(aabb);
        p.eps_mm = p.eps_mm.max(eps);
        p.distance_mm = p.distance_mm.min(d);
        p.error_px = p.error_px.max(error);
        p
    }
}

impl Visitor for Cut<'_> {
    fn object(&mut self, seen: &Seen) -> Result<(), StorageError> {
        if !seen.decision.accepted {
            return Ok(());
        }
        let node = NodeName { id: Some(seen.leaf), parent: None, child: 0 };
        let object = seen.decision.object;
        let (level, bound, eps, shape) = match (seen.mesh, seen.bound) {
            (Some(mesh), _) => (self.m, Bound::Exact, 0.0, Shape::Mesh(mesh.clone())),
            (None, Some((k, v))) => {
                (k, Bound::ObjectBounds, v.grid().max_cell_diagonal(), Shape::Voxels(v.clone()))
            }
            (None, None) => (1, Bound::ObjectBounds, seen.aabb.extent().norm(), Shape::Box(seen.aabb)),
        };
        let keep = self.shapes;
        let p = self.add((seen.leaf, level, bound, 0), node, &seen.aabb, eps);
        if p.objects.last() != Some(&object) {
            p.objects.push(object);
        }
        if keep {
            p.shapes.push(Shown { object: Some(object), aabb: seen.aabb, eps_mm: eps, shape });
        }
        Ok(())
    }

    fn group(
        &mut self,
        name: &NodeName,
        frame: &Aabb,
        level: u8,
        voxels: &Voxels,
        eps: f64,
    ) -> Result<(), StorageError> {
        self.boxes += 1;
        let key = (name.id.unwrap_or(u32::MAX), level, Bound::GroupBound, self.boxes);
        let keep = self.shapes;
        let p = self.add(key, *name, frame, eps);
        if keep {
            p.shapes.push(Shown {
                object: None,
                aabb: *frame,
                eps_mm: eps,
                shape: Shape::Voxels(voxels.clone()),
            });
        }
        Ok(())
    }

    fn stand_in(&mut self, name: &NodeName, frame: &Aabb) -> Result<(), StorageError> {
        self.boxes += 1;
        let key = (name.id.unwrap_or(u32::MAX), 1, Bound::NodeBox, self.boxes);
        let keep = self.shapes;
        let eps = frame.extent().norm();
        let p = self.add(key, *name, frame, eps);
        if keep {
            p.shapes.push(Shown { object: None, aabb: *frame, eps_mm: eps, shape: Shape::Box(*frame) });
        }
        Ok(())
    }
}

impl ReadTransaction {
    /// The cut of the tree `view` needs at `opts`' tolerance and budget,
    /// reading through `cache` (a pool kept across frames) when given.
    ///
    /// ```
    /// # use mktree::db::{CreateOptions, Database};
    /// # use mktree::bulk::BuildParams;
    /// # use mktree::geom::Point;
    /// # use mktree::query::{View, ViewOptions};
    /// # use mktree::scene::generate::{GenOptions, Preset, generate_scene};
    /// # let dir = tempfile::tempdir()?;
    /// # let scene = generate_scene(&GenOptions { preset: Preset::Tanker1, objects: None, seed: 1 })?;
    /// # let db = Database::create(dir.path().join("t1.mkt"), CreateOptions::default())?;
    /// # let mut w = db.begin_write()?;
    /// # w.bulk_load(&scene, &BuildParams::paper(), &|_| {})?;
    /// # w.commit()?;
    /// let r = db.begin_read()?;
    /// let b = scene.aabb();
    /// let eye = Point::new(b.min.x - 2000.0, b.center().y, b.center().z);
    /// let view = View { eye, target: b.center(), fov_deg: 60.0, width_px: 640, height_px: 480,
    ///                   near_mm: 10.0, far_mm: 1.0 }.seeing_all_of(&b);
    /// let opts = ViewOptions { tolerance_px: 2.0, budget: None, shapes: false };
    /// let cut = r.view(&view, &opts, None)?;
    /// assert!(cut.max_error_px <= 2.0 && !cut.nodes.is_empty());
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn view(
        &self,
        view: &View,
        opts: &ViewOptions,
        cache: Option<&BlockCache>,
    ) -> Result<ViewCut, QueryError> {
        view.check()?;
        let tau = opts.tolerance_px;
        if !(tau.is_finite() && tau >= 0.0) {
            let detail = format!("a tolerance of {tau} px (finite, >= 0)");
            return Err(ShapeError::Invalid { what: "a view", detail }.into());
        }
        let frustum = Region::Frustum(Box::new(Frustum::from_camera(&view.camera())?));
        let sight = Sight { view: *view, frustum, tolerance: tau };
        sight.check_input()?;
        let m = self.pager().lod_levels();
        let mut cut = Cut { view, m, shapes: opts.shapes, pieces: BTreeMap::new(), boxes: 0 };
        let q = QueryOptions { lod: None, budget: opts.budget, bounds_up_to: None };
        let stats = {
            let mut select =
                Select::new(self, self.root(), &sight, &q, Reads::new(cache), None)?.visited_by(&mut cut);
            while let Some(d) = select.next_decision() {
                d?;
            }
            select.stats()
        };
        let mut nodes: Vec<CutNode> = cut.pieces.into_values().collect();
        for n in &mut nodes {
            n.objects.sort_unstable();
            n.objects.dedup();
        }
        nodes.sort_by(|a, b| {
            a.distance_mm
                .total_cmp(&b.distance_mm)
                .then(a.node.id.cmp(&b.node.id))
                .then(a.level.cmp(&b.level))
        });
        let max_error_px = nodes.iter().map(|n| n.error_px).fold(0.0, f64::max);
        Ok(ViewCut { nodes, max_error_px, tolerance_px: tau, budget: opts.budget, stats })
    }
}
