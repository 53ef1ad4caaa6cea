//! Reading one node's own level-of-detail entry through a query's buffer
//! pool: what a traversal tests at a node, as opposed to `fetch_level`,
//! which gathers a whole level through the subtree (format-spec/node.md).

use super::{Piece, ReadTransaction};
use crate::store::format::frame::BlockType;
use crate::store::format::lodblock;
use crate::store::format::node::LodRef;
use crate::store::format::node::NodeRecord;
use crate::store::{BlockCache, ReadStats, StorageError};

impl ReadTransaction {
    /// The blob of entry (`level`, `objects`) of `rec` when it is stored at
    /// this node (`entry` as `NodeRecord::entry` resolved it): the record's
    /// box (no read), one LOD or geometry block, or a run; `None` for a spread
    /// entry (the children's entries hold it: a traversal descends) or an
    /// absent one. Reads go through `cache` and are counted in `stats`.
    pub fn read_entry(
        &self,
        rec: &NodeRecord,
        level: u8,
        objects: bool,
        entry: LodRef,
        stats: &mut ReadStats,
        cache: Option<&mut BlockCache>,
    ) -> Result<Option<Piece>, StorageError> {
        let m = self.pager().lod_levels();
        let node = rec.node_id;
        Ok(Some(match entry {
            LodRef::Absent | LodRef::Spread { .. } => return Ok(None),
            LodRef::Same { .. } => {
                return Err(StorageError::Invalid("read_entry takes a resolved entry".into()));
            }
            LodRef::InRecord => Piece::Box { node, aabb: rec.aabb() },
            LodRef::InBlock { .. } | LodRef::Run { .. } if level == m => {
                Piece::Objects(self.read_objects(&entry, stats, cache)?)
            }
            LodRef::InBlock { block, offset, checksum } => {
                self.check_in_snapshot(block)?;
                let b = self.pager().read(block, BlockType::Lod, Some(checksum), stats, cache)?;
                self.decode_piece(node, level, objects, block, lodblock::blob_at(block, &b, offset)?)?
            }
            LodRef::Run { first, blocks, checksum } => {
                let (_, words, len) =
                    self.read_run(first, checksum, Some(blocks), BlockType::LodRun, stats, cache)?;
                let bytes: &[u8] = bytemuck::cast_slice(&words);
                let blob = bytes.get(..len).ok_or_else(|| StorageError::corrupt(first, "run", "short"))?;
                self.decode_piece(node, level, objects, first, blob)?
            }
        }))
    }
}

/// The blocks reading `entry` touches (what a budget pays for, before the
/// buffer pool): one for a block, every block of a run, none otherwise.
pub fn entry_blocks(entry: &LodRef) -> Vec<u32> {
    match *entry {
        LodRef::InBlock { block, .. } => vec![block],
        LodRef::Run { first, blocks, .. } => (first..first.saturating_add(blocks)).collect(),
        _ => Vec::new(),
    }
}
