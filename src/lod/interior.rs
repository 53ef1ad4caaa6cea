//! The interior of one closed mesh on its own part of the grid. Cells the
//! surface does not touch form 6-connected components, each wholly on one
//! side of the surface (two face-adjacent untouched closed cells share an
//! untouched face). A component reaching the sub-grid's border is outside;
//! any other is tested once, by ray parity at one cell centre, so a pocket
//! open to the outside through a channel thinner than a cell is not filled.

use super::inside::inside;
use crate::geom::Point;
use crate::scene::Mesh;

/// A box of cells of a grid, with its own x-fastest bitmap indexing.
pub(crate) struct Sub {
    lo: [u32; 3],
    dims: [usize; 3],
}

impl Sub {
    pub(crate) fn new(r: [(u32, u32); 3]) -> Sub {
        Sub { lo: r.map(|(a, _)| a), dims: r.map(|(a, b)| (b - a) as usize + 1) }
    }

    pub(crate) fn cells(&self) -> usize {
        self.dims.iter().product()
    }

    /// The local index of global cell `c`, which is inside.
    pub(crate) fn index_inside(&self, c: [u32; 3]) -> usize {
        let l = [0, 1, 2].map(|a| (c[a] - self.lo[a]) as usize);
        l[0] + self.dims[0] * (l[1] + self.dims[1] * l[2])
    }

    /// How far the local index moves for a step along each axis.
    pub(crate) fn strides(&self) -> [usize; 3] {
        [1, self.dims[0], self.dims[0] * self.dims[1]]
    }

    /// The part of cell range `r` (inclusive, per axis) inside, if any.
    pub(crate) fn clip(&self, r: [(u32, u32); 3]) -> Option<[(u32, u32); 3]> {
        let mut out = r;
        for (a, (lo, hi)) in out.iter_mut().enumerate() {
            let last = self.lo[a] + (self.dims[a] - 1) as u32;
            (*lo, *hi) = ((*lo).max(self.lo[a]), (*hi).min(last));
            if lo > hi {
                return None;
            }
        }
        Some(out)
    }

    fn coords(&self, i: usize) -> [usize; 3] {
        [i % self.dims[0], (i / self.dims[0]) % self.dims[1], i / (self.dims[0] * self.dims[1])]
    }

    /// The global cell of local index `i`.
    pub(crate) fn global(&self, i: usize) -> [u32; 3] {
        let l = self.coords(i);
        [0, 1, 2].map(|a| self.lo[a] + l[a] as u32)
    }
}

/// Buffers reused across meshes, so filling allocates per voxelization, not per mesh.
#[derive(Default)]
pub(crate) struct Scratch {
    visited: Vec<u64>,
    queue: Vec<u32>,
    component: Vec<u32>,
}

fn get(bits: &[u64], i: usize) -> bool {
    bits[i / 64] >> (i % 64) & 1 == 1
}

fn set(bits: &mut [u64], i: usize) {
    bits[i / 64] |= 1 << (i % 64);
}

/// Sets in `local` (the mesh's surface cells on `sub`) the cells inside the mesh.
pub(crate) fn fill_interior(
    planes: &[Vec<f64>; 3],
    sub: &Sub,
    mesh: &Mesh,
    local: &mut [u64],
    s: &mut Scratch,
) {
    let n = sub.cells();
    let [dx, dy, dz] = sub.dims;
    if dx < 3 || dy < 3 || dz < 3 {
        return; // every cell is on the border
    }
    s.visited.clear();
    s.visited.extend_from_slice(local);
    s.queue.clear();
    for i in 0..n {
        let [x, y, z] = sub.coords(i);
        let border = x == 0 || y == 0 || z == 0 || x == dx - 1 || y == dy - 1 || z == dz - 1;
        if border && !get(&s.visited, i) {
            set(&mut s.visited, i);
            s.queue.push(i as u32);
        }
    }
    flood(sub, &mut s.visited, &mut s.queue, None);
    let mut tris: Option<Vec<[Point; 3]>> = None;
    for wi in 0..s.visited.len() {
        while s.visited[wi] != u64::MAX {
            let i = wi * 64 + (!s.visited[wi]).trailing_zeros() as usize;
            if i >= n {
                break;
            }
            set(&mut s.visited, i);
            s.queue.clear();
            s.queue.push(i as u32);
            s.component.clear();
            flood(sub, &mut s.visited, &mut s.queue, Some(&mut s.component));
            let c = sub.global(i);
            let centre = Point::new(
                (planes[0][c[0] as usize] + planes[0][c[0] as usize + 1]) / 2.0,
                (planes[1][c[1] as usize] + planes[1][c[1] as usize + 1]) / 2.0,
                (planes[2][c[2] as usize] + planes[2][c[2] as usize + 1]) / 2.0,
            );
            let tris = tris.get_or_insert_with(|| mesh.triangle_points().collect());
            if inside(tris, &centre) {
                for &j in &s.component {
                    set(local, j as usize);
                }
            }
        }
    }
}

/// Breadth-first over unvisited 6-neighbours; records the cells reached
/// (the seeds included) in `component` when given.
fn flood(sub: &Sub, visited: &mut [u64], queue: &mut Vec<u32>, mut component: Option<&mut Vec<u32>>) {
    let [dx, dy, dz] = sub.dims;
    let mut head = 0;
    while head < queue.len() {
        let i = queue[head] as usize;
        head += 1;
        if let Some(c) = component.as_deref_mut() {
            c.push(i as u32);
        }
        let [x, y, z] = sub.coords(i);
        let mut visit = |j: usize| {
            if !get(visited, j) {
                set(visited, j);
                queue.push(j as u32);
            }
        };
        if x > 0 {
            visit(i - 1);
        }
        if x + 1 < dx {
            visit(i + 1);
        }
        if y > 0 {
            visit(i - dx);
        }
        if y + 1 < dy {
            visit(i + dx);
        }
        if z > 0 {
            visit(i - dx * dy);
        }
        if z + 1 < dz {
            visit(i + dx * dy);
        }
    }
    queue.clear();
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn range() -> impl Strategy<Value = [(u32, u32); 3]> {
        prop::array::uniform3((0u32..12, 0u32..6)).prop_map(|a| a.map(|(lo, n)| (lo, lo + n)))
    }

    proptest! {
        #[test]
        fn a_clipped_range_holds_the_cells_of_the_range_inside_at_their_local_index(sub in range(), r in range()) {
            let s = Sub::new(sub);
            let inside = |c: [u32; 3]| (0..3).all(|a| sub[a].0 <= c[a] && c[a] <= sub[a].1);
            let cells = |r: [(u32, u32); 3]| {
                let mut v = Vec::new();
                for z in r[2].0..=r[2].1 {
                    for y in r[1].0..=r[1].1 {
                        for x in r[0].0..=r[0].1 {
                            v.push([x, y, z]);
                        }
                    }
                }
                v
            };
            let expected: Vec<[u32; 3]> = cells(r).into_iter().filter(|&c| inside(c)).collect();
            let clipped = s.clip(r).map_or_else(Vec::new, cells);
            prop_assert_eq!(&clipped, &expected);
            for c in clipped {
                let i = s.index_inside(c);
                prop_assert_eq!(s.global(i), c);
                let [sx, sy, sz] = s.strides();
                let l = [0, 1, 2].map(|a| (c[a] - sub[a].0) as usize);
                prop_assert_eq!(i, l[0] * sx + l[1] * sy + l[2] * sz);
            }
        }
    }
}
