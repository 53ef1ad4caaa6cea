//! The measured error of a voxel level: the paper's vDist (§1.4) between
//! the voxel solid and the geometry, sampled at set cells' corners and centres.

use super::inside::inside;
use super::{Voxels, is_closed};
use crate::geom::{Aabb, Point, SurfaceDistance};
use crate::scene::Mesh;

/// The sampled two-sided distance between `v` and `meshes`: the largest, over
/// set cells' 8 corners and centre, of the distance to the geometry (0 inside
/// a closed mesh). The other side is 0, since every point of the geometry
/// lies in a set cell. At most `max_cells` cells are sampled: every
/// ceil(count / max_cells)-th set cell in cell order, so the result is
/// deterministic. Never above `v.grid().max_cell_diagonal()` for a set built
/// by [`Voxels::of_meshes`] on these meshes (or lifted from one).
#[cfg(any(test, feature = "internals"))]
pub fn measured_error<'a>(
    v: &Voxels,
    meshes: impl IntoIterator<Item = &'a Mesh> + Clone,
    max_cells: usize,
) -> f64 {
    ErrorProbe::new(meshes).measure(v, max_cells)
}

/// The geometry [`measured_error`] measures against, built once (a BVH over
/// the triangles) and used for every level of the same objects.
pub struct ErrorProbe {
    surface: SurfaceDistance,
    solids: Vec<(Aabb, Vec<[Point; 3]>)>,
}

impl ErrorProbe {
    /// A probe of `meshes`' surfaces and closed solids.
    pub fn new<'a>(meshes: impl IntoIterator<Item = &'a Mesh> + Clone) -> ErrorProbe {
        let surface = SurfaceDistance::new(meshes.clone().into_iter().flat_map(|m| m.triangle_points()));
        let solids = meshes
            .into_iter()
            .filter(|m| is_closed(m))
            .map(|m| (m.aabb(), m.triangle_points().collect()))
            .collect();
        ErrorProbe { surface, solids }
    }

    /// [`measured_error`] of `v` against this probe's meshes.
    pub fn measure(&self, v: &Voxels, max_cells: usize) -> f64 {
        let count = v.count() as usize;
        if count == 0 {
            return 0.0;
        }
        let stride = count.div_ceil(max_cells.max(1));
        let mut worst = 0.0f64;
        for i in v.set_cells().step_by(stride) {
            let b = v.grid.cell_box(v.grid.coords(i));
            let corners = (0..8).map(|k| {
                Point::new(
                    if k & 1 == 0 { b.min.x } else { b.max.x },
                    if k & 2 == 0 { b.min.y } else { b.max.y },
                    if k & 4 == 0 { b.min.z } else { b.max.z },
                )
            });
            for p in corners.chain([b.center()]) {
                let d = self.surface.distance(&p);
                // Only a point that would raise the maximum pays for the solid test.
                if d > worst && !self.solids.iter().any(|(bb, t)| bb.contains_point(&p) && inside(t, &p)) {
                    worst = d;
                }
            }
        }
        worst
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lod::closed::tests::cube_mesh;
    use crate::lod::{Grid, Lattice};

    #[test]
    fn a_filled_cube_measures_its_surface_cells_only() {
        let l = Lattice { origin: Point::origin(), cell: 1.0 };
        let cube = cube_mesh([0.5; 3], [7.5; 3]);
        // On the cube's own box every cell lies in the solid: no error at all.
        let v = Voxels::of_meshes(Grid::new(&l, 0, &cube.aabb()).unwrap(), [&cube]);
        assert_eq!(measured_error(&v, [&cube], usize::MAX), 0.0);
        // On [0, 8]^3 the surface cells stick out by half a cell: the worst
        // point is a grid corner, half a cell diagonal from the cube's corner.
        let g = Grid::new(&l, 0, &Aabb::from_array([0.0, 0.0, 0.0, 8.0, 8.0, 8.0])).unwrap();
        let v = Voxels::of_meshes(g, [&cube]);
        let e = measured_error(&v, [&cube], usize::MAX);
        assert!((e - 0.75f64.sqrt()).abs() < 1e-9, "{e}");
        assert!(e <= v.grid().max_cell_diagonal());
        // Sampling fewer cells can only miss the worst one.
        assert!(measured_error(&v, [&cube], 7) <= e);
    }
}
