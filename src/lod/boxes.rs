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
        let mut covered = vec![0u64; self.bits.len()];
        let free = |covered: &[u64], i: usize| self.get(i) && covered[i / 64] >> (i % 64) & 1 == 0;
        let all_free = |covered: &[u64], x: [u32; 2], y: [u32; 2], z: [u32; 2]| {
            (z[0]..z[1]).all(|z| {
                (y[0]..y[1]).all(|y| {
                    let row = g.index([0, y, z]);
                    (x[0]..x[1]).all(|x| free(covered, row + x as usize))
                })
            })
        };
        let mut out = Vec::new();
        for wi in 0..self.bits.len() {
            // The least set cell not yet covered, a word at a time:
            // covered cells are skipped without a test each, and a box
            // grown from one cell may cover later cells of its word.
            loop {
                let w = self.bits[wi] & !covered[wi];
                if w == 0 {
                    break;
                }
                let i = wi * 64 + w.trailing_zeros() as usize;
                let [x0, y0, z0] = g.coords(i);
                let mut x1 = x0 + 1;
                while x1 < dx && free(&covered, i + (x1 - x0) as usize) {
                    x1 += 1;
                }
                let mut y1 = y0 + 1;
                while y1 < dy && all_free(&covered, [x0, x1], [y1, y1 + 1], [z0, z0 + 1]) {
                    y1 += 1;
                }
                let mut z1 = z0 + 1;
                while z1 < dz && all_free(&covered, [x0, x1], [y0, y1], [z1, z1 + 1]) {
                    z1 += 1;
                }
                for z in z0..z1 {
                    for y in y0..y1 {
                        let row = g.index([0, y, z]);
                        for x in x0..x1 {
                            let j = row + x as usize;
                            covered[j / 64] |= 1 << (j % 64);
                        }
                    }
                }
                // Dims are at most MAX_DIM = 65535, so every corner fits a u16.
                if out.len() == most {
                    return None;
                }
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
}
