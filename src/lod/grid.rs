//! A voxel grid over a box at one lattice level: cells are lattice cells
//! clipped to the box, so edge cells may be smaller (or flat when the box is).

use super::{Lattice, LodError};
use crate::geom::Aabb;

/// The most cells a grid may have (2 MiB of bitmap): what we build or decode.
pub const MAX_CELLS: u64 = 1 << 24;
/// The most cells along one axis, so cell coordinates fit a u16 box corner.
pub const MAX_DIM: u32 = 65535;

/// A grid over `bounds` at lattice level `level`. Along each axis its planes
/// are `bounds.min`, every lattice plane strictly inside, and `bounds.max`.
/// Because lattice planes of level j + 1 are planes of level j, a grid at
/// level j over R' ⊆ R nests into the grid at any level >= j over R.
#[derive(Debug, Clone, PartialEq)]
pub struct Grid {
    lattice: Lattice,
    level: u8,
    /// `lattice.cell_at(level)`, kept: planes are read per triangle.
    side: f64,
    bounds: Aabb,
    /// Lattice index of the first plane strictly inside the bounds, per axis.
    first: [i64; 3],
    dims: [u32; 3],
}

impl Grid {
    /// The grid over `bounds` at `level`. Refuses empty or non-finite bounds,
    /// an invalid lattice, and grids larger than [`MAX_CELLS`] or [`MAX_DIM`].
    pub fn new(lattice: &Lattice, level: u8, bounds: &Aabb) -> Result<Grid, LodError> {
        if !lattice.is_valid() || !lattice.cell_at(level).is_finite() {
            return Err(LodError::BadLattice { origin: lattice.origin.into(), cell: lattice.cell });
        }
        let arr = bounds.to_array();
        if !arr.iter().all(|c| c.is_finite()) || bounds.is_empty() {
            return Err(LodError::BadBounds(arr));
        }
        let s = lattice.cell_at(level);
        let too_large = |dims: [u32; 3]| LodError::TooLarge {
            level,
            dims,
            cells: dims.iter().map(|&d| u64::from(d)).fold(1u64, u64::saturating_mul),
        };
        let mut first = [0i64; 3];
        let mut dims = [1u32; 3];
        let mut estimate = [1u32; 3];
        for a in 0..3 {
            let (lo, hi) = (bounds.min[a], bounds.max[a]);
            let span = (hi - lo) / s;
            let far = ((lo - lattice.origin[a]) / s).abs().max(((hi - lattice.origin[a]) / s).abs());
            // Beyond 2^50 plane indices stop being exact; beyond MAX_DIM the grid is refused anyway.
            if span > f64::from(MAX_DIM) + 2.0 || far >= (1u64 << 50) as f64 {
                estimate[a] = u32::MAX;
                continue;
            }
            // The estimate is off by a plane or two at most; where planes do
            // not advance with n (a cell below the coordinates' resolution,
            // e.g. a far origin) the walks would never end: they are bounded.
            let stalled = || LodError::BadLattice { origin: lattice.origin.into(), cell: lattice.cell };
            let mut n = ((lo - lattice.origin[a]) / s).floor() as i64 + 1;
            let mut steps = 0;
            while lattice.plane(level, a, n - 1) > lo {
                n -= 1;
                steps += 1;
                if steps > 4 {
                    return Err(stalled());
                }
            }
            while lattice.plane(level, a, n) <= lo {
                n += 1;
                steps += 1;
                if steps > 8 {
                    return Err(stalled());
                }
            }
            let mut m = n - 1;
            while lattice.plane(level, a, m + 1) < hi {
                m += 1;
                if m - n > i64::from(MAX_DIM) + 2 {
                    return Err(stalled());
                }
            }
            first[a] = n;
            let d = (m - n + 2).max(1);
            estimate[a] = u32::try_from(d).unwrap_or(u32::MAX);
            dims[a] = estimate[a];
        }
        if estimate.iter().any(|&d| d > MAX_DIM) {
            return Err(too_large(estimate));
        }
        let grid = Grid { lattice: *lattice, level, side: s, bounds: *bounds, first, dims };
        if grid.cells() > MAX_CELLS {
            return Err(too_large(dims));
        }
        Ok(grid)
    }

