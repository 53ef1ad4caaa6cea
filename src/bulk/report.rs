//! The paper's reports on a built tree: the per-level table of Tables 2-38
//! (§3.1.1, §3.2.1) and the totals of Tables 39-44 (§4), plus a summary of
//! the tree's shape.
//!
//! Serialised with serde under the keys `levels` [{`level`, `leaves`,
//! `ov_min`, `ov_min_rel`, `ov_max`}], `ov_accumulated`, `grey_nodes`,
//! `ov_average`, `depth`, `leaves`, `objects`.

use serde::Serialize;

use super::{Hierarchy, Node};

/// One row of Tables 2-38: one tree level.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LevelRow {
    /// Tree level, 0 at the root.
    pub level: u32,
    /// N. leaves: leaves at this level.
    pub leaves: usize,
    /// `ov_min` (ovMin): the least chosen overlap among this level's
    /// internal nodes; `None` when the level has leaves only.
    pub ov_min: Option<f64>,
    /// `ov_min_rel` (ovMinRel): `ov_min` over the extent, along its cut
    /// axis, of the node where it occurs (the first in preorder on ties); 0
    /// when that extent is 0.
    pub ov_min_rel: Option<f64>,
    /// `ov_max` (ovMax): the greatest chosen overlap at this level.
    pub ov_max: Option<f64>,
}

/// Tables 2-38 and 39-44 for one tree.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Report {
    /// One row per level, root first.
    pub levels: Vec<LevelRow>,
    /// `ov_accumulated` (ovAccumulated): the sum of the chosen (clamped)
    /// overlaps over the grey (internal) nodes, in preorder.
    pub ov_accumulated: f64,
    /// `grey_nodes` (N_g): internal nodes.
    pub grey_nodes: usize,
    /// `ov_average` (ovAverage) = `ov_accumulated` / N_g, 0 when N_g = 0.
    pub ov_average: f64,
    /// Number of levels (deepest level + 1).
    pub depth: u32,
    /// Leaves.
    pub leaves: usize,
    /// Objects over all leaves.
    pub objects: usize,
}

impl Report {
    /// The report of `tree`.
    pub fn of(tree: &Hierarchy) -> Report {
        let depth = tree.depth();
        let mut levels: Vec<LevelRow> = (0..depth)
            .map(|level| LevelRow { level, leaves: 0, ov_min: None, ov_min_rel: None, ov_max: None })
            .collect();
        let (mut ov_accumulated, mut grey_nodes, mut leaves, mut objects) = (0.0, 0, 0, 0);
        for node in &tree.nodes {
            let row = &mut levels[node.level as usize];
            match (node.split(), node.objects()) {
                (Some(split), _) => {
                    ov_accumulated += split.overlap;
                    grey_nodes += 1;
                    if row.ov_min.is_none_or(|m| split.overlap < m) {
                        row.ov_min = Some(split.overlap);
                        row.ov_min_rel = Some(relative(node));
                    }
                    row.ov_max = Some(row.ov_max.map_or(split.overlap, |m| m.max(split.overlap)));
                }
                (None, Some(o)) => {
                    row.leaves += 1;
                    leaves += 1;
                    objects += o.len();
                }
                (None, None) => {}
            }
        }
        let ov_average = if grey_nodes > 0 { ov_accumulated / grey_nodes as f64 } else { 0.0 };
        Report { levels, ov_accumulated, grey_nodes, ov_average, depth, leaves, objects }
    }
}

/// ovMinRel of an internal node: its overlap over its extent on the cut axis.
fn relative(node: &Node) -> f64 {
    match node.split() {
        Some(split) => {
            let extent = node.aabb.extent_on(split.axis);
            if extent > 0.0 { split.overlap / extent } else { 0.0 }
        }
        None => 0.0,
    }
}

/// How the leaves sit in a tree.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TreeShape {
    /// Level of the shallowest leaf.
    pub min_leaf_level: u32,
    /// Level of the deepest leaf.
    pub max_leaf_level: u32,
    /// Mean leaf level (over leaves).
    pub mean_leaf_level: f64,
    /// Mean objects per leaf: the leaf fill, against `mem_page`.
    pub mean_leaf_objects: f64,
    /// Most objects in a leaf.
    pub max_leaf_objects: usize,
}

impl TreeShape {
    /// The shape of `tree`; none when it has no leaf.
    pub fn of(tree: &Hierarchy) -> Option<TreeShape> {
        let leaves: Vec<(u32, usize)> =
            tree.leaves().map(|(id, objects)| (tree.nodes[id.index()].level, objects.len())).collect();
        let count = leaves.len() as f64;
        Some(TreeShape {
            min_leaf_level: leaves.iter().map(|l| l.0).min()?,
            max_leaf_level: leaves.iter().map(|l| l.0).max()?,
            mean_leaf_level: leaves.iter().map(|l| f64::from(l.0)).sum::<f64>() / count,
            mean_leaf_objects: leaves.iter().map(|l| l.1 as f64).sum::<f64>() / count,
            max_leaf_objects: leaves.iter().map(|l| l.1).max()?,
        })
    }
}
