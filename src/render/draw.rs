//! Pictures of what the tree stores: a view's cut (each piece coloured by
//! its level), and one node's level of detail as the paper's Figures 10-17
//! show them, b(S_n,k) (its objects' bounds merged into one voxel solid per
//! lattice level) or B(S_n,k) (each object's bound). Stand-ins become
//! triangle meshes here: a box its 12 triangles, a voxel set the boundary
//! of its cells with coplanar faces merged (`lod/faces.rs`), an exact object
//! its own triangles.

use super::raster::{Image, Projector};
use crate::db::{Level, Piece};
use crate::geom::{Aabb, Point, ShapeError, Vector};
use crate::lod::{Grid, Voxels};
use crate::query::{Bound, Shape, View, ViewCut};
use crate::scene::Mesh;

impl Shape {
    /// The stand-in (or the object) as a closed triangle mesh, to draw or
    /// export; an empty box gives a mesh of no triangle.
    pub fn mesh(&self) -> Mesh {
        match self {
            Shape::Box(b) => Mesh::of_box(b).unwrap_or_else(empty_mesh),
            Shape::Voxels(v) => v.boundary_mesh(),
            Shape::Mesh(m) => m.clone(),
        }
    }
}

fn empty_mesh() -> Mesh {
    Mesh::from_parts(Point::origin(), Vec::new(), Vec::new())
}

/// The colour of a piece: node boxes red, object boxes orange, voxel
/// bounds from yellow (coarse) to green (fine), exact objects blue-grey.
pub fn level_colour(bound: Bound, level: u8, m: u8) -> [u8; 3] {
    match bound {
        Bound::NodeBox => [214, 64, 56],
        Bound::GroupBound => {
            // Group bounds, level 2 .. M-1, from purple to light violet.
            let t = f64::from(level.saturating_sub(2)) / f64::from(m.saturating_sub(3).max(1));
            let mix = |a: f64, b: f64| (a + (b - a) * t.min(1.0)).round() as u8;
            [mix(150.0, 196.0), mix(70.0, 150.0), mix(190.0, 230.0)]
        }
        Bound::Exact => [104, 132, 178],
        Bound::ObjectBounds if level <= 1 => [235, 150, 60],
        Bound::ObjectBounds => {
            // Level 2 .. M-1 from yellow to green.
            let t = f64::from(level.saturating_sub(2)) / f64::from(m.saturating_sub(3).max(1));
            let mix = |a: f64, b: f64| (a + (b - a) * t.min(1.0)).round() as u8;
            [mix(232.0, 96.0), mix(200.0, 176.0), mix(64.0, 96.0)]
        }
    }
}

/// The projector of `view`, or why the view cannot be drawn.
fn projector(view: &View) -> Result<Projector, ShapeError> {
    if view.width_px == 0 || view.height_px == 0 {
        return Err(ShapeError::Invalid { what: "a picture", detail: "a viewport of 0 pixels".into() });
    }
    Projector::new(view).ok_or(ShapeError::Invalid {
        what: "a picture",
        detail: "the view direction is vertical or null (up is +z)".into(),
    })
}

/// Draws `mesh` in `colour`.
fn draw_mesh(p: &Projector, img: &mut Image, mesh: &Mesh, colour: [u8; 3]) {
    for t in mesh.triangle_points() {
        p.triangle(img, &t, colour);
    }
}

/// A picture of `cut` as `view` sees it: every shape of every piece
/// (the cut must have been made with [`ViewOptions::shapes`](crate::query::ViewOptions)),
/// coloured by its level, in a file of M levels.
pub fn draw_cut(view: &View, cut: &ViewCut, m: u8) -> Result<Image, ShapeError> {
    let p = projector(view)?;
    let mut img = Image::new(view.width_px, view.height_px);
    for piece in &cut.nodes {
        let colour = level_colour(piece.bound, piece.level, m);
        for s in &piece.shapes {
            draw_mesh(&p, &mut img, &s.shape.mesh(), colour);
        }
    }
    Ok(img)
}

