//! Group bounds b(S_n,k) (paper §1.4-1.5, format-spec/group.md): for a node
//! n and a level k = 2 .. M-1, the cells of a grid over n's box that the
//! surfaces of S_n's objects touch, a voxel shell drawn as its boundary with
//! coplanar faces merged (`faces.rs`).
//!
//! A node's grid at level k is the grid of whole lattice cells over its box
//! as its record holds it, at the finest lattice level from the level's
//! floor (the meta block's `lod_grid_level[k]`, the objects' eps_k) whose
//! grid has at most `budget_k` cells (`cuberille_bits` at k = 2, then
//! [`LEVEL_FACTOR`] times more per level). So a node small enough has the
//! paper's fixed eps_k, and a larger one a coarser grid, whose error (its
//! largest cell's diagonal) grows with its size: what a view needs, which
//! draws a far node coarsely. A reader finds the same grid from the box
//! and the meta block, so it knows a bound's error before reading it.
//!
//! Bounds are built bottom up: a leaf's from its objects' surfaces, an
//! internal node's by lifting its children's bounds into its coarser grid
//! (levels nest on one lattice, `lattice.rs`), never from the subtree's
//! meshes. A lifted cell holds a child cell, which holds a piece of a
//! surface, so the bound still contains every object of S_n and every
//! point of it lies within its largest cell's diagonal of a surface: eps
//! both ways, as for the objects' bounds (format-spec/lod.md).

use super::{Grid, Lattice, LodError, Voxels, aligned_grid};
use crate::geom::Aabb;
use crate::scene::Mesh;

/// Cells of a group bound's grid grow by this factor from level k to k + 1.
pub const LEVEL_FACTOR: u64 = 4;

/// The highest lattice level a grid may use (a cell of 2^60 lattice cells).
const MAX_LATTICE_LEVEL: u8 = 60;

/// How group bounds are gridded in one file: the lattice, each level's
/// floor and cell budget.
#[derive(Debug, Clone, PartialEq)]
pub struct GroupRule {
    /// The global voxel lattice.
    pub lattice: Lattice,
    /// M.
    pub levels: u8,
    /// Index k - 1: the finest lattice level of level k's group grids.
    pub floor: Vec<u8>,
    /// Cells of a level-2 group grid at most (the meta block's `cuberille_bits`).
    pub cuberille_bits: u32,
}

impl GroupRule {
    /// The levels that hold group bounds: 2 ..= M - 1, and at most
    /// `store::format::node::MAX_GROUP_LEVEL` (8, what a record's flags name).
    pub fn group_levels(&self) -> std::ops::RangeInclusive<u8> {
        2..=self.levels.saturating_sub(1).min(8)
    }

    /// The most cells a group grid of level k has.
    pub fn budget(&self, k: u8) -> u64 {
        u64::from(self.cuberille_bits.max(1))
            .saturating_mul(LEVEL_FACTOR.saturating_pow(u32::from(k.saturating_sub(2))))
    }

    /// The grid of b(S_n,k) for a node whose record holds the box `frame`:
    /// whole lattice cells over it, at the finest lattice level from the
    /// level's floor with at most [`budget`](Self::budget) cells.
    pub fn grid(&self, k: u8, frame: &Aabb) -> Result<Grid, LodError> {
        let floor = self.floor.get(usize::from(k).wrapping_sub(1)).copied().unwrap_or(0);
        let budget = self.budget(k);
        // Start near the level the budget asks for, then walk to the finest that keeps it.
        let e = frame.extent();
        let side = self.lattice.cell_at(floor);
        let cells_at_floor = (0..3).map(|a| (e[a] / side).max(1.0)).product::<f64>();
        let guess = ((cells_at_floor / budget as f64).max(1.0).log2() / 3.0).floor();
        let mut level = floor.saturating_add(if guess.is_finite() { guess.min(60.0) as u8 } else { 0 });
        level = level.saturating_sub(1).max(floor);
        while level <= MAX_LATTICE_LEVEL {
            match aligned_grid(&self.lattice, level, frame) {
                Ok(g) if g.cells() <= budget => return Ok(g),
                Ok(_) | Err(LodError::TooLarge { .. }) => level += 1,
                Err(e) => return Err(e),
            }
        }
        Err(LodError::TooLarge { level, dims: [0; 3], cells: budget.saturating_add(1) })
    }

    /// The same rule with twice the cells per level: a grid as fine or one
    /// lattice level finer, never coarser, so bounds built under it lift
    /// into this rule's grids.
    pub fn finer(&self) -> GroupRule {
        GroupRule { cuberille_bits: self.cuberille_bits.max(1).saturating_mul(2), ..self.clone() }
    }

    /// The guaranteed error of b(S_n,k) over `frame`, mm: its grid's largest
    /// cell diagonal (grown by the voxelization tolerance).
    pub fn eps(&self, k: u8, frame: &Aabb) -> Option<f64> {
        self.grid(k, frame).ok().map(|g| g.max_cell_diagonal())
    }
}