    /// The finest level >= `min_level` whose grid over `bounds` has at most
    /// `max_cells` cells (and fits [`MAX_CELLS`]).
    pub fn coarsest_within(
        lattice: &Lattice,
        bounds: &Aabb,
        max_cells: u64,
        min_level: u8,
    ) -> Result<Grid, LodError> {
        for level in min_level..=u8::MAX {
            match Grid::new(lattice, level, bounds) {
                Ok(g) if g.cells() <= max_cells => return Ok(g),
                Ok(_) | Err(LodError::TooLarge { .. }) => {}
                Err(e) => return Err(e),
            }
        }
        Err(LodError::TooLarge { level: u8::MAX, dims: [0; 3], cells: max_cells.saturating_add(1) })
    }

    /// The lattice the grid sits on.
    pub fn lattice(&self) -> &Lattice {
        &self.lattice
    }

    /// The lattice level j: interior cells have side `lattice.cell_at(j)`.
    pub fn level(&self) -> u8 {
        self.level
    }

    /// The box the grid covers.
    pub fn bounds(&self) -> &Aabb {
        &self.bounds
    }

    /// Cells along x, y and z.
    pub fn dims(&self) -> [u32; 3] {
        self.dims
    }

    /// Total number of cells.
    pub fn cells(&self) -> u64 {
        self.dims.iter().map(|&d| u64::from(d)).product()
    }

    /// Plane `k` (0..=dims) along `axis`.
    pub(crate) fn plane(&self, axis: usize, k: u32) -> f64 {
        if k == 0 {
            self.bounds.min[axis]
        } else if k >= self.dims[axis] {
            self.bounds.max[axis]
        } else {
            self.lattice.plane_at_side(self.side, axis, self.first[axis] + i64::from(k) - 1)
        }
    }

    /// All dims + 1 planes along `axis`, for loops that read many cell boxes.
    pub(crate) fn planes(&self, axis: usize) -> Vec<f64> {
        (0..=self.dims[axis]).map(|k| self.plane(axis, k)).collect()
    }

    /// The closed box of cell `c`.
    pub fn cell_box(&self, c: [u32; 3]) -> Aabb {
        Aabb::from_array([
            self.plane(0, c[0]),
            self.plane(1, c[1]),
            self.plane(2, c[2]),
            self.plane(0, c[0] + 1),
            self.plane(1, c[1] + 1),
            self.plane(2, c[2] + 1),
        ])
    }

    /// The linear index of cell `c` (x fastest, then y, then z).
    pub(crate) fn index(&self, c: [u32; 3]) -> usize {
        let [dx, dy, _] = self.dims.map(|d| d as usize);
        c[0] as usize + dx * (c[1] as usize + dy * c[2] as usize)
    }

    /// The cell coordinates of a linear index.
    pub(crate) fn coords(&self, i: usize) -> [u32; 3] {
        let [dx, dy, _] = self.dims.map(|d| d as usize);
        [(i % dx) as u32, ((i / dx) % dy) as u32, (i / (dx * dy)) as u32]
    }

    /// The cell k along `axis` with plane(k) <= x < plane(k + 1), clamped to the grid.
    pub(crate) fn cell_of(&self, axis: usize, x: f64) -> u32 {
        let d = self.dims[axis];
        // Only a first guess: the loops below settle the cell from any
        // start, so the guess truncates (floor is a library call on
        // baseline x86-64, and this runs per triangle corner) and saturates
        // at far coordinates; NaN stays at cell 0.
        let est = if x.is_nan() {
            0
        } else {
            (((x - self.lattice.origin[axis]) / self.side) as i64)
                .saturating_sub(self.first[axis])
                .saturating_add(1)
                .clamp(0, i64::from(d) - 1)
        };
        let mut k = est as u32;
        while k > 0 && self.plane(axis, k) > x {
            k -= 1;
        }
        while k + 1 < d && self.plane(axis, k + 1) <= x {
            k += 1;
        }
        k
    }

