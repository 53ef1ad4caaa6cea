//! A write transaction on a tree whose blocks live in a host database's
//! table (redb, `src/redb/`). The host's transaction is the commit: no
//! commit slot, no sync, no free-list blocks, no recovery; a commit hands
//! the host the new state and the blocks it no longer holds, and the host
//! makes both durable with its own commit, or drops both
//! (format-spec/redb.md, "One commit protocol").

use std::sync::Arc;

use super::{Begun, NewState, WriteTransaction};
use crate::db::{Host, Inner, Recovery};
use crate::store::StorageError;
use crate::store::alloc::FreeSpace;
use crate::store::format::freelist::FreeRange;
use crate::store::format::header::{Commit, MAX_TXN};

/// The installed state: no other writer can commit while the host's write
/// transaction lives, and every free block is reusable at once, since a
/// reader of an older state reads the host's older snapshot, never these
/// blocks as this transaction rewrites them.
pub(super) fn begin(inner: &Arc<Inner>) -> Result<Begun, StorageError> {
    let s = inner.lock_state();
    let base = s.committed;
    if base.txn >= MAX_TXN {
        return Err(StorageError::Invalid(format!("transaction ids are exhausted at {}", base.txn)));
    }
    let avail = FreeSpace::new(base.block_count, s.free.iter().map(|r| (r.first, r.count)));
    Ok(Begun {
        txn: base.txn + 1,
        base,
        base_free: s.free.clone(),
        base_chain: Vec::new(),
        slot: s.committed_slot,
        slot_order: [0, 1],
        recovery: Recovery::default(),
        avail,
        oldest_reader: None,
    })
}

impl WriteTransaction<'_> {
    /// Commits into the host: the new tree's blocks are written already
    /// (never over a block of the base, which stays readable until here).
    pub(super) fn commit_hosted(mut self, host: &dyn Host, cleared: bool) -> Result<(), StorageError> {
        let (meta_block, meta_checksum, meta) = match self.meta.take() {
            Some((block, sum, meta)) => (block, sum, Some(meta)),
            None if cleared => (0, 0, None),
            None => {
                // Nothing written: the committed state stands as it is.
                self.done = true;
                return Ok(());
            }
        };
        // Every block this transaction did not write is free, the replaced
        // tree's included; the free end is cut off.
        let mut free = FreeSpace::complement(self.avail.end(), &self.written);
        let mut end = self.avail.end();
        while let Some(&(first, count)) = free.last()
            && first + count == end
        {
            end = first;
            free.pop();
        }
        let base_free =
            FreeSpace::new(self.base.block_count, self.base_free.iter().map(|r| (r.first, r.count)));
        let replaced = FreeSpace::complement(self.base.block_count, &base_free);
        let c = Commit {
            txn: self.txn,
            meta_block,
            meta_checksum,
            block_count: end,
            free_blocks: free.iter().map(|r| r.1).sum(),
            ..Commit::default()
        };
        host.commit(&c, &free, &replaced)?;
        let labelled =
            free.iter().map(|&(first, count)| FreeRange { first, count, freed: self.txn }).collect();
        self.install(c, Some(NewState { meta, free: labelled, chain: Vec::new() }));
        Ok(())
    }
}