/// b(S_n,k) of a leaf: the cells of `grid` its objects' surfaces touch.
pub fn leaf_group<'a>(grid: Grid, meshes: impl IntoIterator<Item = &'a Mesh>) -> Voxels {
    Voxels::of_surfaces(grid, meshes)
}

/// b(S_n,k) of an internal node: its children's bounds lifted into `grid`.
/// Refuses children on another lattice, coarser than the grid or outside it.
pub fn lift_group<'a>(
    grid: Grid,
    children: impl IntoIterator<Item = &'a Voxels>,
) -> Result<Voxels, LodError> {
    let mut v = Voxels::empty(grid);
    for c in children {
        c.lift_into(&mut v)?;
    }
    Ok(v)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::Point;
    use proptest::prelude::*;

    fn rule() -> GroupRule {
        GroupRule {
            lattice: Lattice { origin: Point::origin(), cell: 1.0 },
            levels: 4,
            floor: vec![0, 0, 0, 0],
            cuberille_bits: 64,
        }
    }

    fn tri_mesh(p: [[f64; 3]; 3]) -> Mesh {
        let v: Vec<Point> = p.iter().map(|c| Point::new(c[0], c[1], c[2])).collect();
        Mesh::from_world(&v, vec![[0, 1, 2]]).unwrap()
    }

    #[test]
    fn grids_keep_their_budget_and_are_the_finest_that_do() {
        let r = rule();
        let b = Aabb::from_array([0.3, 0.0, 0.0, 37.0, 20.0, 9.0]);
        for k in 2..=3 {
            let g = r.grid(k, &b).unwrap();
            assert!(g.cells() <= r.budget(k));
            assert!(g.bounds().contains(&b));
            if g.level() > 0 {
                let finer = aligned_grid(&r.lattice, g.level() - 1, &b).unwrap();
                assert!(finer.cells() > r.budget(k), "level {k}: a finer grid keeps the budget");
            }
        }
        assert!(r.eps(3, &b).unwrap() < r.eps(2, &b).unwrap());
        // A small box sits at the floor.
        assert_eq!(r.grid(2, &Aabb::from_array([0.0, 0.0, 0.0, 1.5, 1.0, 1.0])).unwrap().level(), 0);
    }

    proptest! {
        /// The finer rule's grid over any box is the same lattice level or
        /// one finer, so its bounds lift into the rule's own grid.
        #[test]
        fn a_finer_rules_grids_lift_into_the_rules_own(
            lo in prop::array::uniform3(-50.0f64..50.0),
            size in prop::array::uniform3(0.01f64..300.0),
            k in 2u8..=3,
        ) {
            let r = rule();
            let b = Aabb::from_array([lo[0], lo[1], lo[2], lo[0] + size[0], lo[1] + size[1], lo[2] + size[2]]);
            let (g, f) = (r.grid(k, &b).unwrap(), r.finer().grid(k, &b).unwrap());
            prop_assert!(f.level() <= g.level() && g.level() <= f.level() + 1, "{} then {}", f.level(), g.level());
            let d = f.dims();
            let mut corners = Voxels::empty(f.clone());
            corners.set_cell([0, 0, 0]);
            corners.set_cell([d[0] - 1, d[1] - 1, d[2] - 1]);
            let lifted = lift_group(g.clone(), [&corners]);
            prop_assert!(lifted.is_ok_and(|v| !v.is_empty() && v.count() <= 2));
        }

        /// A parent's lifted bound holds every child cell's surface, and each
        /// of its cells holds a child cell: within its cell diagonal both ways.
        #[test]
        fn lifted_bounds_contain_their_children_and_stay_within_eps(
            tris in prop::collection::vec(prop::array::uniform3(prop::array::uniform3(0.0f64..40.0)), 2..8),
            cut in 1usize..7,
        ) {
            let r = rule();
            let meshes: Vec<Mesh> = tris.iter().map(|t| tri_mesh(*t)).collect();
            let cut = cut.min(meshes.len() - 1);
            let (a, b) = meshes.split_at(cut);
            let boxes = |ms: &[Mesh]| ms.iter().fold(Aabb::EMPTY, |s, m| s.union(&m.aabb()));
            let (ba, bb) = (boxes(a), boxes(b));
            let parent_box = ba.union(&bb);
            for k in 2..=3u8 {
                let ca = leaf_group(r.grid(k, &ba).unwrap(), a);
                let cb = leaf_group(r.grid(k, &bb).unwrap(), b);
                let p = lift_group(r.grid(k, &parent_box).unwrap(), [&ca, &cb]).unwrap();
                let eps = p.grid().max_cell_diagonal();
                for m in &meshes {
                    for t in m.triangle_points() {
                        prop_assert!(p.intersects_triangle(&t), "a triangle leaves the bound");
                        for v in t {
                            prop_assert!(p.contains_point(&v));
                        }
                    }
                }
                // Every cell of the parent is within eps of some triangle.
                for cell in p.cell_boxes() {
                    let near = meshes.iter().any(|m| m.triangle_points().any(|t| {
                        crate::geom::intersects_triangle_box(&t, &cell)
                    }));
                    prop_assert!(near, "a cell holds no surface");
                    prop_assert!(cell.extent().norm() <= eps);
                }
            }
        }
    }
}
