//! The voxel solid as disjoint boxes (levels k >= 3 store these): a greedy
//! 3D merge, x first, then y, then z, in cell order, so the result is
//! deterministic and a blob decodes back to the same boxes.

use super::Voxels;
use crate::geom::Aabb;

impl Voxels {
    /// Disjoint cell-coordinate boxes `[x0, y0, z0, x1, y1, z1)` that cover
    /// exactly the set cells. Each is grown from its first uncovered cell
    /// along x, then y, then z, as far as every cell it takes is set and free.
    pub fn boxes(&self) -> Vec<[u16; 6]> {
        self.boxes_within(usize::MAX).unwrap_or_default()
    }

    /// [`boxes`](Voxels::boxes) when there are at most `most` of them; `None`
    /// as soon as the cover passes `most`, so a caller that only needs
    /// fewer (a blob choosing boxes over a bitmap) stops early.
    pub(crate) fn boxes_within(&self, most: usize) -> Option<Vec<[u16; 6]>> {
        let g = &self.grid;
        let [dx, dy, dz] = g.dims();
        // The set cells no box covers yet; a box's rows are runs of bits,
        // tested and cleared a word at a time.
        let mut free = self.bits.clone();
        let row_of = |y: u32, z: u32| g.index([0, y, z]);
        let mut out = Vec::new();
        for wi in 0..free.len() {
            // The least free cell, a word at a time: a box grown from one
            // cell may cover later cells of its word.
            loop {
                let w = free[wi];
                if w == 0 {
                    break;
                }
                if out.len() == most {
                    return None;
                }
                let i = wi * 64 + w.trailing_zeros() as usize;
                let [x0, y0, z0] = g.coords(i);
                let x1 = x0 + 1 + ones_from(&free, i + 1, (dx - x0 - 1) as usize) as u32;
                let len = (x1 - x0) as usize;
                let mut y1 = y0 + 1;
                while y1 < dy && all_ones(&free, row_of(y1, z0) + x0 as usize, len) {
                    y1 += 1;
                }
                let mut z1 = z0 + 1;
                while z1 < dz && (y0..y1).all(|y| all_ones(&free, row_of(y, z1) + x0 as usize, len)) {
                    z1 += 1;
                }
                for z in z0..z1 {
                    for y in y0..y1 {
                        clear(&mut free, row_of(y, z) + x0 as usize, len);
                    }
                }
                // Dims are at most MAX_DIM = 65535, so every corner fits a u16.
                out.push([x0, y0, z0, x1, y1, z1].map(|c| c as u16));
            }
        }
        Some(out)
    }

    /// [`boxes`](Voxels::boxes) in world coordinates: closed boxes whose
    /// union is the voxel solid (what queries test against).
    pub fn world_boxes(&self) -> Vec<Aabb> {
        let g = &self.grid;
        self.boxes()
            .iter()
            .map(|b| {
                Aabb::from_array([
                    g.plane(0, b[0].into()),
                    g.plane(1, b[1].into()),
                    g.plane(2, b[2].into()),
                    g.plane(0, b[3].into()),
                    g.plane(1, b[4].into()),
                    g.plane(2, b[5].into()),
                ])
            })
            .collect()
    }

    /// Sets every cell of the cell-coordinate box `b`; false (nothing
    /// changed past the first clash) when a cell is out of range or already set.
    pub(crate) fn fill_box(&mut self, b: [u16; 6]) -> bool {
        let d = self.grid.dims();
        let [x0, y0, z0, x1, y1, z1] = b.map(u32::from);
        if !(x0 < x1 && y0 < y1 && z0 < z1 && x1 <= d[0] && y1 <= d[1] && z1 <= d[2]) {
            return false;
        }
        for z in z0..z1 {
            for y in y0..y1 {
                let row = self.grid.index([0, y, z]);
                for x in x0..x1 {
                    let i = row + x as usize;
                    if self.get(i) {
                        return false;
                    }
                    self.set(i);
                }
            }
        }
        true
    }
}

/// Bits `lo .. hi` of a word (lo < hi <= 64).
fn span(lo: usize, hi: usize) -> u64 {
    (u64::MAX >> (64 - (hi - lo))) << lo
}

/// The words (word index, mask) that bits `start .. start + len` fall in.
fn spans(start: usize, len: usize) -> impl Iterator<Item = (usize, u64)> {
    let end = start + len;
    let mut i = start;
    std::iter::from_fn(move || {
        (i < end).then(|| {
            let w = i / 64;
            let hi = (end - w * 64).min(64);
            let m = span(i % 64, hi);
            i = w * 64 + hi;
            (w, m)
        })
    })
}

