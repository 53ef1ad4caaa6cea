//! Conservative voxelization (paper §1.5, the cuberille): a cell is set when a
//! triangle touches it (exact SAT on the cell grown by the grid's tolerance),
//! plus the interior of each closed mesh, found per mesh (`interior.rs`).

use super::grid::box_range_on;
use super::interior::{Sub, fill_interior};
use super::{Grid, Voxels, is_closed};
use crate::geom::{Aabb, Point, TriangleBoxTest};
use crate::scene::Mesh;

impl Voxels {
    /// The conservative voxelization of `meshes` on `grid`: every cell a
    /// triangle touches, and every cell inside a closed mesh. Interiors are
    /// found per mesh, over the mesh's own part of the grid, so a cavity that
    /// several objects enclose together stays empty. Geometry outside the
    /// grid's bounds is clipped away.
    pub fn of_meshes<'a>(grid: Grid, meshes: impl IntoIterator<Item = &'a Mesh>) -> Voxels {
        Voxels::voxelize(grid, meshes, true)
    }

    /// The cells the surfaces of `meshes` touch, no interior: every set cell
    /// holds a piece of a surface, so a query holding a whole cell (grown by
    /// the tolerance) meets that surface. What the inline bounds store.
    pub fn of_surfaces<'a>(grid: Grid, meshes: impl IntoIterator<Item = &'a Mesh>) -> Voxels {
        Voxels::voxelize(grid, meshes, false)
    }

    fn voxelize<'a>(grid: Grid, meshes: impl IntoIterator<Item = &'a Mesh>, fill: bool) -> Voxels {
        let mut v = Voxels::empty(grid);
        let planes: [Vec<f64>; 3] = std::array::from_fn(|a| v.grid.planes(a));
        let tol = v.grid.tolerance();
        let mut local: Vec<u64> = Vec::new();
        let mut scratch = Default::default();
        for mesh in meshes {
            let Some(range) = v.grid.box_range(&mesh.aabb().grown(2.0 * tol)) else { continue };
            let sub = Sub::new(range);
            local.clear();
            local.resize(sub.cells().div_ceil(64), 0);
            for t in mesh.triangle_points() {
                surface(&v.grid, &planes, tol, &sub, &t, &mut local);
            }
            if fill && is_closed(mesh) {
                fill_interior(&planes, &sub, mesh, &mut local, &mut scratch);
            }
            for (wi, &w) in local.iter().enumerate() {
                let mut w = w;
                while w != 0 {
                    let c = sub.global(wi * 64 + w.trailing_zeros() as usize);
                    w &= w - 1;
                    let i = v.grid.index(c);
                    v.set(i);
                }
            }
        }
        v
    }
}

