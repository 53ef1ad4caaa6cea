//! The block device: every byte of an `.mkt` file goes through [`BlockDevice`],
//! so tests can count, fail or crash it, and another backend (a redb table, an
//! object store) can be added without touching the tree.

mod counting;
#[cfg(any(test, feature = "internals"))]
mod crash;
#[cfg(feature = "object-store")]
mod disk_cache;
#[cfg(any(test, feature = "internals"))]
mod fault;
mod file;
mod mem;
#[cfg(feature = "object-store")]
mod object;
#[cfg(feature = "object-store")]
mod upload;

use std::io;
use std::ops::Range;

#[cfg(feature = "redb")]
pub(crate) use counting::Counters;
pub use counting::{CountingDevice, DeviceCounts};
#[cfg(any(test, feature = "internals"))]
pub use crash::{CrashDevice, CrashImage};
#[cfg(feature = "object-store")]
pub use disk_cache::DiskCacheOptions;
#[cfg(any(test, feature = "internals"))]
pub use fault::{FaultDevice, FaultOp};
pub use file::FileDevice;
pub use mem::MemDevice;
#[cfg(feature = "object-store")]
pub(crate) use object::{Changed, Failed};
#[cfg(feature = "object-store")]
pub use object::{ObjectStoreDevice, RemoteOptions};
#[cfg(feature = "object-store")]
pub use upload::Published;
#[cfg(feature = "object-store")]
pub(crate) use upload::upload;

/// What a device that fetches over a network has fetched since it opened.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct TransferCounts {
    /// Range requests made.
    pub requests: u64,
    /// Bytes received.
    pub bytes: u64,
    /// Waits for the network: requests made together count once.
    pub round_trips: u64,
}

impl TransferCounts {
    /// What was fetched between `before` and these counts (of one device,
    /// taken later).
    pub fn since(&self, before: &TransferCounts) -> TransferCounts {
        TransferCounts {
            requests: self.requests.saturating_sub(before.requests),
            bytes: self.bytes.saturating_sub(before.bytes),
            round_trips: self.round_trips.saturating_sub(before.round_trips),
        }
    }
}

/// True when `name` reads as a URL `ObjectStoreDevice` opens (feature
/// `object-store`) rather than a path:
/// `s3://`, `s3a://`, `gs://`, `az://`, `abfs://`, `abfss://`, `azure://`,
/// `adl://`, `http://`, `https://` or `file://`.
pub fn is_remote_url(name: &str) -> bool {
    const SCHEMES: [&str; 11] = [
        "s3://", "s3a://", "gs://", "az://", "abfs://", "abfss://", "azure://", "adl://", "http://",
        "https://", "file://",
    ];
    SCHEMES
        .iter()
        .any(|s| name.len() > s.len() && name.get(..s.len()).is_some_and(|p| p.eq_ignore_ascii_case(s)))
}

/// Positioned byte storage with a durability barrier. The pager only ever
/// reads and writes whole blocks (and the header's slots): it reads one
/// block at a time and writes one or several consecutive ones (a bulk
/// load's geometry in runs); implementations need not know the block size.
pub trait BlockDevice: Send + Sync {
    /// Fills `buf` from `offset`; reading past the end is `UnexpectedEof`.
    fn read_at(&self, offset: u64, buf: &mut [u8]) -> io::Result<()>;
    /// Writes `data` at `offset`, growing the device if needed.
    fn write_at(&self, offset: u64, data: &[u8]) -> io::Result<()>;
    /// Makes every write so far durable.
    fn sync(&self) -> io::Result<()>;
    /// Current length in bytes.
    fn len(&self) -> io::Result<u64>;
    /// Truncates or extends (with zeros) to `len` bytes.
    fn set_len(&self, len: u64) -> io::Result<()>;
    /// True when the device has no bytes.
    fn is_empty(&self) -> io::Result<bool> {
        Ok(self.len()? == 0)
    }
    /// True when no reader can see part of a write: the device lives in one
    /// process and writes under a lock. A header slot failing its checksum is
    /// then damage, never a write in progress, and is not read again after a
    /// pause. A file another process may write to says false.
    fn writes_are_atomic(&self) -> bool {
        false
    }
    /// What the device has fetched over a network, for a device that does
    /// (an object store); `None` for local storage.
    fn transfer_counts(&self) -> Option<TransferCounts> {
        None
    }
    /// A hint that the byte ranges `spans` will be read soon: a device that
    /// fetches over a network fetches them together, in one round trip, and
    /// returns true when it holds them all (reading them again costs no
    /// request). A failure is left for the read that follows to report.
    fn fetch_ahead(&self, spans: &[Range<u64>]) -> bool {
        let _ = spans;
        false
    }
    /// The bytes of `span` failed to verify: a device that keeps what it
    /// fetched drops them, so that the next read fetches them again.
    fn forget(&self, span: Range<u64>) {
        let _ = span;
    }
}

impl<D: BlockDevice + ?Sized> BlockDevice for std::sync::Arc<D> {
    fn read_at(&self, offset: u64, buf: &mut [u8]) -> io::Result<()> {
        (**self).read_at(offset, buf)
    }
    fn write_at(&self, offset: u64, data: &[u8]) -> io::Result<()> {
        (**self).write_at(offset, data)
    }
    fn sync(&self) -> io::Result<()> {
        (**self).sync()
    }
    fn len(&self) -> io::Result<u64> {
        (**self).len()
    }
    fn set_len(&self, len: u64) -> io::Result<()> {
        (**self).set_len(len)
    }
    fn writes_are_atomic(&self) -> bool {
        (**self).writes_are_atomic()
    }
    fn transfer_counts(&self) -> Option<TransferCounts> {
        (**self).transfer_counts()
    }
    fn fetch_ahead(&self, spans: &[Range<u64>]) -> bool {
        (**self).fetch_ahead(spans)
    }
    fn forget(&self, span: Range<u64>) {
        (**self).forget(span)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn urls_are_told_from_paths() {
        assert!(is_remote_url("s3://bucket/ship.mkt"));
        assert!(is_remote_url("HTTPS://cdn.example.com/ship.mkt"));
        assert!(!is_remote_url("ship.mkt"));
        assert!(!is_remote_url("s3://"));
        // A name whose bytes at a scheme's length cut a character.
        assert!(!is_remote_url("données.mkt"));
    }
}
