//! The blocks of a tree as values of a redb table, keyed by block id; value
//! 0 is the state record (format-spec/redb.md). Two devices serve them to
//! the pager. A read snapshot's table is owned, so its device holds it. A
//! write transaction's table borrows the application's transaction, and
//! the pager holds its device for `'static`: that table stays on a scoped
//! thread, which serves the device's requests one at a time until the
//! device is dropped, so the borrow ends with the scope and no lifetime is
//! stretched.

use std::io;
use std::sync::mpsc::{self, Receiver, Sender};
use std::sync::{Arc, Mutex};

use redb::{ReadOnlyTable, ReadableTable, Table, TableDefinition};

use crate::db::Host;
use crate::store::format::header::Commit;
use crate::store::format::table::TableState;
use crate::store::{BlockDevice, StorageError};

/// The table's types: block id to the block's bytes.
pub(crate) type Blocks<'a> = TableDefinition<'a, u32, &'static [u8]>;

/// The key of the state record (no block has id 0).
const STATE_KEY: u32 = 0;

/// The state record of `table`: `None` for a table that holds nothing yet
/// (a tree never committed); a table holding blocks without one is not a tree.
pub(crate) fn state_of(
    table: &impl ReadableTable<u32, &'static [u8]>,
) -> Result<Option<TableState>, crate::Error> {
    match table.get(STATE_KEY).map_err(redb_error)? {
        Some(v) => Ok(Some(TableState::decode(v.value())?)),
        None if table.is_empty().map_err(redb_error)? => Ok(None),
        None => Err(StorageError::NotMktree.into()),
    }
}

/// A redb error as mktree's.
pub(crate) fn redb_error(e: impl Into<redb::Error>) -> StorageError {
    StorageError::Redb(e.into())
}

/// The block id a whole-block access at `offset` names.
fn block_id(offset: u64, len: usize, block_size: u32) -> io::Result<u32> {
    block_ids(offset, len, block_size).and_then(|ids| match ids.len() {
        1 => Ok(ids.start),
        _ => Err(not_whole_blocks(offset, len)),
    })
}

/// The ids of the consecutive whole blocks (at least one) an access of
/// `len` bytes at `offset` names.
fn block_ids(offset: u64, len: usize, block_size: u32) -> io::Result<std::ops::Range<u32>> {
    let bs = u64::from(block_size);
    let whole = len > 0 && offset.is_multiple_of(bs) && (len as u64).is_multiple_of(bs);
    match (u32::try_from(offset / bs), u32::try_from(offset.saturating_add(len as u64) / bs)) {
        (Ok(first), Ok(end)) if whole && first != STATE_KEY => Ok(first..end),
        _ => Err(not_whole_blocks(offset, len)),
    }
}

fn not_whole_blocks(offset: u64, len: usize) -> io::Error {
    io::Error::new(
        io::ErrorKind::InvalidInput,
        format!("a table holds whole blocks: {len} bytes at offset {offset}"),
    )
}

/// Copies block `id`'s value into `buf`: a missing block reads as the end
/// of a file does, and a value of another size is damage.
fn fill(id: u32, value: Option<&[u8]>, buf: &mut [u8]) -> io::Result<()> {
    let value =
        value.ok_or_else(|| io::Error::new(io::ErrorKind::UnexpectedEof, format!("no block {id}")))?;
    if value.len() != buf.len() {
        return Err(io::Error::new(
            io::ErrorKind::InvalidData,
            format!("block {id} holds {} bytes, not {}", value.len(), buf.len()),
        ));
    }
    buf.copy_from_slice(value);
    Ok(())
}

fn read_only() -> io::Error {
    io::Error::new(io::ErrorKind::PermissionDenied, "a read transaction's table is read-only")
}

/// The blocks of a read snapshot: the application's read transaction's view.
pub(crate) struct SnapshotDevice {
    table: ReadOnlyTable<u32, &'static [u8]>,
    block_size: u32,
}

impl SnapshotDevice {
    pub(crate) fn new(table: ReadOnlyTable<u32, &'static [u8]>, block_size: u32) -> SnapshotDevice {
        SnapshotDevice { table, block_size }
    }
}

impl BlockDevice for SnapshotDevice {
    fn read_at(&self, offset: u64, buf: &mut [u8]) -> io::Result<()> {
        let id = block_id(offset, buf.len(), self.block_size)?;
        let value = self.table.get(id).map_err(io::Error::other)?;
        fill(id, value.as_ref().map(|v| v.value()), buf)
    }
    fn write_at(&self, _: u64, _: &[u8]) -> io::Result<()> {
        Err(read_only())
    }
    fn sync(&self) -> io::Result<()> {
        Err(read_only())
    }
    fn len(&self) -> io::Result<u64> {
        let last = self.table.last().map_err(io::Error::other)?;
        Ok(last.map_or(0, |(k, _)| u64::from(k.value()) + 1) * u64::from(self.block_size))
    }
    fn set_len(&self, _: u64) -> io::Result<()> {
        Err(read_only())
    }
    /// A read transaction's snapshot never changes.
    fn writes_are_atomic(&self) -> bool {
        true
    }
}

/// What the device asks of the thread holding a write transaction's table.
enum Request {
    Read(u32),
    Write(u32, Vec<u8>),
    Last,
    /// Removes the ranges' blocks, then writes the state record (if any).
    Commit {
        remove: Vec<(u32, u32)>,
        state: Option<Vec<u8>>,
    },
}

/// The thread's answer to a request.
type Answer = Result<Reply, redb::StorageError>;

enum Reply {
    Block(Option<Vec<u8>>),
    Last(Option<u32>),
    Done,
}