/// Sets, in the mesh's sub-grid bitmap, every cell the triangle touches.
fn surface(grid: &Grid, planes: &[Vec<f64>; 3], tol: f64, sub: &Sub, t: &[Point; 3], local: &mut [u64]) {
    let tb = Aabb::from_points(t.iter());
    let Some(r) = box_range_on(planes, &tb.grown(2.0 * tol)) else { return };
    // A triangle inside the grid whose range is one cell touches that cell.
    let single = r.iter().all(|&(a, b)| a == b) && grid.bounds().contains(&tb);
    let cell = |x: u32, y: u32, z: u32| {
        Aabb::from_array([
            planes[0][x as usize] - tol,
            planes[1][y as usize] - tol,
            planes[2][z as usize] - tol,
            planes[0][x as usize + 1] + tol,
            planes[1][y as usize + 1] + tol,
            planes[2][z as usize + 1] + tol,
        ])
    };
    // Prepared at the first cell no earlier triangle set: a triangle among
    // neighbours that set all its cells needs none.
    let mut test: Option<TriangleBoxTest> = None;
    let region = || cell(r[0].0, r[1].0, r[2].0).union(&cell(r[0].1, r[1].1, r[2].1));
    // The triangle's cells lie in the mesh's sub-grid (both ranges are of
    // boxes grown alike, one inside the other); clipping to it once keeps
    // the loops free of a check per cell.
    let Some([(x0, x1), (y0, y1), (z0, z1)]) = sub.clip(r) else { return };
    let [_, row_stride, layer_stride] = sub.strides();
    let mut layer = sub.index_inside([x0, y0, z0]);
    for z in z0..z1 + 1 {
        let mut row = layer;
        for y in y0..y1 + 1 {
            for x in x0..x1 + 1 {
                let i = row + (x - x0) as usize;
                // A cell an earlier triangle of the mesh set needs no test
                // (neighbouring triangles share most of their cells).
                let bit = 1 << (i % 64);
                if local[i / 64] & bit == 0
                    && (single
                        || test
                            .get_or_insert_with(|| TriangleBoxTest::new(t, &region()))
                            .intersects(&cell(x, y, z)))
                {
                    local[i / 64] |= bit;
                }
            }
            row += row_stride;
        }
        layer += layer_stride;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lod::Lattice;

    fn lat() -> Lattice {
        Lattice { origin: Point::origin(), cell: 1.0 }
    }

    fn quad(z: f64, lo: f64, hi: f64) -> Mesh {
        let v = [Point::new(lo, lo, z), Point::new(hi, lo, z), Point::new(hi, hi, z), Point::new(lo, hi, z)];
        Mesh::from_world(&v, vec![[0, 1, 2], [0, 2, 3]]).unwrap()
    }

    #[test]
    fn a_plate_on_a_lattice_plane_sets_the_cells_on_both_sides() {
        let g = Grid::new(&lat(), 0, &Aabb::from_array([0.0, 0.0, 0.0, 4.0, 4.0, 4.0])).unwrap();
        let v = Voxels::of_meshes(g, [&quad(2.0, 0.5, 3.5)]);
        assert_eq!(v.count(), 2 * 16);
    }

    #[test]
    fn a_closed_box_is_filled() {
        let g = Grid::new(&lat(), 0, &Aabb::from_array([0.0, 0.0, 0.0, 8.0, 8.0, 8.0])).unwrap();
        let cube = crate::lod::closed::tests::cube_mesh([0.5; 3], [7.5; 3]);
        let v = Voxels::of_meshes(g, [&cube]);
        assert_eq!(v.count(), 512, "surface cells and the 6^3 inner ones");
    }

    #[test]
    fn the_cavity_between_two_open_plates_stays_empty() {
        let g = Grid::new(&lat(), 0, &Aabb::from_array([0.0, 0.0, 0.0, 8.0, 8.0, 8.0])).unwrap();
        let v = Voxels::of_meshes(g, [&quad(0.5, 0.5, 7.5), &quad(7.5, 0.5, 7.5)]);
        assert_eq!(v.count(), 2 * 64);
    }

    #[test]
    fn a_cavity_walled_by_six_closed_slabs_stays_empty() {
        use crate::lod::closed::tests::cube_mesh;
        let g = Grid::new(&lat(), 0, &Aabb::from_array([0.0, 0.0, 0.0, 8.0, 8.0, 8.0])).unwrap();
        let (a, b) = (0.2, 0.8); // each slab is thinner than a cell
        let slabs = [
            cube_mesh([a, a, a], [7.8, 7.8, b]),
            cube_mesh([a, a, 7.2], [7.8, 7.8, 7.8]),
            cube_mesh([a, a, a], [b, 7.8, 7.8]),
            cube_mesh([7.2, a, a], [7.8, 7.8, 7.8]),
            cube_mesh([a, a, a], [7.8, b, 7.8]),
            cube_mesh([a, 7.2, a], [7.8, 7.8, 7.8]),
        ];
        let v = Voxels::of_meshes(g, &slabs);
        assert_eq!(v.count(), 512 - 216, "the walls only");
    }

    proptest::proptest! {
        /// The surface set is exactly the cells whose grown box a triangle
        /// meets, found cell by cell: the walk of each triangle's range, its
        /// skips of set cells and its one-cell shortcut lose none and add none.
        #[test]
        fn the_surface_set_is_every_cell_a_triangle_touches(
            corners in proptest::collection::vec(proptest::array::uniform3(-5.0f64..5.0), 3..10),
            level in 0u8..2,
        ) {
            let v: Vec<Point> = corners.iter().map(|c| Point::new(c[0], c[1], c[2])).collect();
            let tris: Vec<[u32; 3]> = (0..v.len() as u32 - 2).map(|i| [i, i + 1, i + 2]).collect();
            let Ok(mesh) = Mesh::from_world(&v, tris) else { return Ok(()) };
            let fine = Lattice { origin: Point::origin(), cell: 0.5 };
            let g = Grid::new(&fine, level, &mesh.aabb().grown(0.3)).unwrap();
            let got = Voxels::of_surfaces(g.clone(), [&mesh]);
            let tol = g.tolerance();
            let mut want = Voxels::empty(g.clone());
            let d = g.dims();
            for z in 0..d[2] {
                for y in 0..d[1] {
                    for x in 0..d[0] {
                        let cell = g.cell_box([x, y, z]).grown(tol);
                        if mesh.triangle_points().any(|t| crate::geom::intersects_triangle_box(&t, &cell)) {
                            want.set_cell([x, y, z]);
                        }
                    }
                }
            }
            proptest::prop_assert_eq!(got, want);
        }
    }
}
