//! Every node record of a stored tree with the box its parent holds for
//! it (its frame), in the traversal's order: for the fuzz targets' bodies
//! (`fuzz-bodies/`), which forge records in place and decode a leaf's
//! quantized boxes in its frame (format-spec/node.md).

use std::sync::Arc;

use super::{Everything, QueryError, QueryOptions, Visitor, walk};
use crate::geom::Aabb;
use crate::store::{Block, StorageError};
use crate::tree::{NodeRef, ReadTransaction, Reads};

/// A node record: its block, its offset there, and its frame.
pub type RecordAt = (Arc<Block>, u32, Aabb);

#[derive(Default)]
struct Records(Vec<RecordAt>);

impl Visitor for Records {
    fn node(&mut self, block: &Arc<Block>, offset: u32, frame: &Aabb) -> Result<(), StorageError> {
        self.0.push((block.clone(), offset, *frame));
        Ok(())
    }
}

/// Every record of the tree from `root`, each once, in the traversal's
/// order; the walk runs at level 1, where every object is decided by its box.
pub fn node_records(txn: &ReadTransaction, root: NodeRef) -> Result<Vec<RecordAt>, QueryError> {
    let mut records = Records::default();
    let level_one = QueryOptions { lod: Some(1), ..Default::default() };
    walk(txn, root, &Everything, &level_one, &mut Reads::new(None), &mut records)?;
    Ok(records.0)
}
