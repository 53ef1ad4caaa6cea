//! The voxel solid as a polyhedron (levels k >= 3, reported as Faces(b(S,k))):
//! its boundary squares, with coplanar squares of the same plane and normal
//! merged. A face is a 4-connected region of one plane (it may be L-shaped or
//! hold holes); the exported mesh splits each into greedy rectangles.

use super::Voxels;
use crate::geom::Point;
use crate::scene::Mesh;
use std::collections::HashMap;

/// One boundary rectangle: cells [u0, u1) x [v0, v1) of the plane `plane`
/// normal to `axis` (u = axis + 1, v = axis + 2, cyclic), facing +axis if `positive`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Rect {
    pub axis: usize,
    pub plane: u32,
    pub positive: bool,
    pub uv: [u32; 4],
}

impl Voxels {
    /// Faces of the boundary polyhedron after merging coplanar faces: the
    /// 4-connected regions of boundary squares per plane and normal.
    pub fn faces(&self) -> usize {
        self.faces_up_to(usize::MAX)
    }

    /// [`Voxels::faces`], but counting stops at `limit`: min(faces, limit).
    /// Deciding whether a bound has fewer faces than its triangles need not
    /// count them all.
    pub fn faces_up_to(&self, limit: usize) -> usize {
        let mut n = 0;
        let mut seen = Vec::new();
        let mut stack = Vec::new();
        self.for_each_plane(|_, _, _, mask, du, dv| {
            if n >= limit {
                return false;
            }
            seen.clear();
            seen.resize(mask.len(), false);
            for start in 0..mask.len() {
                if !mask[start] || seen[start] {
                    continue;
                }
                n += 1;
                seen[start] = true;
                stack.push(start);
                while let Some(i) = stack.pop() {
                    let (u, v) = (i % du, i / du);
                    let mut go = |j: usize| {
                        if mask[j] && !seen[j] {
                            seen[j] = true;
                            stack.push(j);
                        }
                    };
                    if u > 0 {
                        go(i - 1);
                    }
                    if u + 1 < du {
                        go(i + 1);
                    }
                    if v > 0 {
                        go(i - du);
                    }
                    if v + 1 < dv {
                        go(i + du);
                    }
                }
            }
            true
        });
        n.min(limit)
    }

    /// The boundary as greedy rectangles per plane and normal (T-junctions
    /// where rectangles of one plane meet those of another are allowed).
    pub(crate) fn boundary_rects(&self) -> Vec<Rect> {
        let mut out = Vec::new();
        let mut used = Vec::new();
        self.for_each_plane(|axis, plane, positive, mask, du, dv| {
            used.clear();
            used.resize(mask.len(), false);
            for start in 0..mask.len() {
                if !mask[start] || used[start] {
                    continue;
                }
                let (u0, v0) = (start % du, start / du);
                let mut u1 = u0 + 1;
                while u1 < du && mask[v0 * du + u1] && !used[v0 * du + u1] {
                    u1 += 1;
                }
                let mut v1 = v0 + 1;
                while v1 < dv && (u0..u1).all(|u| mask[v1 * du + u] && !used[v1 * du + u]) {
                    v1 += 1;
                }
                for v in v0..v1 {
                    used[v * du + u0..v * du + u1].fill(true);
                }
                let uv = [u0, v0, u1, v1].map(|c| c as u32);
                out.push(Rect { axis, plane, positive, uv });
            }
            true
        });
        out
    }

    /// The closed boundary polyhedron as a mesh: each greedy rectangle as two
    /// triangles wound counter-clockwise seen from outside, corners shared.
    /// An empty set gives a mesh with no triangle.
    pub fn boundary_mesh(&self) -> Mesh {
        let g = &self.grid;
        let mut ids: HashMap<[u32; 3], u32> = HashMap::new();
        let mut verts: Vec<Point> = Vec::new();
        let mut tris: Vec<[u32; 3]> = Vec::new();
        for r in self.boundary_rects() {
            let (a, u, v) = (r.axis, (r.axis + 1) % 3, (r.axis + 2) % 3);
            let [u0, v0, u1, v1] = r.uv;
            let mut corner = |cu: u32, cv: u32| {
                let mut c = [0u32; 3];
                c[a] = r.plane;
                c[u] = cu;
                c[v] = cv;
                *ids.entry(c).or_insert_with(|| {
                    verts.push(Point::new(g.plane(0, c[0]), g.plane(1, c[1]), g.plane(2, c[2])));
                    verts.len() as u32 - 1
                })
            };
            let q = [corner(u0, v0), corner(u1, v0), corner(u1, v1), corner(u0, v1)];
            // (u, v, axis) is right-handed, so u then v turns counter-clockwise about +axis.
            if r.positive {
                tris.extend([[q[0], q[1], q[2]], [q[0], q[2], q[3]]]);
            } else {
                tris.extend([[q[0], q[2], q[1]], [q[0], q[3], q[2]]]);
            }
        }
        if tris.is_empty() {
            return Mesh::from_parts(Point::origin(), Vec::new(), Vec::new());
        }
        Mesh::from_world(&verts, tris).expect("finite corners and valid indices")
    }

