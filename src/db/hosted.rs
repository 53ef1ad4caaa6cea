//! A tree whose blocks live in a table of a host database (redb,
//! `src/redb/`): the host's transactions are the tree's, so its state is
//! the table's state record, not block 0's commit slots, and opening reads
//! no header and recovers nothing (format-spec/redb.md).

use crate::store::StorageError;
use crate::store::format::header::Commit;

/// Where the blocks of a hosted tree live, for its write transactions.
pub(crate) trait Host: Send + Sync {
    /// Makes `c` with its `free` ranges the committed state, and removes the
    /// blocks of `replaced`; durable with the host's commit.
    fn commit(&self, c: &Commit, free: &[(u32, u32)], replaced: &[(u32, u32)]) -> Result<(), StorageError>;
    /// Removes the blocks an abandoned transaction wrote.
    fn discard(&self, written: &[(u32, u32)]) -> Result<(), StorageError>;
}

#[cfg(feature = "redb")]
mod open {
    use std::collections::BTreeMap;
    use std::sync::Arc;

    use super::super::committed::read_meta;
    use super::super::{Database, Snapshot, State};
    use super::{Commit, Host};
    use crate::store::format::freelist::FreeRange;
    use crate::store::format::header::{SlotPair, SlotRead};
    use crate::store::format::table::TableState;
    use crate::store::{BlockDevice, Pager, StorageError};

    impl Database {
        /// The tree of `state` on `device`, the blocks of a host's table. With
        /// `host`, write transactions commit into it; without, the database
        /// only reads (a host's read snapshot).
        pub(crate) fn hosted(
            device: Arc<dyn BlockDevice>,
            host: Option<Arc<dyn Host>>,
            state: &TableState,
        ) -> Result<Database, StorageError> {
            let pager = Pager::new(device, state.block_size, state.lod_levels);
            let committed = Commit {
                txn: state.txn,
                meta_block: state.meta_block,
                meta_checksum: state.meta_checksum,
                block_count: state.block_count,
                free_blocks: state.free_blocks(),
                ..Commit::default()
            };
            let meta = read_meta(&pager, &committed)?;
            let free = state
                .free
                .iter()
                .map(|&(first, count)| FreeRange { first, count, freed: state.txn })
                .collect();
            let read_only = host.is_none();
            let state = State {
                // Unused: the host's commit takes the slots' place.
                slots: [SlotPair { copies: [SlotRead::Committed(committed); 2] }; 2],
                committed,
                committed_slot: 0,
                free,
                chain: Vec::new(),
                unfinished: None,
                snapshot: Arc::new(Snapshot::of(&committed, meta)),
                readers: BTreeMap::new(),
                born: std::collections::HashMap::new(),
            };
            Ok(Database::assemble(pager, state, None, host, read_only, Vec::new()))
        }
    }
}
