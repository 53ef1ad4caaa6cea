//! db's own passes over a stored tree (`check`, `stats`, `scene`, group
//! summaries) walk it through the one traversal here, which turns the
//! walk's error back into the file's in one place.

use crate::query::{Everything, QueryError, QueryOptions, Visitor, walk};
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
    match walk(txn, root, &Everything, &all, reads, visitor) {
        Ok(_) => Ok(()),
        Err(QueryError::Storage(s)) => Err(s),
        Err(other) => Err(StorageError::Invalid(format!("the tree's walk: {other}"))),
    }
}
