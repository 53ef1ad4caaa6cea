//! The cost model that `refine` minimises: the expected number of leaves a
//! box query reaches (Kamel and Faloutsos, "On packing R-trees", CIKM 1993;
//! Pagel, Six, Toben and Widmayer, "Towards an analysis of range query
//! performance in spatial data structures", PODS 1993).
//!
//! A query box of extents q_i, placed uniformly so that it meets the scene
//! of extents S_i, meets a box of extents W_i with probability
//! ∏_i (W_i + q_i) / (S_i + q_i); the expected leaf accesses of a tree are
//! that probability summed over its leaves. Not in the paper, which
//! minimises overlap instead (§3.1).
//!
//! What `refine` minimises, [`CostModel::expected_cost`], adds the nodes'
//! reads: a node block holds a clustered subtree of about three levels (7
//! records of a 16 KiB block with 4 levels of detail, README), and a query
//! reads it when it reaches the subtree's root, so every node reached
//! costs about a third of a block read. Measured: without that term,
//! `refine` visits 22% fewer leaves than `vsah` on collision queries of
//! the 10^5-object ship but reads 5% fewer blocks only, its deeper tree
//! reading 13% more node blocks; with it, 17% fewer blocks.

#[cfg(feature = "internals")]
use super::Hierarchy;
use super::QueryExtent;
use crate::geom::{Aabb, Point, Vector};

/// Added to the mean object extent by [`QueryExtent::Auto`], in mm.
const AUTO_MARGIN_MM: f64 = 100.0;

/// Block reads per node reached, in [`CostModel::expected_cost`].
pub const NODE_READ_WEIGHT: f64 = 1.0 / 3.0;

/// The Kamel–Faloutsos / Pagel model for one query extent.
///
/// ```
/// use mktree::bulk::{CostModel, QueryExtent};
/// use mktree::geom::Aabb;
///
/// let boxes = [Aabb::from_array([0.0, 0.0, 0.0, 100.0, 100.0, 100.0]),
///              Aabb::from_array([900.0, 900.0, 900.0, 1000.0, 1000.0, 1000.0])];
/// let model = CostModel::of_boxes(&boxes, QueryExtent::Auto);
/// assert_eq!(model.query_extent(), [200.0; 3]); // mean extent 100 + 100 mm
/// assert_eq!(model.access_probability(&Aabb::from_array([0.0, 0.0, 0.0, 1000.0, 1000.0, 1000.0])), 1.0);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CostModel {
    scene: [f64; 3],
    query: [f64; 3],
}

impl CostModel {
    /// The model of a scene of box `scene` for queries of extents `query` (mm).
    pub fn new(scene: &Aabb, query: [f64; 3]) -> CostModel {
        let e = scene.extent();
        CostModel { scene: [e.x, e.y, e.z], query }
    }

    /// The model of the scene of `boxes` (not empty), with q from `extent`:
    /// [`QueryExtent::Auto`] takes the mean extent of the boxes on each
    /// axis plus 100 mm.
    pub fn of_boxes(boxes: &[Aabb], extent: QueryExtent) -> CostModel {
        let scene = boxes.iter().fold(Aabb::EMPTY, |s, b| s.union(b));
        let query = match extent {
            QueryExtent::Mm(q) => q,
            QueryExtent::Auto => {
                let n = boxes.len().max(1) as f64;
                let sum = boxes.iter().fold([0.0; 3], |s, b| {
                    let e = b.extent();
                    [s[0] + e.x, s[1] + e.y, s[2] + e.z]
                });
                sum.map(|s| s / n + AUTO_MARGIN_MM)
            }
        };
        CostModel::new(&scene, query)
    }

    /// q, per axis, in mm.
    pub fn query_extent(&self) -> [f64; 3] {
        self.query
    }

    /// The probability that a query meets a box `aabb` of the scene:
    /// ∏_i (W_i + q_i) / (S_i + q_i) (an axis where the scene and the query
    /// are both flat counts 1).
    pub fn access_probability(&self, aabb: &Aabb) -> f64 {
        let w = aabb.extent();
        (0..3)
            .map(|i| {
                let whole = self.scene[i] + self.query[i];
                if whole > 0.0 { (w[i] + self.query[i]) / whole } else { 1.0 }
            })
            .product()
    }

    /// The expected number of leaves of `tree` a query reaches: the sum of
    /// its leaves' access probabilities, in preorder.
    #[cfg(feature = "internals")]
    pub fn expected_leaf_accesses(&self, tree: &Hierarchy) -> f64 {
        tree.nodes.iter().filter(|n| n.objects().is_some()).map(|n| self.access_probability(&n.aabb)).sum()
    }

    /// What one node of box `aabb` adds to [`expected_cost`](Self::expected_cost).
    pub fn node_cost(&self, aabb: &Aabb, leaf: bool) -> f64 {
        let p = self.access_probability(aabb);
        if leaf { (1.0 + NODE_READ_WEIGHT) * p } else { NODE_READ_WEIGHT * p }
    }

    /// The expected block reads of a query, as `refine` estimates them: a
    /// leaf reached costs one geometry read, every node reached (leaves
    /// included) `NODE_READ_WEIGHT` (a third) of a node block read. Summed in preorder.
    #[cfg(feature = "internals")]
    pub fn expected_cost(&self, tree: &Hierarchy) -> f64 {
        tree.nodes.iter().map(|n| self.node_cost(&n.aabb, n.objects().is_some())).sum()
    }
}

