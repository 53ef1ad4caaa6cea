//! Random query workloads for measurements: boxes of a given share of the
//! scene's extent, centred uniformly in the scene box, from a seed.

use mktree::geom::{Aabb, Point};

use crate::rng::Rng;

/// `count` boxes whose sides are `share` of the scene's extent on each axis,
/// centred uniformly at random in `scene` (deterministic for a seed).
pub fn random_boxes(scene: &Aabb, count: usize, share: f64, seed: u64) -> Vec<Aabb> {
    let mut rng = Rng::new(seed, share.to_bits());
    let e = scene.extent();
    let half = e * share / 2.0;
    (0..count)
        .map(|_| {
            let c = Point::new(
                scene.min.x + rng.unit() * e.x,
                scene.min.y + rng.unit() * e.y,
                scene.min.z + rng.unit() * e.z,
            );
            Aabb::new(c - half, c + half)
        })
        .collect()
}

/// Means over a set of queries.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct WorkloadStats {
    /// Queries run.
    pub queries: usize,
    /// Node blocks read.
    pub mean_node_reads: f64,
    /// Geometry blocks read.
    pub mean_geometry_reads: f64,
    /// All blocks read.
    pub mean_total_reads: f64,
    /// Objects in the answer.
    pub mean_objects: f64,
    /// Leaves reached.
    pub mean_leaves_visited: f64,
    /// Wall time.
    pub mean_milliseconds: f64,
}

/// Runs `queries` against `txn` and averages their statistics.
pub fn run_boxes(
    txn: &mktree::db::ReadTransaction,
    queries: &[Aabb],
) -> Result<WorkloadStats, mktree::query::QueryError> {
    let mut s = WorkloadStats { queries: queries.len(), ..WorkloadStats::default() };
    for q in queries {
        let r = txn.query_box(q)?;
        s.mean_node_reads += r.stats.reads.node as f64;
        s.mean_geometry_reads += r.stats.reads.geometry as f64;
        s.mean_total_reads += r.stats.reads.total() as f64;
        s.mean_objects += r.objects.len() as f64;
        s.mean_leaves_visited += r.stats.leaves_visited as f64;
        s.mean_milliseconds += r.stats.seconds * 1e3;
    }
    let n = queries.len().max(1) as f64;
    for v in [
        &mut s.mean_node_reads,
        &mut s.mean_geometry_reads,
        &mut s.mean_total_reads,
        &mut s.mean_objects,
        &mut s.mean_leaves_visited,
        &mut s.mean_milliseconds,
    ] {
        *v /= n;
    }
    Ok(s)
}

#[cfg(test)]
mod tests {
    use super::*;
    use mktree::geom::Vector;

    #[test]
    fn boxes_are_deterministic_and_sized() {
        let scene = Aabb::from_array([0.0, 0.0, 0.0, 100.0, 200.0, 300.0]);
        let a = random_boxes(&scene, 5, 0.1, 7);
        assert_eq!(a, random_boxes(&scene, 5, 0.1, 7));
        assert_ne!(a, random_boxes(&scene, 5, 0.1, 8));
        for b in &a {
            assert!((b.extent() - Vector::new(10.0, 20.0, 30.0)).norm() < 1e-9);
            assert!(scene.contains_point(&b.center()));
        }
    }
}
