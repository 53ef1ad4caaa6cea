//! A wrapper that counts device operations, so tests can check that the block
//! reads a query reports are the reads the device saw.

use std::io;
use std::sync::atomic::{AtomicU64, Ordering};

use super::BlockDevice;

/// Operation counts of a [`CountingDevice`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct DeviceCounts {
    /// Read operations.
    pub reads: u64,
    /// Bytes read.
    pub bytes_read: u64,
    /// Write operations.
    pub writes: u64,
    /// Bytes written.
    pub bytes_written: u64,
    /// Syncs to stable storage.
    pub syncs: u64,
}

/// The counts as they grow, shared by the counting wrappers (this one, and
/// redb's storage backend in `src/redb/`).
#[derive(Debug, Default)]
pub(crate) struct Counters {
    reads: AtomicU64,
    bytes_read: AtomicU64,
    writes: AtomicU64,
    bytes_written: AtomicU64,
    syncs: AtomicU64,
}

impl Counters {
    pub(crate) fn read(&self, bytes: usize) {
        self.reads.fetch_add(1, Ordering::Relaxed);
        self.bytes_read.fetch_add(bytes as u64, Ordering::Relaxed);
    }

    pub(crate) fn write(&self, bytes: usize) {
        self.writes.fetch_add(1, Ordering::Relaxed);
        self.bytes_written.fetch_add(bytes as u64, Ordering::Relaxed);
    }

    pub(crate) fn sync(&self) {
        self.syncs.fetch_add(1, Ordering::Relaxed);
    }

    pub(crate) fn get(&self) -> DeviceCounts {
        DeviceCounts {
            reads: self.reads.load(Ordering::Relaxed),
            bytes_read: self.bytes_read.load(Ordering::Relaxed),
            writes: self.writes.load(Ordering::Relaxed),
            bytes_written: self.bytes_written.load(Ordering::Relaxed),
            syncs: self.syncs.load(Ordering::Relaxed),
        }
    }
}

/// Counts every call that reaches `inner`.
#[derive(Debug, Default)]
pub struct CountingDevice<D> {
    inner: D,
    counters: Counters,
}

impl<D: BlockDevice> CountingDevice<D> {
    /// Wraps `inner` with all counts at zero.
    pub fn new(inner: D) -> CountingDevice<D> {
        CountingDevice { inner, counters: Counters::default() }
    }

    /// The counts so far.
    pub fn counts(&self) -> DeviceCounts {
        self.counters.get()
    }

    /// The wrapped device.
    pub fn inner(&self) -> &D {
        &self.inner
    }
}

impl<D: BlockDevice> BlockDevice for CountingDevice<D> {
    fn read_at(&self, offset: u64, buf: &mut [u8]) -> io::Result<()> {
        self.counters.read(buf.len());
        self.inner.read_at(offset, buf)
    }
    fn write_at(&self, offset: u64, data: &[u8]) -> io::Result<()> {
        self.counters.write(data.len());
        self.inner.write_at(offset, data)
    }
    fn sync(&self) -> io::Result<()> {
        self.counters.sync();
        self.inner.sync()
    }
    fn len(&self) -> io::Result<u64> {
        self.inner.len()
    }
    fn set_len(&self, len: u64) -> io::Result<()> {
        self.inner.set_len(len)
    }
    fn writes_are_atomic(&self) -> bool {
        self.inner.writes_are_atomic()
    }
    fn transfer_counts(&self) -> Option<super::TransferCounts> {
        self.inner.transfer_counts()
    }
    fn fetch_ahead(&self, spans: &[std::ops::Range<u64>]) -> bool {
        self.inner.fetch_ahead(spans)
    }
    fn forget(&self, span: std::ops::Range<u64>) {
        self.inner.forget(span)
    }
}
