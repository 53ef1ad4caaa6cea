//! How far change commits have moved a file's node layout from the one a
//! bulk load would give it (format-spec/commit.md, "Drift"): the node
//! blocks the read model's sample queries ([`QueryMix`]) read on the
//! stored packing, against a fresh packing of the same records chosen as a
//! bulk load chooses it. `mktree stats` reports it; `optimize` restores a
//! fresh layout.

use serde::Serialize;

use super::ReadTransaction;
use super::hierarchy::{StoredLayout, read_layout};
use super::load::{SAMPLES_PER_SCALE, choose_packing, node_reads_per_scale};
use crate::bulk::{Hierarchy, QueryMix};
use crate::store::StorageError;
use crate::store::format::node;
use crate::store::layout::Packing;

/// The read model's node block reads per query on the stored layout and
/// on a fresh one, per scale of the query mix.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LayoutDrift {
    /// The query extents of the mix's scales (mm): the collision-sized
    /// query the file was built for, then boxes of 1%, 5% and 20% of the
    /// scene.
    pub query_extents: Vec<[f64; 3]>,
    /// Per scale: node blocks read per query on the layout as stored.
    pub stored_reads: Vec<f64>,
    /// Per scale: node blocks read per query on a fresh packing of the
    /// same records (what `optimize` would lay out, before any change to
    /// the tree's shape).
    pub fresh_reads: Vec<f64>,
    /// Node blocks as stored.
    pub stored_node_blocks: u32,
    /// Node blocks of the fresh packing.
    pub fresh_node_blocks: u32,
    /// Node blocks on the longest path from the root to a leaf as stored:
    /// over a network, the round trips a cold query needs to reach its
    /// deepest leaf (docs/object-storage.md).
    pub node_block_depth: u32,
}

impl LayoutDrift {
    /// Per scale: stored reads over fresh reads (1 where neither reads).
    pub fn ratios(&self) -> Vec<f64> {
        self.stored_reads
            .iter()
            .zip(&self.fresh_reads)
            .map(|(&s, &f)| {
                if f > 0.0 {
                    s / f
                } else if s > 0.0 {
                    f64::INFINITY
                } else {
                    1.0
                }
            })
            .collect()
    }

    /// The largest ratio over the scales: how much more the worst-placed
    /// queries read than they would after `optimize`.
    pub fn worst_ratio(&self) -> f64 {
        self.ratios().into_iter().fold(1.0, f64::max)
    }
}

impl ReadTransaction {
    /// The snapshot's layout drift, `None` without a tree. Reads every node
    /// block (no geometry), as `stats` does.
    pub fn layout_drift(&self) -> Result<Option<LayoutDrift>, StorageError> {
        Ok(read_tree_and_drift(self)?.1)
    }

    fn drift_of(&self, stored: &StoredLayout) -> Result<Option<LayoutDrift>, StorageError> {
        let Some(meta) = self.snapshot.meta.as_ref() else { return Ok(None) };
        let tree = &stored.tree;
        if tree.nodes.is_empty() {
            return Ok(None);
        }
        // The samples a bulk load of this tree would judge its packing on.
        let root = tree.nodes[0].aabb;
        let mix = QueryMix::new(&root, meta.lods.query_extent);
        let samples = mix.sample_centred(&root, SAMPLES_PER_SCALE);
        let as_stored = packing_of(&stored.blocks);
        let capacity = node::capacity(self.pager().block_size());
        if let Some(i) = stored.sizes.iter().position(|&s| s > capacity) {
            return Err(StorageError::Invalid(format!(
                "node {i}'s record takes {} bytes, more than a node block holds",
                stored.sizes[i]
            )));
        }
        let (fresh, _) = choose_packing(tree, &stored.sizes, capacity, &samples);
        Ok(Some(LayoutDrift {
            query_extents: mix.extents().to_vec(),
            stored_reads: node_reads_per_scale(tree, &as_stored, &samples),
            fresh_reads: node_reads_per_scale(tree, &fresh, &samples),
            stored_node_blocks: as_stored.blocks.len() as u32,
            fresh_node_blocks: fresh.blocks.len() as u32,
            node_block_depth: block_depth(
                &tree.nodes.iter().map(|n| n.children().map(|c| c.map(|c| c.index()))).collect::<Vec<_>>(),
                &stored.blocks,
            ),
        }))
    }
}

/// The stored tree of `txn` (as `read_hierarchy` gives it) and its layout
/// drift, from one read of every node block: what `stats` shows of a file.
pub fn read_tree_and_drift(txn: &ReadTransaction) -> Result<(Hierarchy, Option<LayoutDrift>), StorageError> {
    let stored = read_layout(txn)?;
    let drift = txn.drift_of(&stored)?;
    Ok((stored.tree, drift))
}

/// Node blocks on the longest root-to-leaf path of a tree in preorder (a
/// parent before its children), node `i` with `children[i]`, in block
/// `blocks[i]`.
fn block_depth(children: &[Option<[usize; 2]>], blocks: &[u32]) -> u32 {
    let n = children.len();
    let mut depth = vec![1u32; n];
    for (i, kids) in children.iter().enumerate() {
        for &c in kids.iter().flatten().filter(|&&c| c > i && c < n) {
            depth[c] = depth[i] + u32::from(blocks.get(c) != blocks.get(i));
        }
    }
    depth.into_iter().max().unwrap_or(0)
}

/// The packing the stored tree has: node `i` in block `blocks[i]`, blocks
/// numbered in the order the preorder first meets them.
fn packing_of(blocks: &[u32]) -> Packing {
    let mut index = std::collections::HashMap::new();
    let mut packing = Packing { place: Vec::with_capacity(blocks.len()), blocks: Vec::new() };
    for (i, &b) in blocks.iter().enumerate() {
        let next = packing.blocks.len() as u32;
        let at = *index.entry(b).or_insert(next);
        if at == next {
            packing.blocks.push(Vec::new());
        }
        let members = &mut packing.blocks[at as usize];
        packing.place.push((at, members.len() as u32));
        members.push(i as u32);
    }
    packing
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_stored_packing_numbers_blocks_as_the_preorder_meets_them() {
        let p = packing_of(&[7, 7, 3, 7, 3, 9]);
        assert_eq!(p.blocks, vec![vec![0, 1, 3], vec![2, 4], vec![5]]);
        assert_eq!(p.place, vec![(0, 0), (0, 1), (1, 0), (0, 2), (1, 1), (2, 0)]);
    }

    #[test]
    fn the_block_depth_counts_the_blocks_a_path_crosses() {
        // 0 -> (1 -> (2, 3), 4).
        let tree = [Some([1, 4]), Some([2, 3]), None, None, None];
        assert_eq!(block_depth(&tree, &[5, 5, 5, 5, 5]), 1);
        assert_eq!(block_depth(&tree, &[5, 6, 6, 7, 5]), 3);
        assert_eq!(block_depth(&tree, &[5, 5, 5, 5, 6]), 2);
        assert_eq!(block_depth(&[], &[]), 0);
    }

    #[test]
    fn ratios_compare_stored_with_fresh_per_scale() {
        let d = LayoutDrift {
            query_extents: vec![[1.0; 3]; 3],
            stored_reads: vec![3.0, 2.0, 0.0],
            fresh_reads: vec![2.0, 2.0, 0.0],
            stored_node_blocks: 4,
            fresh_node_blocks: 3,
            node_block_depth: 2,
        };
        assert_eq!(d.ratios(), vec![1.5, 1.0, 1.0]);
        assert_eq!(d.worst_ratio(), 1.5);
    }
}