/// True when bits `start .. start + len` are all set.
fn all_ones(words: &[u64], start: usize, len: usize) -> bool {
    spans(start, len).all(|(w, m)| words[w] & m == m)
}

/// Clears bits `start .. start + len`.
fn clear(words: &mut [u64], start: usize, len: usize) {
    for (w, m) in spans(start, len) {
        words[w] &= !m;
    }
}

/// How many bits from `start` on are set in a row, at most `most`.
fn ones_from(words: &[u64], start: usize, most: usize) -> usize {
    let mut n = 0;
    while n < most {
        let (w, b) = ((start + n) / 64, (start + n) % 64);
        // The shift brings in zeros, so a run to the word's end stops there.
        let run = ((!(words[w] >> b)).trailing_zeros() as usize).min(64 - b);
        n += run;
        if run < 64 - b {
            break;
        }
    }
    n.min(most)
}

#[cfg(test)]
mod tests {
    use crate::geom::{Aabb, Point};
    use crate::lod::{Grid, Lattice, Voxels};

    #[test]
    fn a_full_grid_is_one_box_and_an_l_is_two() {
        let l = Lattice { origin: Point::origin(), cell: 1.0 };
        let g = Grid::new(&l, 0, &Aabb::from_array([0.0, 0.0, 0.0, 3.0, 2.0, 2.0])).unwrap();
        let mut v = Voxels::empty(g.clone());
        assert!(v.fill_box([0, 0, 0, 3, 2, 2]));
        assert_eq!(v.boxes(), vec![[0, 0, 0, 3, 2, 2]]);
        assert_eq!(v.world_boxes(), vec![*g.bounds()]);
        let mut l = Voxels::empty(g);
        assert!(l.fill_box([0, 0, 0, 2, 1, 1]));
        assert!(l.fill_box([0, 1, 0, 1, 2, 1]));
        assert!(!l.fill_box([0, 0, 0, 1, 1, 1]), "overlap");
        assert_eq!(l.boxes(), vec![[0, 0, 0, 2, 1, 1], [0, 1, 0, 1, 2, 1]]);
    }

    /// The cover cell by cell: what the word-at-a-time cover must give.
    fn boxes_cell_by_cell(v: &Voxels) -> Vec<[u16; 6]> {
        let g = v.grid();
        let [dx, dy, dz] = g.dims();
        let mut covered = Voxels::empty(g.clone());
        let free = |c: &Voxels, x: u32, y: u32, z: u32| v.is_set([x, y, z]) && !c.is_set([x, y, z]);
        let mut out = Vec::new();
        for i in 0..g.cells() as usize {
            let [x0, y0, z0] = g.coords(i);
            if !free(&covered, x0, y0, z0) {
                continue;
            }
            let mut x1 = x0 + 1;
            while x1 < dx && free(&covered, x1, y0, z0) {
                x1 += 1;
            }
            let mut y1 = y0 + 1;
            while y1 < dy && (x0..x1).all(|x| free(&covered, x, y1, z0)) {
                y1 += 1;
            }
            let mut z1 = z0 + 1;
            while z1 < dz && (y0..y1).all(|y| (x0..x1).all(|x| free(&covered, x, y, z1))) {
                z1 += 1;
            }
            let b = [x0, y0, z0, x1, y1, z1].map(|c| c as u16);
            assert!(covered.fill_box(b));
            out.push(b);
        }
        out
    }

    proptest::proptest! {
        /// Rows tested and cleared a word at a time give the cell-by-cell
        /// cover, on grids whose rows straddle words.
        #[test]
        fn the_cover_is_the_cell_by_cell_greedy_cover(
            dims in proptest::array::uniform3(1u32..80),
            seeds in proptest::collection::vec(proptest::num::u64::ANY, 0..200),
            blocks in proptest::collection::vec(proptest::array::uniform3(0u32..80), 0..3),
        ) {
            let l = Lattice { origin: Point::origin(), cell: 1.0 };
            let dims = [dims[0], dims[1], 1 + dims[2] % 6];
            let b = Aabb::from_array([0.0, 0.0, 0.0, f64::from(dims[0]), f64::from(dims[1]), f64::from(dims[2])]);
            let v = Voxels::scattered_and_solid(Grid::new(&l, 0, &b).unwrap(), &seeds, &blocks);
            let want = boxes_cell_by_cell(&v);
            proptest::prop_assert_eq!(v.boxes(), want.clone());
            proptest::prop_assert_eq!(v.boxes_within(want.len()), Some(want.clone()));
            if let Some(fewer) = want.len().checked_sub(1) {
                proptest::prop_assert_eq!(v.boxes_within(fewer), None);
            }
        }
    }
}
