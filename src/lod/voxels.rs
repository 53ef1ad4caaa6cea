//! A voxel set on a [`Grid`]: a dense bitmap, one bit per cell, and the
//! operations every level needs (lift into a coarser grid, point, box and
//! triangle tests).

use super::{Grid, LodError};
use crate::geom::{Aabb, Point, intersects_triangle_box};

/// A set of cells of a grid, as a dense bitmap (bit i of word i / 64 is cell
/// i, x fastest, then y, then z). Bits past the last cell are always zero.
#[derive(Debug, Clone, PartialEq)]
pub struct Voxels {
    pub(crate) grid: Grid,
    pub(crate) bits: Vec<u64>,
}

impl Voxels {
    /// No cell set.
    pub fn empty(grid: Grid) -> Voxels {
        let words = (grid.cells() as usize).div_ceil(64);
        Voxels { grid, bits: vec![0; words] }
    }

    /// The grid the set lives on.
    pub fn grid(&self) -> &Grid {
        &self.grid
    }

    /// Number of set cells.
    pub fn count(&self) -> u64 {
        self.bits.iter().map(|w| u64::from(w.count_ones())).sum()
    }

    /// True when no cell is set.
    pub fn is_empty(&self) -> bool {
        self.bits.iter().all(|&w| w == 0)
    }

    /// True when cell `c` is set. Panics when `c` is outside the grid.
    pub fn is_set(&self, c: [u32; 3]) -> bool {
        self.get(self.checked_index(c))
    }

    /// Sets cell `c`. Panics when `c` is outside the grid.
    pub fn set_cell(&mut self, c: [u32; 3]) {
        let i = self.checked_index(c);
        self.set(i);
    }

    fn checked_index(&self, c: [u32; 3]) -> usize {
        let d = self.grid.dims();
        assert!((0..3).all(|a| c[a] < d[a]), "cell {c:?} outside a grid of {d:?}");
        self.grid.index(c)
    }

    pub(crate) fn get(&self, i: usize) -> bool {
        self.bits[i / 64] >> (i % 64) & 1 == 1
    }

    pub(crate) fn set(&mut self, i: usize) {
        self.bits[i / 64] |= 1 << (i % 64);
    }

