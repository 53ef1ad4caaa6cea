//! Query workloads that compare bulk loaders (`mktree bench-build`): box
//! queries shaped like the scene, isotropic cubes of the same volumes,
//! collision-like queries (an object's box grown by a margin), and the
//! leaves a box query reaches in a hierarchy held in memory.
//!
//! Every generator is deterministic for a seed. The in-memory count is the
//! one the file's traversal makes, on exact f64 boxes: a leaf is reached
//! when its box and its ancestors' boxes meet the query.

use serde::Serialize;

use mktree::bulk::{Hierarchy, NodeId};
use mktree::geom::{Aabb, Vector};

use crate::rng::Rng;
use crate::workload::random_boxes;

/// Seeds cubes apart from the boxes of the same share.
const CUBE_STREAM: u64 = 0xC0BE;
/// Tags collision draws apart from boxes whose share has the margin's bits.
const COLLISION_STREAM: u64 = 0xC011;

/// The growth of an object's box in a collision-like query, in mm.
pub const COLLISION_MARGIN_MM: f64 = 50.0;

/// One kind of query of a benchmark.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum QueryKind {
    /// Boxes whose sides are `share` of the scene's extent on each axis,
    /// centred uniformly in the scene ([`random_boxes`]).
    Box {
        /// Side over the scene's side.
        share: f64,
    },
    /// Cubes of the volume of `Box { share }`, centred uniformly in the
    /// scene (on a flat scene, squares or segments of its measure).
    Cube {
        /// The share of the box of the same volume.
        share: f64,
    },
    /// The box of an object drawn uniformly, grown by `margin_mm` on every side.
    Collision {
        /// Growth in mm.
        margin_mm: f64,
    },
}

impl QueryKind {
    /// The standard set: boxes and cubes of 1%, 5% and 20%, and collisions
    /// with a 50 mm margin.
    pub const STANDARD: [QueryKind; 7] = [
        QueryKind::Box { share: 0.01 },
        QueryKind::Box { share: 0.05 },
        QueryKind::Box { share: 0.2 },
        QueryKind::Collision { margin_mm: COLLISION_MARGIN_MM },
        QueryKind::Cube { share: 0.01 },
        QueryKind::Cube { share: 0.05 },
        QueryKind::Cube { share: 0.2 },
    ];

    /// A short name: "box 1%", "cube 20%", "collide +50".
    pub fn label(&self) -> String {
        match *self {
            QueryKind::Box { share } => format!("box {}%", share * 100.0),
            QueryKind::Cube { share } => format!("cube {}%", share * 100.0),
            QueryKind::Collision { margin_mm } => format!("collide +{margin_mm}"),
        }
    }

    /// `count` queries of this kind over the objects of boxes `boxes` (not
    /// empty), deterministic for a seed.
    pub fn generate(&self, boxes: &[Aabb], count: usize, seed: u64) -> Vec<Aabb> {
        let scene = boxes.iter().fold(Aabb::EMPTY, |s, b| s.union(b));
        match *self {
            QueryKind::Box { share } => random_boxes(&scene, count, share, seed),
            QueryKind::Cube { share } => random_cubes(&scene, count, share, seed),
            QueryKind::Collision { margin_mm } => collision_boxes(boxes, count, margin_mm, seed),
        }
    }
}

/// `count` cubes of the volume of a box whose sides are `share` of the
/// scene's, centred uniformly in `scene`. A flat scene's measure is taken
/// on its non-flat axes, and the query is flat where the scene is.
pub fn random_cubes(scene: &Aabb, count: usize, share: f64, seed: u64) -> Vec<Aabb> {
    let e = scene.extent();
    let axes: Vec<f64> = (0..3).map(|i| e[i]).filter(|&x| x > 0.0).collect();
    let side = if axes.is_empty() {
        0.0
    } else {
        share * axes.iter().product::<f64>().powf(1.0 / axes.len() as f64)
    };
    let half = Vector::new(
        if e.x > 0.0 { side / 2.0 } else { 0.0 },
        if e.y > 0.0 { side / 2.0 } else { 0.0 },
        if e.z > 0.0 { side / 2.0 } else { 0.0 },
    );
    // The centres of boxes of another stream: the same placement rule.
    random_boxes(scene, count, share, seed ^ CUBE_STREAM)
        .into_iter()
        .map(|b| {
            let c = b.center();
            Aabb::new(c - half, c + half)
        })
        .collect()
}

/// `count` boxes of objects drawn uniformly (with repeats) from `boxes`,
/// each grown by `margin_mm`. None when `boxes` is empty.
pub fn collision_boxes(boxes: &[Aabb], count: usize, margin_mm: f64, seed: u64) -> Vec<Aabb> {
    if boxes.is_empty() {
        return Vec::new();
    }
    let mut rng = Rng::new(seed, margin_mm.to_bits() ^ COLLISION_STREAM);
    (0..count).map(|_| boxes[rng.below(boxes.len() as u64) as usize].grown(margin_mm)).collect()
}

/// What a box query meets in a hierarchy held in memory.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct TreeQueryCount {
    /// Leaves reached: their box and all their ancestors' meet the query.
    pub leaves_visited: u64,
    /// Leaves holding an object whose box meets the query: the leaves no
    /// search by boxes can skip, a lower bound on `leaves_visited`.
    pub answer_leaves: u64,
    /// Objects whose box meets the query.
    pub answers: u64,
}

/// The leaves of `tree` (built over `boxes`, object j with box `boxes[j]`)
/// that `query` reaches, and the answers by box among them. A leaf that
/// names an object beyond `boxes` counts none of it.
pub fn count_in_tree(tree: &Hierarchy, boxes: &[Aabb], query: &Aabb) -> TreeQueryCount {
    let mut count = TreeQueryCount::default();
    for (_, _, node) in tree.subtree_where(NodeId::ROOT, |n| n.aabb.intersects(query)) {
        if let Some(objects) = node.objects() {
            count.leaves_visited += 1;
            let hits =
                objects.iter().filter(|o| boxes.get(o.index()).is_some_and(|b| b.intersects(query))).count()
                    as u64;
            count.answers += hits;
            count.answer_leaves += u64::from(hits > 0);
        }
    }
    count
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cubes_have_the_volume_of_the_boxes_of_the_same_share() {
        let scene = Aabb::from_array([0.0, 0.0, 0.0, 100.0, 200.0, 400.0]);
        for share in [0.01, 0.2] {
            let cubes = random_cubes(&scene, 5, share, 3);
            let boxes = random_boxes(&scene, 5, share, 3);
            for (c, b) in cubes.iter().zip(&boxes) {
                let e = c.extent();
                assert!((e.x - e.y).abs() < 1e-9 && (e.y - e.z).abs() < 1e-9);
                assert!((c.volume() / b.volume() - 1.0).abs() < 1e-9);
                assert!(scene.contains_point(&c.center()));
            }
            assert_eq!(cubes, random_cubes(&scene, 5, share, 3));
        }
    }

    #[test]
    fn collisions_are_object_boxes_grown_by_the_margin() {
        let boxes: Vec<Aabb> =
            (0..10).map(|i| Aabb::from_array([i as f64, 0.0, 0.0, i as f64 + 1.0, 1.0, 1.0])).collect();
        for q in collision_boxes(&boxes, 20, 50.0, 1) {
            let inner = Aabb::new(q.min + Vector::repeat(50.0), q.max - Vector::repeat(50.0));
            assert!(boxes.contains(&inner));
        }
        assert!(collision_boxes(&[], 3, 50.0, 1).is_empty());
    }
}