/// The voxel sets of `sets` merged, one set per lattice level (sets of one
/// level share the lattice's planes, so their union is exact): b(S_n,k)
/// from the objects' B(o,k). A union too large for one grid keeps its sets apart.
pub fn group_bound(sets: &[&Voxels]) -> Vec<Voxels> {
    let mut levels: Vec<u8> = sets.iter().map(|v| v.grid().level()).collect();
    levels.sort_unstable();
    levels.dedup();
    let mut out = Vec::new();
    for level in levels {
        let these: Vec<&&Voxels> = sets.iter().filter(|v| v.grid().level() == level).collect();
        let bounds = these.iter().fold(Aabb::EMPTY, |b, v| b.union(v.grid().bounds()));
        let union =
            these.first().and_then(|v| Grid::new(v.grid().lattice(), level, &bounds).ok()).and_then(|g| {
                let mut u = Voxels::empty(g);
                these.iter().all(|v| v.lift_into(&mut u).is_ok()).then_some(u)
            });
        match union {
            Some(u) => out.push(u),
            None => out.extend(these.into_iter().map(|v| (*v).clone())),
        }
    }
    out
}

/// A picture of level `k` of a node as fetched ([`crate::ReadTransaction::fetch_level`]):
/// B(S_n,k) as each object's bound, or with `group` b(S_n,k), the bounds
/// merged (objects bounded by their boxes stay boxes; a node's box is a box).
pub fn draw_level(view: &View, level: &Level, k: u8, m: u8, group: bool) -> Result<Image, ShapeError> {
    let p = projector(view)?;
    let mut img = Image::new(view.width_px, view.height_px);
    let bound = if k == m { Bound::Exact } else { Bound::ObjectBounds };
    for piece in &level.pieces {
        match piece {
            Piece::Box { aabb, .. } => {
                draw_mesh(&p, &mut img, &Shape::Box(*aabb).mesh(), level_colour(Bound::NodeBox, 1, m))
            }
            Piece::ObjectBoxes(b) => {
                for (_, aabb) in b {
                    draw_mesh(
                        &p,
                        &mut img,
                        &Shape::Box(*aabb).mesh(),
                        level_colour(Bound::ObjectBounds, 1, m),
                    );
                }
            }
            Piece::ObjectVoxels(v) => {
                let colour = level_colour(bound, k, m);
                let sets: Vec<&Voxels> = v.iter().map(|(_, v)| v).collect();
                let merged = if group { group_bound(&sets) } else { sets.into_iter().cloned().collect() };
                for s in &merged {
                    draw_mesh(&p, &mut img, &s.boundary_mesh(), colour);
                }
            }
            Piece::Objects(o) => {
                for (_, mesh) in o {
                    draw_mesh(&p, &mut img, mesh, level_colour(Bound::Exact, m, m));
                }
            }
            Piece::Group { level, voxels, .. } => {
                draw_mesh(&p, &mut img, &voxels.boundary_mesh(), level_colour(Bound::GroupBound, *level, m))
            }
        }
    }
    Ok(img)
}

/// A view of `b` whole, from in front, to the left and above (a paper
/// figure's angle), `width` x `height` pixels, `fov_deg` degrees high.
pub fn framing(b: &Aabb, width_px: u32, height_px: u32, fov_deg: f64) -> View {
    let c = b.center();
    let r = (b.extent().norm() / 2.0).max(1.0);
    // Far enough that the bounding sphere fits the vertical field of view.
    let d = r / (fov_deg.to_radians() / 2.0).sin() * 1.05;
    let dir = Vector::new(-0.55, -0.7, 0.45).normalize();
    View {
        eye: c + dir * d,
        target: c,
        fov_deg,
        width_px,
        height_px,
        near_mm: (d - r).max(d * 1e-3),
        far_mm: d + r,
    }
}
