//! One node's group bound b(S_n,k) (paper §1.5, format-spec/group.md): the
//! grid rule from the meta block, and the bound from its node block's group
//! block (one read, predicted from the record's flags: the paper's
//! bFits/bPage).

use super::{ReadTransaction, Reads, view};
use crate::geom::Aabb;
use crate::lod::{GroupRule, Voxels};
use crate::store::format::frame::BlockType;
use crate::store::format::{group, node};
use crate::store::{Block, StorageError};

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
}
