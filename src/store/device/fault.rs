//! A wrapper that fails one chosen operation with an I/O error, to test that
//! every read, write and sync failure becomes a typed error and the file
//! reopens cleanly.

use std::io;
use std::sync::atomic::{AtomicU64, Ordering};

use super::BlockDevice;

/// Which kind of operation to fail.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FaultOp {
    /// A read.
    Read,
    /// A write.
    Write,
    /// A sync.
    Sync,
}

/// Fails the `nth` (0-based) operation of kind `op`, and only that one.
#[derive(Debug)]
pub struct FaultDevice<D> {
    inner: D,
    op: FaultOp,
    nth: u64,
    seen: AtomicU64,
}

impl<D: BlockDevice> FaultDevice<D> {
    /// Wraps `inner`; the `nth` operation of kind `op` will fail.
    pub fn new(inner: D, op: FaultOp, nth: u64) -> FaultDevice<D> {
        FaultDevice { inner, op, nth, seen: AtomicU64::new(0) }
    }

    /// Operations of the chosen kind seen so far.
    pub fn seen(&self) -> u64 {
        self.seen.load(Ordering::Relaxed)
    }

    /// The wrapped device.
    pub fn inner(&self) -> &D {
        &self.inner
    }

    fn check(&self, op: FaultOp) -> io::Result<()> {
        if op == self.op && self.seen.fetch_add(1, Ordering::Relaxed) == self.nth {
            return Err(io::Error::other(format!("injected {op:?} fault")));
        }
        Ok(())
    }
}

impl<D: BlockDevice> BlockDevice for FaultDevice<D> {
    fn read_at(&self, offset: u64, buf: &mut [u8]) -> io::Result<()> {
        self.check(FaultOp::Read)?;
        self.inner.read_at(offset, buf)
    }
    fn write_at(&self, offset: u64, data: &[u8]) -> io::Result<()> {
        self.check(FaultOp::Write)?;
        self.inner.write_at(offset, data)
    }
    fn sync(&self) -> io::Result<()> {
        self.check(FaultOp::Sync)?;
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
}
