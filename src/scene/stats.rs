//! Scene statistics for `mktree info`: counts, extent, and the distributions
//! of triangles per object and of object box sizes.

use serde::Serialize;

use super::Scene;
use crate::geom::Aabb;

/// Min, median and max of a sample (all zero for an empty one).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Distribution {
    /// The smallest value.
    pub min: f64,
    /// The median.
    pub median: f64,
    /// The largest value.
    pub max: f64,
}

impl Distribution {
    /// The distribution of `values` (reordered in place). The median of an
    /// even-sized sample is the mean of the two middle values.
    pub fn of(values: &mut [f64]) -> Distribution {
        if values.is_empty() {
            return Distribution { min: 0.0, median: 0.0, max: 0.0 };
        }
        values.sort_by(f64::total_cmp);
        let n = values.len();
        let median = if n % 2 == 1 { values[n / 2] } else { (values[n / 2 - 1] + values[n / 2]) / 2.0 };
        Distribution { min: values[0], median, max: values[n - 1] }
    }
}

/// What `mktree info` prints. JSON keys `objects`, `triangles`, `vertices`,
/// `extent` (`[dx, dy, dz]`) and `bbox` (`[x0, y0, z0, x1, y1, z1]`) are part of the CLI contract.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SceneInfo {
    /// Objects in the scene.
    pub objects: usize,
    /// Triangles over all objects.
    pub triangles: usize,
    /// Vertices over all objects.
    pub vertices: usize,
    /// Triangles of zero area (repeated index or collinear corners).
    pub degenerate_triangles: usize,
    /// The scene box's size along x, y and z, mm.
    pub extent: [f64; 3],
    /// The scene box, x0 y0 z0 x1 y1 z1, mm.
    pub bbox: [f64; 6],
    /// Triangles per object.
    pub triangles_per_object: Distribution,
    /// Longest side of each object's box, mm.
    pub box_longest_side: Distribution,
    /// Shortest side of each object's box, mm.
    pub box_shortest_side: Distribution,
}

impl SceneInfo {
    /// Statistics of `scene`.
    pub fn of(scene: &Scene) -> SceneInfo {
        let aabb =
            if scene.is_empty() { Aabb::new(Default::default(), Default::default()) } else { scene.aabb() };
        let mut tris: Vec<f64> = scene.objects().iter().map(|o| o.mesh.triangle_count() as f64).collect();
        let sides: Vec<(f64, f64)> = scene
            .objects()
            .iter()
            .map(|o| {
                let e = o.aabb().extent();
                (e.max(), e.min())
            })
            .collect();
        let mut longest: Vec<f64> = sides.iter().map(|s| s.0).collect();
        let mut shortest: Vec<f64> = sides.iter().map(|s| s.1).collect();
        let e = aabb.extent();
        SceneInfo {
            objects: scene.len(),
            triangles: scene.triangle_count(),
            vertices: scene.vertex_count(),
            degenerate_triangles: scene.objects().iter().map(|o| o.mesh.degenerate_triangles()).sum(),
            extent: [e.x, e.y, e.z],
            bbox: aabb.to_array(),
            triangles_per_object: Distribution::of(&mut tris),
            box_longest_side: Distribution::of(&mut longest),
            box_shortest_side: Distribution::of(&mut shortest),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::Point;
    use crate::scene::{Mesh, Object};

    #[test]
    fn distribution_of_even_and_odd_samples() {
        assert_eq!(Distribution::of(&mut [3.0, 1.0, 2.0]), Distribution { min: 1.0, median: 2.0, max: 3.0 });
        assert_eq!(Distribution::of(&mut [4.0, 1.0, 2.0, 3.0]).median, 2.5);
        assert_eq!(Distribution::of(&mut []).max, 0.0);
    }

    #[test]
    fn info_counts_a_two_object_scene() {
        let tri = |x: f64| {
            let p = [Point::new(x, 0.0, 0.0), Point::new(x + 2.0, 0.0, 0.0), Point::new(x, 1.0, 3.0)];
            Object::new("t", Mesh::from_world(&p, vec![[0, 1, 2]]).unwrap())
        };
        let info = SceneInfo::of(&Scene::new(vec![tri(0.0), tri(10.0)]));
        assert_eq!((info.objects, info.triangles, info.vertices), (2, 2, 6));
        assert_eq!(info.extent, [12.0, 1.0, 3.0]);
        assert_eq!(info.bbox, [0.0, 0.0, 0.0, 12.0, 1.0, 3.0]);
        assert_eq!(info.box_longest_side.median, 3.0);
        assert_eq!(info.box_shortest_side.min, 1.0);
    }
}