    /// The cells along `axis` whose closed extent meets [lo, hi], if any.
    pub(crate) fn range(&self, axis: usize, lo: f64, hi: f64) -> Option<(u32, u32)> {
        let extent = (self.bounds.min[axis], self.bounds.max[axis]);
        closed_range(extent, lo, hi, |x| self.cell_of(axis, x), |k| self.plane(axis, k))
    }

    /// The cells whose closed boxes meet `b`, per axis.
    pub(crate) fn box_range(&self, b: &Aabb) -> Option<[(u32, u32); 3]> {
        Some([
            self.range(0, b.min.x, b.max.x)?,
            self.range(1, b.min.y, b.max.y)?,
            self.range(2, b.min.z, b.max.z)?,
        ])
    }

    /// How far cells are grown before testing against geometry, so rounding in
    /// the tests never loses a touching triangle: 1e-9 of the coordinates' magnitude.
    pub fn tolerance(&self) -> f64 {
        let a = self.bounds.to_array();
        let mag = a.iter().fold(0.0f64, |m, c| m.max(c.abs()));
        let ext = self.bounds.extent().max();
        (1e-9 * (mag + ext)).max(f64::MIN_POSITIVE)
    }

    /// The guaranteed error of a voxel set built on this grid: the diagonal
    /// of its largest cell, grown by the voxelization tolerance on every side.
    pub fn max_cell_diagonal(&self) -> f64 {
        let t = self.tolerance();
        let w: Vec<f64> = (0..3)
            .map(|a| {
                let p = self.planes(a);
                p.windows(2).fold(0.0f64, |m, w| m.max(w[1] - w[0])) + 2.0 * t
            })
            .collect();
        // Rounded up by a relative 1e-12 so the bound holds on the f64 result too.
        (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]).sqrt() * (1.0 + 1e-12)
    }
}

/// [`Grid::box_range`] on a grid's planes read once (`Grid::planes` per
/// axis): a binary search per bound instead of lattice planes computed on a
/// walk, for loops that locate many boxes (a voxelizer's triangles).
pub(crate) fn box_range_on(planes: &[Vec<f64>; 3], b: &Aabb) -> Option<[(u32, u32); 3]> {
    Some([
        range_on(&planes[0], b.min.x, b.max.x)?,
        range_on(&planes[1], b.min.y, b.max.y)?,
        range_on(&planes[2], b.min.z, b.max.z)?,
    ])
}

/// [`Grid::range`] on one axis's planes.
fn range_on(planes: &[f64], lo: f64, hi: f64) -> Option<(u32, u32)> {
    let extent = (*planes.first()?, *planes.last()?);
    // Planes rise strictly (a flat axis has one cell), so the cell holding x
    // is one less than the number of planes at or below it, clamped.
    let last = planes.len().saturating_sub(2);
    let cell_of = |x: f64| planes.partition_point(|&p| p <= x).saturating_sub(1).min(last) as u32;
    closed_range(extent, lo, hi, cell_of, |k| planes[k as usize])
}

