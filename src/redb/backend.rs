//! What redb reads underneath: a storage backend that counts the calls
//! reaching the one it wraps. A query's block reads are mktree's count
//! (the pager's); what they cost redb in pages its cache lacked is this
//! one's, for the whole database.

use std::ops::Bound;
use std::sync::Arc;

use redb::{BackendError, StorageBackend};

use crate::store::device::{Counters, DeviceCounts};

/// Wraps an application's redb storage backend
/// (`redb::Builder::create_with_backend`) and counts reads, writes and
/// syncs, with their bytes; locks pass through.
///
/// ```
/// use mktree::redb::CountingBackend;
/// let backend = CountingBackend::new(redb::backends::InMemoryBackend::new());
/// let counter = backend.counter();
/// let db = redb::Builder::new().create_with_backend(backend)?;
/// assert!(counter.get().writes > 0, "creating a database writes its header");
/// # drop(db);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug)]
pub struct CountingBackend<B> {
    inner: B,
    counters: Arc<Counters>,
}

/// The counts of a [`CountingBackend`], readable after redb took it.
#[derive(Debug, Clone)]
pub struct BackendCounter(Arc<Counters>);

impl BackendCounter {
    /// The counts so far.
    pub fn get(&self) -> DeviceCounts {
        self.0.get()
    }
}

impl<B: StorageBackend> CountingBackend<B> {
    /// Wraps `inner` with all counts at zero.
    pub fn new(inner: B) -> CountingBackend<B> {
        CountingBackend { inner, counters: Arc::default() }
    }

    /// A handle to the counts.
    pub fn counter(&self) -> BackendCounter {
        BackendCounter(self.counters.clone())
    }
}

impl<B: StorageBackend> StorageBackend for CountingBackend<B> {
    fn len(&self) -> Result<u64, std::io::Error> {
        self.inner.len()
    }
    fn read(&self, offset: u64, out: &mut [u8]) -> Result<(), std::io::Error> {
        self.counters.read(out.len());
        self.inner.read(offset, out)
    }
    fn set_len(&self, len: u64) -> Result<(), std::io::Error> {
        self.inner.set_len(len)
    }
    fn sync_data(&self) -> Result<(), std::io::Error> {
        self.counters.sync();
        self.inner.sync_data()
    }
    fn write(&self, offset: u64, data: &[u8]) -> Result<(), std::io::Error> {
        self.counters.write(data.len());
        self.inner.write(offset, data)
    }
    fn close(&self) -> Result<(), std::io::Error> {
        self.inner.close()
    }
    fn try_lock_range(&self, start: Bound<u64>, end: Bound<u64>) -> Result<bool, BackendError> {
        self.inner.try_lock_range(start, end)
    }
    fn try_lock_shared_range(&self, start: Bound<u64>, end: Bound<u64>) -> Result<bool, BackendError> {
        self.inner.try_lock_shared_range(start, end)
    }
    fn lock_range(&self, start: Bound<u64>, end: Bound<u64>) -> Result<(), BackendError> {
        self.inner.lock_range(start, end)
    }
    fn lock_shared_range(&self, start: Bound<u64>, end: Bound<u64>) -> Result<(), BackendError> {
        self.inner.lock_shared_range(start, end)
    }
    fn unlock_range(&self, start: Bound<u64>, end: Bound<u64>) -> Result<(), BackendError> {
        self.inner.unlock_range(start, end)
    }
    fn query_lock_range(&self, start: Bound<u64>, end: Bound<u64>) -> Result<bool, BackendError> {
        self.inner.query_lock_range(start, end)
    }
}