    /// Linear indices of the set cells, in increasing order.
    pub(crate) fn set_cells(&self) -> impl Iterator<Item = usize> + '_ {
        SetCells::new(&self.bits, 0..self.bits.len() * 64)
    }

    /// A test set on `grid`: the cells `seeds` pick (modulo the cells),
    /// and, from each of `corners` (modulo the dims) to the grid's far
    /// corner, every cell: scattered cells and solid parts.
    #[cfg(test)]
    pub(crate) fn scattered_and_solid(grid: Grid, seeds: &[u64], corners: &[[u32; 3]]) -> Voxels {
        let mut v = Voxels::empty(grid);
        let (cells, d) = (v.grid.cells(), v.grid.dims());
        for s in seeds {
            v.set((s % cells) as usize);
        }
        for c in corners {
            for z in c[2] % d[2]..d[2] {
                for y in c[1] % d[1]..d[1] {
                    for x in c[0] % d[0]..d[0] {
                        v.set_cell([x, y, z]);
                    }
                }
            }
        }
        v
    }

    /// ORs every set cell into the cell of `target`'s grid that contains it.
    /// Refuses (NotNested) a target on another lattice, at a finer level, or
    /// whose bounds do not contain this set's bounds.
    pub fn lift_into(&self, target: &mut Voxels) -> Result<(), LodError> {
        let (from, to) = (&self.grid, &target.grid);
        let not_nested = || LodError::NotNested {
            from_level: from.level(),
            from: from.bounds().to_array(),
            to_level: to.level(),
            to: to.bounds().to_array(),
        };
        if from.lattice() != to.lattice() || to.level() < from.level() || !to.bounds().contains(from.bounds())
        {
            return Err(not_nested());
        }
        // Per axis, the target cell of each source cell; checked to contain it.
        // Source cells start ever further on, so the target cell is found by
        // walking on from the last one: `to.cell_of`'s cell (the last whose
        // plane is at or below the start, clamped) without a search per cell
        // (this map was most of a sparse set's lift).
        let mut map: [Vec<u32>; 3] = Default::default();
        for (a, m) in map.iter_mut().enumerate() {
            let p = from.planes(a);
            let last = to.dims()[a].saturating_sub(1);
            let mut t = 0;
            for k in 0..from.dims()[a] as usize {
                while t < last && to.plane(a, t + 1) <= p[k] {
                    t += 1;
                }
                if !(to.plane(a, t) <= p[k] && p[k + 1] <= to.plane(a, t + 1)) {
                    return Err(not_nested());
                }
                m.push(t);
            }
        }
        // One pass over the set cells (x fastest): a row's target row is
        // found when its first set cell comes, so empty rows cost nothing
        // and a cell no division.
        let [dx, dy, _] = from.dims().map(|d| d as usize);
        let to_grid = to.clone();
        let (mut row, mut row_end, mut base) = (0, 0, 0);
        for i in self.set_cells() {
            if i >= row_end {
                let r = i / dx;
                (row, row_end) = (r * dx, r * dx + dx);
                base = to_grid.index([0, map[1][r % dy], map[2][r / dy]]);
            }
            target.set(base + map[0][i - row] as usize);
        }
        Ok(())
    }

    /// True when every cell of this set, lifted into `other`'s grid, is set there.
    pub fn is_subset_of(&self, other: &Voxels) -> Result<bool, LodError> {
        let mut lifted = Voxels::empty(other.grid.clone());
        self.lift_into(&mut lifted)?;
        Ok(lifted.bits.iter().zip(&other.bits).all(|(a, b)| a & !b == 0))
    }

    /// Visits the cells of a per-axis range until `f` returns true.
    pub(crate) fn any_in(&self, r: [(u32, u32); 3], mut f: impl FnMut(usize, [u32; 3]) -> bool) -> bool {
        for z in r[2].0..=r[2].1 {
            for y in r[1].0..=r[1].1 {
                let row = self.grid.index([0, y, z]);
                for x in r[0].0..=r[0].1 {
                    let i = row + x as usize;
                    if self.get(i) && f(i, [x, y, z]) {
                        return true;
                    }
                }
            }
        }
        false
    }

    /// True when a cell of the range `r` is set: a row at a time, and in a
    /// row a word at a time (the read model and the queries ask this of
    /// every bound a query leaves open).
    fn any_set_in(&self, r: [(u32, u32); 3]) -> bool {
        let len = (r[0].1 - r[0].0) as usize + 1;
        (r[2].0..=r[2].1).any(|z| {
            (r[1].0..=r[1].1).any(|y| {
                let row = self.grid.index([r[0].0, y, z]);
                SetCells::new(&self.bits, row..row + len).next().is_some()
            })
        })
    }

    /// True when `p` lies in a set cell, grown by the voxelization tolerance
    /// (so rounding in a point computed on the geometry never loses it).
    pub fn contains_point(&self, p: &Point) -> bool {
        let b = Aabb::new(*p, *p).grown(self.grid.tolerance());
        self.grid.box_range(&b).is_some_and(|r| self.any_set_in(r))
    }

    /// True when the closed box `b` meets a set (closed) cell.
    pub fn intersects_aabb(&self, b: &Aabb) -> bool {
        self.grid.box_range(b).is_some_and(|r| self.any_set_in(r))
    }

    /// True when `b` may meet the surface the set bounds: it meets a set
    /// cell grown by the voxelization tolerance.
    pub fn may_meet(&self, b: &Aabb) -> bool {
        self.intersects_aabb(&b.grown(self.grid.tolerance()))
    }

    /// True when `q` holds a whole set cell grown by the tolerance: for a
    /// set of surface cells (`of_surfaces`), `q` then meets the surface.
    pub fn holds_a_cell_in(&self, q: &Aabb) -> bool {
        let tol = self.grid.tolerance();
        let Some(mut r) = self.grid.box_range(q) else { return false };
        // A grown cell lies in `q` when it does on each axis, and on an axis
        // the cells that do are a run (planes increase): the cells held
        // are a box range, tested a word at a time instead of cell by cell.
        for (a, (lo, hi)) in r.iter_mut().enumerate() {
            let held = |k: u32| {
                q.min[a] <= self.grid.plane(a, k) - tol && self.grid.plane(a, k + 1) + tol <= q.max[a]
            };
            let Some(first) = (*lo..=*hi).find(|&k| held(k)) else { return false };
            // Both ends found from their own side: a step or two each.
            let last = (first..=*hi).rev().find(|&k| held(k)).unwrap_or(first);
            (*lo, *hi) = (first, last);
        }
        self.any_set_in(r)
    }

    /// Every set cell's box, grown by the voxelization tolerance: each holds
    /// the surface piece that set it.
    pub fn cell_boxes(&self) -> impl Iterator<Item = Aabb> + '_ {
        let tol = self.grid.tolerance();
        self.set_cells().map(move |i| self.grid.cell_box(self.grid.coords(i)).grown(tol))
    }

    /// True when the triangle meets a set cell (grown by the tolerance:
    /// conservative, never a missed contact).
    pub fn intersects_triangle(&self, t: &[Point; 3]) -> bool {
        let tol = self.grid.tolerance();
        let b = Aabb::from_points(t.iter()).grown(tol);
        self.grid.box_range(&b).is_some_and(|r| {
            self.any_in(r, |_, c| intersects_triangle_box(t, &self.grid.cell_box(c).grown(tol)))
        })
    }
}

