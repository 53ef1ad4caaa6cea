//! The MKtree inside an application's redb database (the `redb` feature):
//! its blocks are values of a table in the application's own database, so
//! the application's tables and its spatial index commit in one redb
//! transaction, and read queries see the snapshot of the application's
//! read transaction. redb's commit is the only commit: the tree's state is
//! one value of the table, written in the application's transaction, with
//! no commit slot, sync or recovery of mktree's own. The layout and which
//! layer checks what: format-spec/redb.md.

mod backend;
mod table;

use std::sync::Arc;

pub use backend::{BackendCounter, CountingBackend};

use crate::Error;
use crate::db::{CreateOptions, DEFAULT_LOD_LEVELS, Database, ReadTransaction, WriteTransaction};
use crate::store::device::MemDevice;
use crate::store::format::table::TableState;
use crate::store::format::{validate_block_size, validate_lod_levels};
use table::{Blocks, SnapshotDevice, TableClient, redb_error, state_of};

/// The default block size in a redb table: 16 KiB less 16 bytes, so that a
/// block and its redb leaf's header (12 bytes for one `u32` key and a
/// value) fit one 16 KiB redb page. A block of exactly 16 KiB takes a
/// 32 KiB page, and the database twice the space (format-spec/redb.md).
pub const DEFAULT_BLOCK_SIZE: u32 = 16 * 1024 - 16;

/// A tree kept in the redb table `name` of an application's database; like
/// `redb::TableDefinition`, a constant the application names its index by.
///
/// ```
/// use mktree::redb::TreeDefinition;
/// use mktree::scene::generate::{GenOptions, Preset, generate_scene};
/// use mktree::{Aabb, BuildParams};
/// use redb::{ReadableDatabase, TableDefinition};
///
/// const PUMPS: TableDefinition<u64, &str> = TableDefinition::new("pumps");
/// const INDEX: TreeDefinition = TreeDefinition::new("pumps-index");
///
/// let db = redb::Builder::new().create_with_backend(redb::backends::InMemoryBackend::new())?;
/// let scene = generate_scene(&GenOptions { preset: Preset::Tanker1, objects: None, seed: 1 })?;
/// let txn = db.begin_write()?;
/// txn.open_table(PUMPS)?.insert(1, "P-101")?;
/// INDEX.write(&txn, |w| w.bulk_load(&scene, &BuildParams::paper(), &|_| {}).map(|_| ()))?;
/// txn.commit()?; // the row and the index, or neither
///
/// let r = INDEX.read(&db.begin_read()?)?; // an mktree::ReadTransaction
/// assert_eq!(r.query_box(&scene.aabb())?.objects.len(), scene.len());
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TreeDefinition<'a> {
    name: &'a str,
    options: CreateOptions,
}

impl<'a> TreeDefinition<'a> {
    /// The tree in table `name`, created with [`DEFAULT_BLOCK_SIZE`] and the
    /// default levels of detail.
    pub const fn new(name: &'a str) -> TreeDefinition<'a> {
        TreeDefinition {
            name,
            options: CreateOptions { block_size: DEFAULT_BLOCK_SIZE, lod_levels: DEFAULT_LOD_LEVELS },
        }
    }

    /// The block size and levels of detail a new tree is created with; a
    /// tree already committed keeps its own.
    pub const fn with_options(self, options: CreateOptions) -> TreeDefinition<'a> {
        TreeDefinition { options, ..self }
    }

    /// The table's name.
    pub fn name(&self) -> &str {
        self.name
    }

    fn blocks(&self) -> Blocks<'a> {
        Blocks::new(self.name)
    }

    /// The state of a tree never committed.
    fn empty(&self) -> Result<TableState, Error> {
        let block_size = validate_block_size(self.options.block_size.into())?;
        let lod_levels = validate_lod_levels(self.options.lod_levels.into())?;
        Ok(TableState::empty(block_size, lod_levels))
    }

    /// Runs `f` on a write transaction of the tree inside the application's
    /// transaction `txn`, and commits it there when `f` succeeds: the new
    /// tree and the application's own writes become durable together with
    /// `txn.commit()`, and `txn.abort()`, a failed commit or a crash drops
    /// both. When `f` fails, the blocks it wrote are removed and the tree is
    /// as it was. `f` must not open the tree's table itself.
    ///
    /// The table is created when it does not exist. Its blocks are written
    /// through redb's table on a thread of this call's own, which `f` never
    /// sees (`src/redb/table.rs`).
    pub fn write<R>(
        &self,
        txn: &redb::WriteTransaction,
        f: impl FnOnce(&mut WriteTransaction<'_>) -> Result<R, Error>,
    ) -> Result<R, Error> {
        let table = txn.open_table(self.blocks()).map_err(redb_error)?;
        let state = match state_of(&table)? {
            Some(s) => s,
            None => self.empty()?,
        };
        table::with_table(table, &state, |client| run(client, &state, f))
    }

    /// The tree as the application's read transaction `txn` sees it, with
    /// mktree's whole read surface (queries, `get`, `mesh`, `select`, ...).
    /// It holds `txn`'s snapshot while it lives. A table that does not
    /// exist, or was never committed, is an empty tree.
    pub fn read(&self, txn: &redb::ReadTransaction) -> Result<ReadTransaction, Error> {
        let table = match txn.open_table(self.blocks()) {
            Ok(t) => t,
            Err(redb::TableError::TableDoesNotExist(_)) => return self.read_empty(),
            Err(e) => return Err(redb_error(e).into()),
        };
        let Some(state) = state_of(&table)? else { return self.read_empty() };
        let device = Arc::new(SnapshotDevice::new(table, state.block_size));
        Ok(Database::hosted(device, None, &state)?.begin_read()?)
    }

    /// An empty tree reads no block: a device of no bytes serves it.
    fn read_empty(&self) -> Result<ReadTransaction, Error> {
        Ok(Database::hosted(Arc::new(MemDevice::new()), None, &self.empty()?)?.begin_read()?)
    }
}

fn run<R>(
    client: Arc<TableClient>,
    state: &TableState,
    f: impl FnOnce(&mut WriteTransaction<'_>) -> Result<R, Error>,
) -> Result<R, Error> {
    let db = Database::hosted(client.clone(), Some(client), state)?;
    let mut w = db.begin_write()?;
    // On an error `w` is dropped: its rollback removes what it wrote.
    let out = f(&mut w)?;
    w.commit()?;
    Ok(out)
}