/// Scene-relative query sides of [`QueryMix`]: 1%, 5% and 20% of the
/// scene's extent on each axis.
pub const MIX_SHARES: [f64; 3] = [0.01, 0.05, 0.2];

/// The read model a file's layout and levels of detail are judged on: box
/// queries at four scales, equally likely, each placed uniformly so that it
/// meets the scene: the collision-sized query of extent q (refine's
/// [`QueryExtent`]), and boxes of [`MIX_SHARES`] of the scene's extent. A
/// layout tuned to one scale can lose at another; the mix keeps all four in
/// view (format-spec/lod.md, "What pays").
#[derive(Debug, Clone, PartialEq)]
pub struct QueryMix {
    scene: Aabb,
    extents: Vec<[f64; 3]>,
}

impl QueryMix {
    /// The mix over `scene` with collision-sized queries of extent `q`.
    pub fn new(scene: &Aabb, q: [f64; 3]) -> QueryMix {
        let e = scene.extent();
        let mut extents = vec![q];
        extents.extend(MIX_SHARES.iter().map(|s| [e.x * s, e.y * s, e.z * s]));
        QueryMix { scene: *scene, extents }
    }

    /// The query extents, one per scale.
    pub fn extents(&self) -> &[[f64; 3]] {
        &self.extents
    }

    /// The probability that a query of the mix meets box `b`.
    #[cfg(feature = "internals")]
    pub fn probability(&self, b: &Aabb) -> f64 {
        let n = self.extents.len() as f64;
        self.extents.iter().map(|q| CostModel::new(&self.scene, *q).access_probability(b)).sum::<f64>() / n
    }

    /// `per_scale` queries of each scale, evenly spread (a Halton sequence)
    /// over the positions where they meet `zone` (the scene, or a box in it).
    pub fn sample(&self, zone: &Aabb, per_scale: usize) -> Vec<Aabb> {
        self.spread(per_scale, |half| (zone.min - half, zone.extent() + 2.0 * half))
    }

    /// `per_scale` queries of each scale centred evenly (a Halton sequence)
    /// in `zone`: how a workload over the scene places them.
    pub fn sample_centred(&self, zone: &Aabb, per_scale: usize) -> Vec<Aabb> {
        self.spread(per_scale, |_| (zone.min, zone.extent()))
    }

    /// `per_scale` queries of each scale, centred at Halton points of the box
    /// (corner, extent) that `centres` gives for the query's half extent.
    fn spread(&self, per_scale: usize, centres: impl Fn(Vector) -> (Point, Vector)) -> Vec<Aabb> {
        // The same unit points serve every scale.
        let units: Vec<[f64; 3]> =
            (1..=per_scale).map(|s| [halton(s, 2), halton(s, 3), halton(s, 5)]).collect();
        let mut out = Vec::with_capacity(per_scale * self.extents.len());
        for q in &self.extents {
            let half = Vector::new(q[0], q[1], q[2]) / 2.0;
            let (lo, e) = centres(half);
            for u in &units {
                let c = lo + Vector::new(u[0] * e.x, u[1] * e.y, u[2] * e.z);
                out.push(Aabb::new(c - half, c + half));
            }
        }
        out
    }

    /// The probability that a query of scale `i` meets `b`.
    pub fn scale_probability(&self, i: usize, b: &Aabb) -> f64 {
        self.extents.get(i).map_or(0.0, |q| CostModel::new(&self.scene, *q).access_probability(b))
    }
}

/// The i-th point (i >= 1) of the van der Corput sequence in `base`.
fn halton(mut i: usize, base: usize) -> f64 {
    let (mut f, mut r) = (1.0, 0.0);
    while i > 0 {
        f /= base as f64;
        r += f * (i % base) as f64;
        i /= base;
    }
    r
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_box_half_the_scene_on_one_axis_is_met_in_proportion() {
        let scene = Aabb::from_array([0.0, 0.0, 0.0, 100.0, 100.0, 100.0]);
        let m = CostModel::new(&scene, [0.0; 3]);
        let half = Aabb::from_array([0.0, 0.0, 0.0, 50.0, 100.0, 100.0]);
        assert_eq!(m.access_probability(&half), 0.5);
        let m = CostModel::new(&scene, [100.0; 3]);
        assert_eq!(m.access_probability(&half), 0.75);
    }

    #[test]
    fn a_node_costs_a_third_of_a_read_and_a_leaf_one_more() {
        let scene = Aabb::from_array([0.0, 0.0, 0.0, 100.0, 100.0, 100.0]);
        let m = CostModel::new(&scene, [0.0; 3]);
        assert_eq!(m.node_cost(&scene, false), NODE_READ_WEIGHT);
        assert_eq!(m.node_cost(&scene, true), 1.0 + NODE_READ_WEIGHT);
    }

    #[test]
    fn a_flat_scene_with_flat_queries_counts_the_flat_axis_as_one() {
        let scene = Aabb::from_array([0.0, 0.0, 0.0, 100.0, 100.0, 0.0]);
        let m = CostModel::new(&scene, [0.0; 3]);
        assert_eq!(m.access_probability(&Aabb::from_array([0.0, 0.0, 0.0, 100.0, 25.0, 0.0])), 0.25);
    }
}
