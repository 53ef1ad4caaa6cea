//! db's own passes over a stored tree (`check`, `stats`, `scene`, group
//! summaries) walk it through the one traversal here, at level 1, which
//! every file holds: only the file can fail them.

use crate::query::{Everything, QueryOptions, Visitor, walk_level};
use crate::store::StorageError;
use crate::tree::{NodeRef, ReadTransaction, Reads};

/// Walks every node below `root` (level 1: boxes only, no geometry but
/// what `visitor` reads itself): the db's own passes over a stored tree
/// (`check`, `stats`, `scene`, group summaries). Only the file can fail
/// such a walk: level 1 exists at every M, and it has no other option to
/// refuse.
pub(crate) fn walk_everything(
    txn: &ReadTransaction,
    root: NodeRef,
    reads: &mut Reads,
    visitor: &mut dyn Visitor,
) -> Result<(), StorageError> {
    let all = QueryOptions { lod: Some(1), budget: None, ..Default::default() };
    walk_level(txn, root, &Everything, 1, &all, reads, visitor).map(|_| ())
}
