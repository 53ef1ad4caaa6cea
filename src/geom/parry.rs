//! The only place that imports parry: a triangle set's BVH for point distances.

use super::Point;
use parry3d_f64::query::PointQuery;
use parry3d_f64::shape::TriMesh;

/// Distances from points to a set of triangles (the surface, not a solid),
/// through parry's BVH. Deterministic: the same triangles give the same tree.
pub struct SurfaceDistance {
    mesh: Option<TriMesh>,
}

impl SurfaceDistance {
    /// The surface of `triangles`. Zero-area triangles are dropped (parry
    /// cannot project onto them); they lie on their neighbours' edges in
    /// any mesh that has area, so distances only grow where one stood alone.
    pub fn new(triangles: impl IntoIterator<Item = [Point; 3]>) -> SurfaceDistance {
        let mut vertices = Vec::new();
        let mut indices = Vec::new();
        for [a, b, c] in triangles {
            if (b - a).cross(&(c - a)).norm_squared() > 0.0 {
                let n = vertices.len() as u32;
                vertices.extend([a, b, c]);
                indices.push([n, n + 1, n + 2]);
            }
        }
        SurfaceDistance { mesh: TriMesh::new(vertices, indices).ok() }
    }

    /// The distance from `p` to the nearest triangle (infinite when there is none).
    pub fn distance(&self, p: &Point) -> f64 {
        self.mesh.as_ref().map_or(f64::INFINITY, |m| (p - m.project_local_point(p, false).point).norm())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distance_to_a_triangle_from_its_plane_edge_and_corner_regions() {
        let s = SurfaceDistance::new([[
            Point::new(0.0, 0.0, 0.0),
            Point::new(1.0, 0.0, 0.0),
            Point::new(0.0, 1.0, 0.0),
        ]]);
        assert!((s.distance(&Point::new(0.2, 0.2, 3.0)) - 3.0).abs() < 1e-12);
        assert!((s.distance(&Point::new(0.5, -2.0, 0.0)) - 2.0).abs() < 1e-12);
        assert!((s.distance(&Point::new(-3.0, -4.0, 0.0)) - 5.0).abs() < 1e-12);
        assert_eq!(SurfaceDistance::new([]).distance(&Point::origin()), f64::INFINITY);
    }
}
