//! Reading group bounds b(S_n,k) (paper §1.5, format-spec/group.md): the
//! grid rule from the meta block, one node's bound from its node block's
//! group block (one read, predicted from the record's flags: the paper's
//! bFits/bPage), and a file's summary of them per level (`mktree lods`).

use std::collections::{BTreeMap, HashSet};
use std::sync::Arc;

use super::{ReadTransaction, Reads, view, walk_everything};
use crate::geom::Aabb;
use crate::lod::{GroupRule, Voxels};
use crate::query::Visitor;
use crate::store::format::frame::BlockType;
use crate::store::format::{group, node};
use crate::store::{Block, StorageError};

/// Group bounds of one level k, over a whole tree.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct GroupLevel {
    /// k.
    pub level: u8,
    /// Nodes whose b(S_n,k) is stored (the paper's `bFits[k]` true).
    pub stored: u64,
    /// Their blobs' bytes.
    pub bytes: u64,
    /// The root's b(S,k): faces of its boundary with coplanar faces merged
    /// (the paper's Faces(b(S,k)), Figure 2), and its guaranteed error, mm;
    /// `None` when the root's is not stored.
    pub root_faces: Option<u64>,
    /// The root's bound's guaranteed error, mm; `None` when it is not stored.
    pub root_eps_mm: Option<f64>,
    /// Triangles of the root's bound as drawn (its greedy rectangles, two each).
    pub root_triangles: Option<u64>,
}

/// What a file holds of group bounds.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct GroupSummary {
    /// Per level k = 2 .. min(M - 1, 8).
    pub levels: Vec<GroupLevel>,
    /// Group blocks, and the bytes of entries they hold.
    pub blocks: u64,
    /// Bytes of entries the group blocks hold.
    pub block_bytes: u64,
    /// Nodes of the tree (each could hold one per level).
    pub nodes: u64,
}

impl ReadTransaction {
    /// How the snapshot's group bounds are gridded (`None` for M < 3 or no tree).
    pub fn group_rule(&self) -> Option<GroupRule> {
        let meta = self.snapshot.meta.as_ref()?;
        let m = self.pager().lod_levels();
        (m >= 3).then_some(())?;
        Some(GroupRule {
            lattice: self.lattice()?,
            levels: m,
            floor: meta.lods.grid_level.iter().take(usize::from(m)).copied().collect(),
            cuberille_bits: meta.lods.cuberille_bits,
        })
    }

    /// b(S_n,k) of the record at `offset` of node block `block`, whose box
    /// is `frame`, read through `reads` (its group block, unless held);
    /// `None` when the block's group block holds none at level k.
    pub(crate) fn group_bound(
        &self,
        block: &Block,
        offset: u32,
        frame: &Aabb,
        k: u8,
        reads: &mut Reads,
    ) -> Result<Option<Voxels>, StorageError> {
        let record = view(block, offset)?;
        if !record.group_levels().any(|l| l == k) {
            return Ok(None);
        }
        let frame = record.frame(*frame);
        let corrupt = |d: String| StorageError::corrupt(block.id(), "group_block", d);
        let (gb, sum) = node::group_ref(block.bytes()).ok_or_else(|| corrupt("no group block".into()))?;
        let g = self.block(gb, BlockType::Group, sum, reads)?;
        let blob = group::find(g.bytes(), &g.groups, offset, k).ok_or_else(|| {
            corrupt(format!("record {offset}'s bound at level {k} is not in group block {gb}"))
        })?;
        let rule =
            self.group_rule().ok_or_else(|| corrupt("group bounds in a file without a lattice".into()))?;
        let grid = rule.grid(k, &frame).map_err(|e| corrupt(format!("level {k}: {e}")))?;
        crate::lod::decode(blob, &rule.lattice, grid.bounds())
            .ok()
            .filter(|v| v.grid() == &grid)
            .map(Some)
            .ok_or_else(|| {
                StorageError::corrupt(
                    gb,
                    "blob",
                    format!("record {offset}'s bound at level {k} is not on its grid"),
                )
            })
    }

    /// Every group bound the snapshot's tree stores, per level, with the
    /// root's faces (reads every node block and group block once).
    pub fn group_summary(&self) -> Result<GroupSummary, StorageError> {
        let mut out = GroupSummary::default();
        let (Some(rule), Some(root)) = (self.group_rule(), self.root()) else { return Ok(out) };
        out.levels = rule.group_levels().map(|level| GroupLevel { level, ..GroupLevel::default() }).collect();
        let mut tally =
            Tally { txn: self, rule: &rule, out: &mut out, blocks: HashSet::new(), root: true, err: None };
        walk_everything(self, root, &mut Reads::new(None), &mut tally)?;
        if let Some(e) = tally.err {
            return Err(e);
        }
        Ok(out)
    }
}

struct Tally<'a> {
    txn: &'a ReadTransaction,
    rule: &'a GroupRule,
    out: &'a mut GroupSummary,
    blocks: HashSet<u32>,
    root: bool,
    err: Option<StorageError>,
}

impl Visitor for Tally<'_> {
    fn node(&mut self, block: &Arc<Block>, offset: u32, frame: &Aabb) -> Result<(), StorageError> {
        self.out.nodes += 1;
        let root = std::mem::take(&mut self.root);
        let record = view(block, offset)?;
        let mut reads = Reads::new(None);
        let mut by_level: BTreeMap<u8, Voxels> = BTreeMap::new();
        for k in record.group_levels() {
            // `frame` is the record's own frame already (the traversal applies it).
            if let Some(v) = self.txn.group_bound(block, offset, frame, k, &mut reads)? {
                by_level.insert(k, v);
            }
        }
        if let Some((gb, sum)) = node::group_ref(block.bytes())
            && self.blocks.insert(gb)
        {
            let g = self.txn.block(gb, BlockType::Group, sum, &mut reads)?;
            self.out.blocks += 1;
            self.out.block_bytes +=
                8 + g.groups.iter().map(|e| (group::ENTRY_LEN + e.2.len()) as u64).sum::<u64>();
        }
        for l in &mut self.out.levels {
            let Some(v) = by_level.get(&l.level) else { continue };
            l.stored += 1;
            l.bytes += crate::lod::encoded_len(v) as u64;
            if root {
                l.root_faces = Some(v.faces() as u64);
                l.root_eps_mm = self.rule.eps(l.level, frame);
                l.root_triangles = Some(v.boundary_mesh().triangle_count() as u64);
            }
        }
        Ok(())
    }
}
