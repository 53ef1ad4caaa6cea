//! The global lattice every level-of-detail grid sits on, so that levels nest.

use crate::geom::Point;

/// The global voxel lattice: lattice level j has cells of side `cell * 2^j`
/// whose planes pass through `origin`. Plane n of level j is computed as
/// `origin + n * cell_at(j)`; since scaling by a power of two commutes with
/// rounding, plane 2n of level j and plane n of level j + 1 are the same f64.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lattice {
    /// A point every lattice plane of every level passes through (mm).
    pub origin: Point,
    /// The cell side at lattice level 0 (mm).
    pub cell: f64,
}

impl Lattice {
    /// The cell side at `level`: `cell * 2^level` (exact).
    pub fn cell_at(&self, level: u8) -> f64 {
        self.cell * 2f64.powi(i32::from(level))
    }

    /// The coordinate of plane `n` of `level` along `axis`.
    pub(crate) fn plane(&self, level: u8, axis: usize, n: i64) -> f64 {
        self.plane_at_side(self.cell_at(level), axis, n)
    }

    /// [`Lattice::plane`] of the level whose cell side is `side`, for
    /// callers that keep the side (a grid reads planes per triangle).
    pub(crate) fn plane_at_side(&self, side: f64, axis: usize, n: i64) -> f64 {
        // n stays below 2^53 (grids are at most 65535 cells wide), so n as f64 is exact.
        self.origin[axis] + n as f64 * side
    }

    pub(crate) fn is_valid(&self) -> bool {
        self.origin.iter().all(|c| c.is_finite()) && self.cell.is_finite() && self.cell > 0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn even_planes_of_a_level_are_the_planes_of_the_next(
            o in -1.0e6f64..1.0e6, cell in 1.0e-3f64..1.0e3, n in -100_000i64..100_000, level in 0u8..20,
        ) {
            let l = Lattice { origin: Point::new(o, o, o), cell };
            prop_assert_eq!(l.plane(level, 0, 2 * n), l.plane(level + 1, 0, n));
        }
    }
}