/// Runs `f` with a device over `table` (of a tree in `state`), served
/// from a scoped thread that holds the table until `f` has dropped every
/// clone of the device.
pub(crate) fn with_table<R>(
    table: Table<'_, u32, &'static [u8]>,
    state: &TableState,
    f: impl FnOnce(Arc<TableClient>) -> R,
) -> R {
    std::thread::scope(|scope| {
        let (requests, incoming) = mpsc::channel();
        let (answers, replies) = mpsc::channel();
        let server = scope.spawn(move || serve(table, incoming, answers));
        let out = f(Arc::new(TableClient::new(requests, replies, state)));
        match server.join() {
            Ok(()) => out,
            Err(panic) => std::panic::resume_unwind(panic),
        }
    })
}

/// Serves `requests` from `table` until the device that sends them is
/// dropped.
fn serve(mut table: Table<'_, u32, &'static [u8]>, requests: Receiver<Request>, replies: Sender<Answer>) {
    for request in requests {
        let reply = match request {
            Request::Read(id) => table.get(id).map(|v| Reply::Block(v.map(|v| v.value().to_vec()))),
            Request::Write(id, bytes) => table.insert(id, bytes.as_slice()).map(|_| Reply::Done),
            Request::Last => table.last().map(|e| Reply::Last(e.map(|(k, _)| k.value()))),
            Request::Commit { remove, state } => (|| {
                for (first, count) in remove {
                    for id in first..first + count {
                        table.remove(id)?;
                    }
                }
                if let Some(state) = state {
                    table.insert(STATE_KEY, state.as_slice())?;
                }
                Ok(Reply::Done)
            })(),
        };
        if replies.send(reply).is_err() {
            return;
        }
    }
}

/// The blocks of a write transaction's table, through the thread that holds
/// it; also the host that commits into it.
pub(crate) struct TableClient {
    channel: Mutex<(Sender<Request>, Receiver<Answer>)>,
    block_size: u32,
    lod_levels: u8,
}

impl TableClient {
    fn new(requests: Sender<Request>, replies: Receiver<Answer>, state: &TableState) -> TableClient {
        TableClient {
            channel: Mutex::new((requests, replies)),
            block_size: state.block_size,
            lod_levels: state.lod_levels,
        }
    }

    fn call(&self, request: Request) -> Result<Reply, io::Error> {
        let gone = || io::Error::new(io::ErrorKind::BrokenPipe, "the table's thread has ended");
        let channel = self.channel.lock().unwrap_or_else(|e| e.into_inner());
        channel.0.send(request).map_err(|_| gone())?;
        channel.1.recv().map_err(|_| gone())?.map_err(io::Error::other)
    }

    fn done(&self, request: Request) -> io::Result<()> {
        match self.call(request)? {
            Reply::Done => Ok(()),
            _ => Err(io::Error::other("the table's thread answered out of turn")),
        }
    }
}

impl BlockDevice for TableClient {
    fn read_at(&self, offset: u64, buf: &mut [u8]) -> io::Result<()> {
        let id = block_id(offset, buf.len(), self.block_size)?;
        match self.call(Request::Read(id))? {
            Reply::Block(value) => fill(id, value.as_deref(), buf),
            _ => Err(io::Error::other("the table's thread answered out of turn")),
        }
    }
    /// One or several consecutive whole blocks, each its own value.
    fn write_at(&self, offset: u64, data: &[u8]) -> io::Result<()> {
        let ids = block_ids(offset, data.len(), self.block_size)?;
        for (id, block) in ids.zip(data.chunks_exact(self.block_size as usize)) {
            self.done(Request::Write(id, block.to_vec()))?;
        }
        Ok(())
    }
    /// Nothing to make durable: the application's redb commit does.
    fn sync(&self) -> io::Result<()> {
        Ok(())
    }
    fn len(&self) -> io::Result<u64> {
        match self.call(Request::Last)? {
            Reply::Last(last) => Ok(last.map_or(0, |k| u64::from(k) + 1) * u64::from(self.block_size)),
            _ => Err(io::Error::other("the table's thread answered out of turn")),
        }
    }
    /// Blocks go by commits only (`Host`), never by cutting a length.
    fn set_len(&self, _: u64) -> io::Result<()> {
        Err(io::Error::new(io::ErrorKind::Unsupported, "a table's blocks are removed by commits"))
    }
}

impl Host for TableClient {
    fn commit(&self, c: &Commit, free: &[(u32, u32)], replaced: &[(u32, u32)]) -> Result<(), StorageError> {
        let state = TableState {
            block_size: self.block_size,
            lod_levels: self.lod_levels,
            txn: c.txn,
            meta_block: c.meta_block,
            meta_checksum: c.meta_checksum,
            block_count: c.block_count,
            free: free.to_vec(),
        };
        Ok(self.done(Request::Commit { remove: replaced.to_vec(), state: Some(state.encode()) })?)
    }
    fn discard(&self, written: &[(u32, u32)]) -> Result<(), StorageError> {
        Ok(self.done(Request::Commit { remove: written.to_vec(), state: None })?)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A table's access names whole blocks after the state record: one for
    /// a read, one or more for a write; anything else is refused.
    #[test]
    fn an_access_names_whole_blocks_past_the_state_record() {
        assert_eq!(block_ids(4 * 64, 3 * 64, 64).unwrap(), 4..7);
        assert_eq!(block_id(4 * 64, 64, 64).unwrap(), 4);
        assert!(block_id(4 * 64, 2 * 64, 64).is_err(), "a read is one block");
        for (offset, len) in [(4 * 64, 0), (4 * 64 + 1, 64), (4 * 64, 65), (0, 64), (0, 2 * 64)] {
            assert!(block_ids(offset, len, 64).is_err(), "{len} bytes at {offset}");
        }
    }
}
