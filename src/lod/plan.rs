//! The levels of detail of a file: M levels, 1 the box, 2 the cuberille (a
//! grid within a cell budget), 3 .. M-1 polyhedra (voxel sets at a fixed
//! lattice level each), M the exact objects; the lattice every grid sits on,
//! so levels nest (see `lattice.rs`), and the parameters that shape them.

use super::{Lattice, LodError};
use crate::geom::Aabb;

/// How a tree's levels of detail are built.
#[derive(Debug, Clone, PartialEq)]
pub struct LodParams {
    /// eps_k of the polyhedral levels k = 3 .. M-1, in mm, coarse to fine
    /// (non-increasing); `None` takes them from the scene's object sizes.
    pub eps: Option<Vec<f64>>,
    /// Cells of a node's cuberille (level 2).
    pub cuberille_bits: u32,
    /// Cells of an object's cuberille.
    pub cuberille_object_bits: u32,
    /// Cells sampled per bound to measure its error.
    pub error_samples: usize,
    /// Query positions sampled per candidate bound to judge whether it pays.
    pub model_samples: usize,
    /// Store every object's bound at every level 2 .. M-1, paying or not
    /// (to measure what each level could give, and in tests).
    pub store_all: bool,
    /// Store the nodes' group bounds b(S_n,k) in group blocks
    /// (format-spec/group.md), as many as each node block's group block holds.
    pub group_bounds: bool,
}

impl Default for LodParams {
    fn default() -> LodParams {
        LodParams {
            eps: None,
            cuberille_bits: 4096,
            cuberille_object_bits: 4096,
            error_samples: 64,
            model_samples: 64,
            store_all: false,
            group_bounds: true,
        }
    }
}

/// The lattice and the lattice level of each level's grids.
#[derive(Debug, Clone, PartialEq)]
pub struct LodPlan {
    /// M.
    pub levels: u8,
    /// The global voxel lattice.
    pub lattice: Lattice,
    /// Index k - 1: the lattice level of level k's grids (level 2: the
    /// finest its per-node grids may use); 0 for levels 1 and M.
    pub grid_level: Vec<u8>,
}

/// The median of `f` over the objects' box sides (sorted ascending), and
/// `None` for a scene of points.
fn median_side(boxes: &[Aabb], f: impl Fn(&[f64; 3]) -> f64) -> Option<f64> {
    let mut v: Vec<f64> = boxes
        .iter()
        .map(|b| {
            let e = b.extent();
            let mut s = [e.x, e.y, e.z];
            s.sort_by(f64::total_cmp);
            f(&s)
        })
        .filter(|s| *s > 0.0)
        .collect();
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied()
}

impl LodPlan {
    /// The plan for a scene of objects with boxes `boxes` and M = `levels`.
    pub fn new(boxes: &[Aabb], levels: u8, params: &LodParams) -> Result<LodPlan, LodError> {
        let polyhedral = usize::from(levels.saturating_sub(3));
        let scene_box = boxes.iter().fold(Aabb::EMPTY, |s, b| s.union(b));
        let (cell, steps) = match &params.eps {
            Some(eps) => {
                if eps.len() != polyhedral {
                    return Err(LodError::Params(format!(
                        "{} eps values for {polyhedral} polyhedral levels (3 .. M-1 with M = {levels})",
                        eps.len()
                    )));
                }
                if eps.iter().any(|e| !(e.is_finite() && *e > 0.0)) || eps.windows(2).any(|w| w[1] > w[0]) {
                    return Err(LodError::Params(format!(
                        "eps {eps:?} must be positive and not increase with k"
                    )));
                }
                let finest = eps.last().copied().unwrap_or(1.0);
                // A level's error is its cell diagonal: round each cell down to a power-of-two multiple.
                let steps: Vec<u8> =
                    eps.iter().map(|e| (e / finest).log2().floor().clamp(0.0, 60.0) as u8).collect();
                (finest / 3f64.sqrt(), steps)
            }
            None => {
                // The finest eps: the geometric mean of the median object's
                // shortest and longest sides, fine enough to carve the inside
                // out of long thin parts (walls, plates), coarse enough to stay
                // a few cells across small ones. Measured best within 2x on the
                // house (eps 300 to 600 mm) and the engine (15 to 37 mm).
                let short = median_side(boxes, |s| s[0]);
                let long = median_side(boxes, |s| s[2]);
                let eps = match (short, long) {
                    (Some(a), Some(b)) => (a * b).sqrt(),
                    (None, Some(b)) => b,
                    _ => longest_side_of(&scene_box.extent().into()).max(1.0), // points only
                };
                let steps = (0..polyhedral).map(|i| (polyhedral - 1 - i) as u8).collect();
                (eps / 3f64.sqrt(), steps)
            }
        };
        let mut grid_level = vec![0u8; usize::from(levels)];
        for (i, s) in steps.iter().enumerate() {
            grid_level[3 + i - 1] = *s;
        }
        if levels >= 3 {
            grid_level[1] = if polyhedral > 0 { grid_level[2] } else { 0 };
        }
        Ok(LodPlan { levels, lattice: Lattice { origin: scene_box.min, cell }, grid_level })
    }

    /// Level k's guaranteed error for a grid at its lattice level (k >= 3).
    #[cfg(feature = "internals")]
    pub fn eps(&self, k: u8) -> f64 {
        self.lattice.cell_at(self.grid_level[usize::from(k) - 1]) * 3f64.sqrt()
    }
}

fn longest_side_of(e: &[f64; 3]) -> f64 {
    e[0].max(e[1]).max(e[2])
}
