//! A file's summary of its group bounds b(S_n,k) per level (paper §1.5,
//! format-spec/group.md; `mktree lods`). One bound is read by
//! `tree/group.rs`.

use std::collections::{BTreeMap, HashSet};
use std::sync::Arc;

use super::walk_everything;
use crate::geom::Aabb;
use crate::lod::{GroupRule, Voxels};
use crate::query::Visitor;
use crate::store::format::frame::BlockType;
use crate::store::format::{group, node};
use crate::store::{Block, StorageError};
use crate::tree::{ReadTransaction, Reads, view};

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
    /// Cells of a level-2 group grid at most (the meta block's
    /// `cuberille_bits`; level k's: 4^(k-2) times more), 0 without a rule.
    pub cuberille_bits: u32,
}

impl ReadTransaction {
    /// Every group bound the snapshot's tree stores, per level, with the
    /// root's faces (reads every node block and group block once).
    pub fn group_summary(&self) -> Result<GroupSummary, StorageError> {
        let mut out = GroupSummary::default();
        let (Some(rule), Some(root)) = (self.group_rule(), self.root()) else { return Ok(out) };
        out.levels = rule.group_levels().map(|level| GroupLevel { level, ..GroupLevel::default() }).collect();
        out.cuberille_bits = rule.cuberille_bits;
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
