//! Locks between processes that share one file (format-spec/commit.md,
//! "Many processes"). They are byte-range locks far past any block, so they
//! never touch data: one byte a writer holds exclusively, and one byte per
//! transaction id, which a process reading that transaction's state holds
//! shared. `check` is a reader like any other and never blocks a writer;
//! mktree before issue 39 held the writer's byte shared while checking,
//! so a shared holder of it is reported as such a checker. A writer finds the
//! oldest state another process still reads and leaves the blocks that
//! state may reach alone.
//!
//! The platform's byte-range locks do the work: `fcntl` on Unix
//! (`unix.rs`), `LockFileEx` on Windows (`windows.rs`).

#![allow(unsafe_code)]

#[cfg(unix)]
mod unix;
#[cfg(unix)]
use unix as sys;
#[cfg(windows)]
mod windows;
#[cfg(windows)]
use windows as sys;

use std::fs::File;
use std::io;

use crate::store::format::header::MAX_TXN;

/// The writer's byte: 2^62, past any file of 2^32 blocks of 4 MiB.
const WRITER: u64 = 1 << 62;
/// Transaction `t`'s reader byte is `READERS + t`.
const READERS: u64 = WRITER + 1;

/// The kind of a lock.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Shared,
    Exclusive,
    Unlock,
}

/// Who holds the writer's byte.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Holder {
    /// A write transaction (or a file being created).
    Writer,
    /// A `check` of an mktree from before issue 39, which held the byte shared.
    OldChecker,
}

/// The locks of one open file.
#[derive(Debug)]
pub struct FileLocks {
    file: File,
}

impl FileLocks {
    /// Locks through `file` (a handle of the open file the device reads).
    pub fn new(file: File) -> FileLocks {
        FileLocks { file }
    }

    fn set(&self, kind: Kind, start: u64, wait: bool) -> io::Result<bool> {
        sys::set(&self.file, kind, start, wait)
    }

    fn taken(&self, start: u64, len: u64) -> io::Result<bool> {
        sys::taken(&self.file, start, len)
    }

    /// Takes the writer's byte exclusively: `Ok(false)` when another writer
    /// (or a checker) holds it and `wait` is false.
    pub fn lock_writer(&self, wait: bool) -> io::Result<bool> {
        self.set(Kind::Exclusive, WRITER, wait)
    }

    /// Who holds the writer's byte in another owner, if anyone: the
    /// role a "locked" error names.
    pub fn writer_holder(&self) -> io::Result<Option<Holder>> {
        Ok(sys::holder(&self.file, WRITER, 1)?.map(|k| match k {
            Kind::Shared => Holder::OldChecker,
            _ => Holder::Writer,
        }))
    }

    /// Releases the writer's byte.
    pub fn unlock_writer(&self) -> io::Result<()> {
        self.set(Kind::Unlock, WRITER, false).map(drop)
    }

    /// Marks the state of transaction `txn` as read by this owner.
    pub fn pin(&self, txn: u64) -> io::Result<()> {
        self.set(Kind::Shared, READERS + txn, true).map(drop)
    }

    /// Ends [`pin`](Self::pin).
    pub fn unpin(&self, txn: u64) -> io::Result<()> {
        self.set(Kind::Unlock, READERS + txn, false).map(drop)
    }

    /// Whether another owner reads the state of a transaction in `lo .. hi`.
    pub fn pinned_between(&self, lo: u64, hi: u64) -> io::Result<bool> {
        let (lo, hi) = (lo.min(MAX_TXN), hi.min(MAX_TXN));
        Ok(hi > lo && self.taken(READERS + lo, hi - lo)?)
    }

    /// The oldest transaction below `below` whose state another owner reads.
    pub fn oldest_pin(&self, below: u64) -> io::Result<Option<u64>> {
        let below = below.min(MAX_TXN);
        let (mut lo, mut hi) = (0, below);
        if hi == 0 || !self.taken(READERS, hi)? {
            return Ok(None);
        }
        // Invariant: a pin lies in lo .. hi. The kernel reports some
        // conflicting lock, not the lowest, so halve the range.
        while hi - lo > 1 {
            let mid = lo + (hi - lo) / 2;
            if self.taken(READERS + lo, mid - lo)? {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        Ok(Some(lo))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two opens of one file: separate owners with open-file locks (Linux)
    /// and handle locks (Windows), not with POSIX process locks.
    #[cfg(any(target_os = "linux", target_os = "android", windows))]
    fn two_owners() -> (tempfile::NamedTempFile, FileLocks, FileLocks) {
        let f = tempfile::NamedTempFile::new().unwrap();
        let open =
            || FileLocks::new(std::fs::OpenOptions::new().read(true).write(true).open(f.path()).unwrap());
        let (a, b) = (open(), open());
        (f, a, b)
    }

    #[cfg(any(target_os = "linux", target_os = "android", windows))]
    #[test]
    fn writers_exclude_each_other_and_the_holder_is_named() {
        let (_f, a, b) = two_owners();
        assert_eq!(b.writer_holder().unwrap(), None);
        assert!(a.lock_writer(false).unwrap());
        assert!(!b.lock_writer(false).unwrap(), "a second writer is refused");
        assert_eq!(b.writer_holder().unwrap(), Some(Holder::Writer));
        a.unlock_writer().unwrap();
        assert!(b.lock_writer(false).unwrap());
        b.unlock_writer().unwrap();
        // What a checker before issue 39 held.
        assert!(a.set(Kind::Shared, WRITER, false).unwrap());
        assert!(!b.lock_writer(false).unwrap());
        assert_eq!(b.writer_holder().unwrap(), Some(Holder::OldChecker));
    }

    // Windows counts a range its own handle holds as taken.
    #[cfg(any(target_os = "linux", target_os = "android"))]
    #[test]
    fn a_writer_finds_the_oldest_pin_of_another_owner() {
        let (_f, a, b) = two_owners();
        assert_eq!(a.oldest_pin(100).unwrap(), None);
        b.pin(70).unwrap();
        b.pin(12).unwrap();
        b.pin(90).unwrap();
        assert_eq!(a.oldest_pin(100).unwrap(), Some(12));
        assert_eq!(a.oldest_pin(12).unwrap(), None, "only pins below the bound count");
        assert_eq!(b.oldest_pin(100).unwrap(), None, "an owner's own pins are not another's");
        b.unpin(12).unwrap();
        assert_eq!(a.oldest_pin(100).unwrap(), Some(70));
        assert_eq!(a.oldest_pin(u64::MAX).unwrap(), Some(70));
    }
}
