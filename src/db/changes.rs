//! What later commits changed, as a snapshot's meta block logs it
//! (format-spec/meta.md, "The change log"; `store/format/change_log.rs`).

use super::ReadTransaction;
use crate::store::StorageError;
use crate::store::format::change_log::LoggedChange;

impl ReadTransaction {
    /// Every key a commit after `txn` (up to this snapshot's) inserted,
    /// updated or removed, oldest commit first; `None` when this snapshot's
    /// log does not reach back to `txn`: a bulk load since, more changes
    /// than its meta block holds, a tree whose objects were all removed, or
    /// a `txn` after this snapshot's. Reads no block: the log is the meta
    /// block's.
    pub fn changes_since(&self, txn: u64) -> Result<Option<Vec<LoggedChange>>, StorageError> {
        if txn > self.txn() {
            return Ok(None);
        }
        match self.snapshot.meta.as_ref() {
            Some(m) => m.log.changes_after(txn),
            None => Ok((txn == self.txn()).then(Vec::new)),
        }
    }
}