/// The set bits of a bitmap within a range, in increasing order: a word
/// at a time, each set bit its word's next, so that a sparse row costs a
/// load per word and a set cell a few instructions (this walk is most of
/// lifting a level into the next).
pub(crate) struct SetCells<'a> {
    bits: &'a [u64],
    /// The word being read, and its bits in range not yet returned.
    word: usize,
    rest: u64,
    /// The word past the range's last, and the range's bits of that last word.
    end: usize,
    last_mask: u64,
}

impl<'a> SetCells<'a> {
    fn new(bits: &'a [u64], range: std::ops::Range<usize>) -> SetCells<'a> {
        if range.start >= range.end {
            return SetCells { bits, word: 0, rest: 0, end: 0, last_mask: 0 };
        }
        let (first, end) = (range.start / 64, (range.end - 1) / 64 + 1);
        let last_mask = match range.end % 64 {
            0 => u64::MAX,
            hi => (1u64 << hi) - 1,
        };
        let mut rest = bits[first] & (u64::MAX << (range.start % 64));
        if first + 1 == end {
            rest &= last_mask;
        }
        SetCells { bits, word: first, rest, end, last_mask }
    }
}

impl Iterator for SetCells<'_> {
    type Item = usize;

    fn next(&mut self) -> Option<usize> {
        while self.rest == 0 {
            if self.word + 1 >= self.end {
                return None;
            }
            self.word += 1;
            self.rest = self.bits[self.word];
            if self.word + 1 == self.end {
                self.rest &= self.last_mask;
            }
        }
        let b = self.rest.trailing_zeros() as usize;
        self.rest &= self.rest - 1;
        Some(self.word * 64 + b)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lod::Lattice;

    fn grid(level: u8, b: [f64; 6]) -> Grid {
        Grid::new(&Lattice { origin: Point::origin(), cell: 1.0 }, level, &Aabb::from_array(b)).unwrap()
    }

    #[test]
    fn lifting_maps_each_cell_into_the_coarse_cell_holding_it() {
        let mut fine = Voxels::empty(grid(0, [1.0, 0.0, 0.0, 3.0, 1.0, 1.0]));
        fine.set(1); // cell [2, 3] on x
        let mut coarse = Voxels::empty(grid(1, [0.0, 0.0, 0.0, 4.0, 2.0, 2.0]));
        fine.lift_into(&mut coarse).unwrap();
        assert_eq!(coarse.set_cells().collect::<Vec<_>>(), vec![1]);
        assert!(fine.is_subset_of(&coarse).unwrap());
        assert!(!fine.is_subset_of(&Voxels::empty(coarse.grid.clone())).unwrap());
    }

    #[test]
    fn lifting_into_a_finer_or_smaller_grid_is_refused() {
        let a = Voxels::empty(grid(1, [0.0, 0.0, 0.0, 4.0, 4.0, 4.0]));
        let mut finer = Voxels::empty(grid(0, [0.0, 0.0, 0.0, 4.0, 4.0, 4.0]));
        assert!(matches!(a.lift_into(&mut finer), Err(LodError::NotNested { .. })));
        let mut smaller = Voxels::empty(grid(2, [0.0, 0.0, 0.0, 3.0, 4.0, 4.0]));
        assert!(matches!(a.lift_into(&mut smaller), Err(LodError::NotNested { .. })));
    }

    #[test]
    fn point_box_and_triangle_tests_see_only_set_cells() {
        let mut v = Voxels::empty(grid(0, [0.0, 0.0, 0.0, 2.0, 1.0, 1.0]));
        v.set(0);
        assert!(v.contains_point(&Point::new(0.5, 0.5, 0.5)));
        assert!(v.contains_point(&Point::new(1.0, 0.5, 0.5)), "closed cells");
        assert!(!v.contains_point(&Point::new(1.5, 0.5, 0.5)));
        assert!(v.intersects_aabb(&Aabb::from_array([1.0, 0.0, 0.0, 1.5, 1.0, 1.0])));
        assert!(!v.intersects_aabb(&Aabb::from_array([1.1, 0.0, 0.0, 1.5, 1.0, 1.0])));
        let p = |x, y, z| Point::new(x, y, z);
        assert!(v.intersects_triangle(&[p(0.9, 0.5, 0.5), p(1.9, 0.5, 0.5), p(1.9, 0.6, 0.5)]));
        assert!(!v.intersects_triangle(&[p(1.2, 0.5, 0.5), p(1.9, 0.5, 0.5), p(1.9, 0.6, 0.5)]));
    }

    proptest::proptest! {
        /// Lifting row by row sets exactly the coarse cells holding the
        /// centres of the fine set cells, on grids whose rows straddle words.
        #[test]
        fn lifting_sets_the_coarse_cells_holding_each_fine_cell(
            lo in proptest::array::uniform3(0u8..20),
            size in proptest::array::uniform3(1u8..24),
            level in 1u8..4,
            seeds in proptest::collection::vec(proptest::num::u64::ANY, 1..40),
        ) {
            let b = [lo[0], lo[1], lo[2], lo[0] + size[0], lo[1] + size[1], lo[2] + size[2]].map(f64::from);
            let fine = Voxels::scattered_and_solid(grid(0, b), &seeds, &[]);
            let mut coarse = Voxels::empty(grid(level, [0.0, 0.0, 0.0, 48.0, 48.0, 48.0]));
            fine.lift_into(&mut coarse).unwrap();
            let mut want = Voxels::empty(coarse.grid.clone());
            for i in fine.set_cells() {
                let c = fine.grid.coords(i);
                let centre = |a: usize| 0.5 * (fine.grid.plane(a, c[a]) + fine.grid.plane(a, c[a] + 1));
                want.set_cell([0, 1, 2].map(|a| coarse.grid.cell_of(a, centre(a))));
            }
            proptest::prop_assert_eq!(coarse, want);
        }

        /// The box tests a row and a word at a time answer as testing every
        /// cell of the range would: `intersects_aabb` as any set cell there,
        /// `holds_a_cell_in` as any set cell whose grown box `q` contains.
        #[test]
        fn box_tests_answer_as_cell_by_cell_tests(
            lo in proptest::array::uniform3(0u8..8),
            size in proptest::array::uniform3(1u8..12),
            level in 0u8..2,
            seeds in proptest::collection::vec(proptest::num::u64::ANY, 0..12),
            corners in proptest::collection::vec(proptest::array::uniform3(0u32..24), 0..2),
            q in proptest::array::uniform6(-2.0f64..22.0),
            on_planes in proptest::bool::ANY,
        ) {
            let b = [lo[0], lo[1], lo[2], lo[0] + size[0], lo[1] + size[1], lo[2] + size[2]].map(f64::from);
            let v = Voxels::scattered_and_solid(grid(level, b), &seeds, &corners);
            // Corners on lattice planes, or not: where a grown cell's side
            // meets the query's, the tolerance decides.
            let q = if on_planes { q.map(f64::round) } else { q };
            let q = Aabb::from_array([q[0].min(q[3]), q[1].min(q[4]), q[2].min(q[5]), q[0].max(q[3]), q[1].max(q[4]), q[2].max(q[5])]);
            let tol = v.grid.tolerance();
            let cells = |f: &dyn Fn([u32; 3]) -> bool| v.grid.box_range(&q).is_some_and(|r| v.any_in(r, |_, c| f(c)));
            proptest::prop_assert_eq!(v.intersects_aabb(&q), cells(&|_| true));
            proptest::prop_assert_eq!(v.holds_a_cell_in(&q), cells(&|c| q.contains(&v.grid.cell_box(c).grown(tol))));
        }

        /// The word-at-a-time walk finds exactly the set bits of any range,
        /// whichever words its ends fall in.
        #[test]
        fn set_cells_of_a_range_are_its_set_bits(
            bits in proptest::collection::vec(proptest::num::u64::ANY, 1..5),
            a in 0usize..320,
            b in 0usize..320,
        ) {
            let n = bits.len() * 64;
            let range = a.min(b) % (n + 1)..a.max(b) % (n + 1);
            let got: Vec<usize> = SetCells::new(&bits, range.clone()).collect();
            let want: Vec<usize> = range.filter(|&i| bits[i / 64] >> (i % 64) & 1 == 1).collect();
            proptest::prop_assert_eq!(got, want);
        }
    }

    #[test]
    fn an_empty_range_has_no_set_cells_wherever_it_starts() {
        let mut v = Voxels::empty(grid(0, [0.0, 0.0, 0.0, 20.0, 20.0, 1.0]));
        for i in 0..v.grid.cells() as usize {
            v.set(i);
        }
        for start in [0, 5, 63, 64, 70] {
            assert_eq!(SetCells::new(&v.bits, start..start).count(), 0, "at {start}");
            assert_eq!(SetCells::new(&v.bits, start..start + 1).collect::<Vec<_>>(), [start]);
        }
    }
}