/// The cells along one axis whose closed extent meets [lo, hi], if any, on
/// an axis spanning `extent`, given the cell holding a coordinate and the
/// planes: a cell ending on lo meets it too.
fn closed_range(
    extent: (f64, f64),
    lo: f64,
    hi: f64,
    cell_of: impl Fn(f64) -> u32,
    plane: impl Fn(u32) -> f64,
) -> Option<(u32, u32)> {
    if lo.is_nan() || hi.is_nan() || lo > hi || hi < extent.0 || lo > extent.1 {
        return None;
    }
    let mut a = cell_of(lo);
    if a > 0 && plane(a) == lo {
        a -= 1;
    }
    Some((a, cell_of(hi)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::Point;

    fn lat() -> Lattice {
        Lattice { origin: Point::origin(), cell: 1.0 }
    }

    #[test]
    fn edge_cells_are_clipped_to_the_bounds() {
        let g = Grid::new(&lat(), 1, &Aabb::from_array([0.5, 0.0, 0.0, 4.5, 2.0, 0.0])).unwrap();
        // x planes: 0.5, 2, 4, 4.5; y: 0, 2; z flat.
        assert_eq!(g.dims(), [3, 1, 1]);
        assert_eq!(g.planes(0), vec![0.5, 2.0, 4.0, 4.5]);
        assert_eq!(g.cell_box([1, 0, 0]), Aabb::from_array([2.0, 0.0, 0.0, 4.0, 2.0, 0.0]));
        assert_eq!(g.cell_of(0, 2.0), 1);
        assert_eq!(g.range(0, 2.0, 2.0), Some((0, 1)));
        assert_eq!(g.range(0, 5.0, 6.0), None);
    }

    #[test]
    fn too_large_grids_are_refused_and_coarsest_within_finds_a_level() {
        let b = Aabb::from_array([0.0, 0.0, 0.0, 1000.0, 1000.0, 1000.0]);
        assert!(matches!(Grid::new(&lat(), 0, &b), Err(LodError::TooLarge { .. })));
        let g = Grid::coarsest_within(&lat(), &b, 4096, 0).unwrap();
        assert!(g.cells() <= 4096);
        let finer = Grid::new(&lat(), g.level() - 1, &b).unwrap();
        assert!(finer.cells() > 4096);
        assert!(Grid::coarsest_within(&lat(), &b, 0, 0).is_err());
    }

    proptest::proptest! {
        /// The cell of a coordinate is the one whose planes hold it (clamped
        /// to the grid), wherever the guess starts: below the lattice's
        /// origin, far outside the bounds, at infinities and NaN.
        #[test]
        fn the_cell_of_a_coordinate_is_the_one_its_planes_hold(
            origin in -50.0f64..50.0,
            cell in 0.5f64..4.0,
            level in 0u8..3,
            lo in -100.0f64..100.0,
            size in 0.5f64..60.0,
            x in proptest::prop_oneof![
                -300.0f64..300.0,
                proptest::prelude::Just(f64::INFINITY),
                proptest::prelude::Just(f64::NEG_INFINITY),
                proptest::prelude::Just(f64::NAN),
                proptest::prelude::Just(1e300),
                proptest::prelude::Just(-1e300),
            ],
        ) {
            let l = Lattice { origin: Point::new(origin, origin, origin), cell };
            let g = Grid::new(&l, level, &Aabb::from_array([lo, lo, lo, lo + size, lo + size, lo + size]));
            // Grids past MAX_CELLS are refused (tested above).
            let Ok(g) = g else { return Ok(()) };
            let d = g.dims()[0];
            let want = (0..d).rev().find(|&k| g.plane(0, k) <= x).unwrap_or(0);
            proptest::prop_assert_eq!(g.cell_of(0, x), want);
        }
    }

    #[test]
    fn bad_bounds_and_lattices_are_refused() {
        assert!(matches!(Grid::new(&lat(), 0, &Aabb::EMPTY), Err(LodError::BadBounds(_))));
        let l = Lattice { origin: Point::origin(), cell: 0.0 };
        let b = Aabb::from_array([0.0; 6]);
        assert!(matches!(Grid::new(&l, 0, &b), Err(LodError::BadLattice { .. })));
    }

    proptest::proptest! {
        /// The binary search on planes read once answers as the grid does,
        /// for boxes inside, across and outside clipped grids.
        #[test]
        fn box_range_on_planes_is_the_grids_box_range(
            lo in proptest::array::uniform3(-8.0f64..8.0),
            size in proptest::array::uniform3(0.0f64..12.0),
            level in 0u8..3,
            q in proptest::array::uniform3(-12.0f64..12.0),
            q_size in proptest::array::uniform3(0.0f64..6.0),
            on_plane in proptest::bool::ANY,
        ) {
            let b = Aabb::from_array([lo[0], lo[1], lo[2], lo[0] + size[0], lo[1] + size[1], lo[2] + size[2]]);
            let g = Grid::new(&lat(), level, &b).unwrap();
            let planes: [Vec<f64>; 3] = std::array::from_fn(|a| g.planes(a));
            // Corners on lattice planes, where the closed-extent rule matters.
            let q = if on_plane { q.map(f64::round) } else { q };
            let qb = Aabb::from_array([q[0], q[1], q[2], q[0] + q_size[0], q[1] + q_size[1], q[2] + q_size[2]]);
            proptest::prop_assert_eq!(box_range_on(&planes, &qb), g.box_range(&qb));
        }
    }
}