    /// Calls `f(axis, plane, positive, mask, du, dv)` for every plane and
    /// normal with a boundary square; `mask[u + du * v]` marks the squares.
    /// Calls `f` with each plane's mask of boundary squares until `f` returns false.
    fn for_each_plane(&self, mut f: impl FnMut(usize, u32, bool, &[bool], usize, usize) -> bool) {
        let g = &self.grid;
        let d = g.dims();
        let mut mask = Vec::new();
        for a in 0..3 {
            let (u, v) = ((a + 1) % 3, (a + 2) % 3);
            let (du, dv) = (d[u] as usize, d[v] as usize);
            let cell = |k: u32, cu: usize, cv: usize| {
                let mut c = [0u32; 3];
                c[a] = k;
                c[u] = cu as u32;
                c[v] = cv as u32;
                self.get(g.index(c))
            };
            for plane in 0..=d[a] {
                for positive in [true, false] {
                    // Positive: the cell below the plane is set, the one above is not.
                    let (inner, outer) = if positive {
                        (plane.checked_sub(1), Some(plane).filter(|&p| p < d[a]))
                    } else {
                        (Some(plane).filter(|&p| p < d[a]), plane.checked_sub(1))
                    };
                    let Some(inner) = inner else { continue };
                    mask.clear();
                    let mut any = false;
                    for cv in 0..dv {
                        for cu in 0..du {
                            let b = cell(inner, cu, cv) && !outer.is_some_and(|o| cell(o, cu, cv));
                            any |= b;
                            mask.push(b);
                        }
                    }
                    if any && !f(a, plane, positive, &mask, du, dv) {
                        return;
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::geom::{Aabb, Point};
    use crate::lod::{Grid, Lattice, Voxels};
    use std::collections::HashMap;

    fn solid(cells: &[[u16; 3]]) -> Voxels {
        let l = Lattice { origin: Point::origin(), cell: 1.0 };
        let g = Grid::new(&l, 0, &Aabb::from_array([0.0, 0.0, 0.0, 3.0, 3.0, 3.0])).unwrap();
        let mut v = Voxels::empty(g);
        for c in cells {
            assert!(v.fill_box([c[0], c[1], c[2], c[0] + 1, c[1] + 1, c[2] + 1]));
        }
        v
    }

    #[test]
    fn faces_counted_by_hand() {
        assert_eq!(solid(&[[0, 0, 0]]).faces(), 6);
        assert_eq!(solid(&[[0, 0, 0], [1, 0, 0]]).faces(), 6, "a 2x1x1 bar");
        // An L in one layer: top and bottom are L-shaped faces, plus 6 sides.
        assert_eq!(solid(&[[0, 0, 0], [1, 0, 0], [0, 1, 0]]).faces(), 8);
        let l = solid(&[[0, 0, 0], [1, 0, 0], [0, 1, 0]]);
        assert_eq!((l.faces_up_to(3), l.faces_up_to(8), l.faces_up_to(100)), (3, 8, 8));
        // A 2x2x2 cube without its corner cell (1, 1, 1): the 3 faces at the
        // corner become L-shaped, the other 3 stay whole, the notch adds 3.
        let mut c: Vec<[u16; 3]> = Vec::new();
        for i in 0..7u16 {
            c.push([i & 1, (i >> 1) & 1, (i >> 2) & 1]);
        }
        assert_eq!(solid(&c).faces(), 9);
        // Two cells touching at an edge only: two separate cubes' faces.
        assert_eq!(solid(&[[0, 0, 0], [1, 1, 0]]).faces(), 12);
        assert_eq!(solid(&[]).faces(), 0);
    }

    /// Every directed unit edge of the rectangles (split at every lattice
    /// vertex, so T-junctions are allowed) is matched by its reverse: the
    /// boundary is closed and consistently oriented.
    fn balanced(rects: &[super::Rect]) -> bool {
        let mut count: HashMap<([u32; 3], [u32; 3]), i32> = HashMap::new();
        for r in rects {
            let (a, u, w) = (r.axis, (r.axis + 1) % 3, (r.axis + 2) % 3);
            let p = |cu: u32, cw: u32| {
                let mut c = [0u32; 3];
                c[a] = r.plane;
                c[u] = cu;
                c[w] = cw;
                c
            };
            let [u0, v0, u1, v1] = r.uv;
            let mut ring = vec![];
            ring.extend((u0..u1).map(|x| (p(x, v0), p(x + 1, v0))));
            ring.extend((v0..v1).map(|y| (p(u1, y), p(u1, y + 1))));
            ring.extend((u0..u1).rev().map(|x| (p(x + 1, v1), p(x, v1))));
            ring.extend((v0..v1).rev().map(|y| (p(u0, y + 1), p(u0, y))));
            for (s, e) in ring {
                let (s, e) = if r.positive { (s, e) } else { (e, s) };
                let (key, d) = if s < e { ((s, e), 1) } else { ((e, s), -1) };
                *count.entry(key).or_insert(0) += d;
            }
        }
        count.values().all(|&n| n == 0)
    }

    #[test]
    fn boundary_rectangles_close_up() {
        let mut c: Vec<[u16; 3]> = Vec::new();
        for i in 0..27u16 {
            if (i * 7) % 5 < 3 {
                c.push([i % 3, (i / 3) % 3, i / 9]);
            }
        }
        for cells in [&c[..], &[[0, 0, 0], [1, 1, 0]], &[[0, 0, 0], [1, 0, 0], [0, 1, 0]]] {
            let rects = solid(cells).boundary_rects();
            assert!(balanced(&rects), "unmatched directed edges");
            assert!(!balanced(&rects[1..]), "the check can fail");
            let mut flipped = rects.clone();
            flipped[0].positive = !flipped[0].positive;
            assert!(!balanced(&flipped), "orientation is checked");
        }
    }
}
