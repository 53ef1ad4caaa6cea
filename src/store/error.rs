//! Errors of the storage layer.

use std::io;

/// Anything that can go wrong reading or writing an `.mkt` file.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum StorageError {
    /// Reading, writing or syncing the file failed.
    #[error("I/O error")]
    Io(#[source] io::Error),
    /// An object store could not be reached, or refused the object (the
    /// URL, the store's settings or credentials, a missing object), or a
    /// request failed after its retries (a server error, a short answer).
    #[error("{url}: {detail}")]
    Remote {
        /// The URL.
        url: String,
        /// What the store said.
        detail: String,
    },
    /// The object a reader opened in an object store was replaced or
    /// removed after it was opened: its answers would mix two files.
    #[error("{url} changed after it was opened: open it again to read the new file")]
    ObjectChanged {
        /// The URL.
        url: String,
    },
    /// The file could not be opened or created (the reason is in the message,
    /// not a source, so that printing the error alone says why).
    #[error("cannot open {}: {error}", path.display())]
    Open {
        /// The file.
        path: std::path::PathBuf,
        /// Why it could not be opened or created.
        error: io::Error,
    },
    /// The spill file of a staged scene could not be created, written or read.
    #[error("spill file {}: {error}", path.display())]
    Spill {
        /// The spill file.
        path: std::path::PathBuf,
        /// What went wrong.
        error: io::Error,
    },
    /// The file does not start with the mktree magic number.
    #[error("not an MKtree file (bad magic number)")]
    NotMktree,
    /// The file is of a format version this build does not read.
    #[error("unsupported format version {found} (this build reads version {supported})")]
    UnsupportedVersion {
        /// The version the file states.
        found: u32,
        /// The version this build reads.
        supported: u32,
    },
    /// A block size that is not a multiple of 16 in 1,024 ..= 4,194,304 bytes.
    #[error("invalid block size {0}: it must be a multiple of 16 from 1024 to 4194304 bytes")]
    InvalidBlockSize(u64),
    /// A number of levels of detail outside 1 ..= 16.
    #[error("invalid number of levels of detail {0}: it must be 1 to 16")]
    InvalidLodLevels(u64),
    /// The file is shorter than its header, or ends before a block it needs.
    #[error("file is truncated: {detail}")]
    Truncated {
        /// What is missing.
        detail: String,
    },
    /// A checksum or structural rule failed; names the block, the record (if any) and the field.
    #[error("corrupt file: block {block}{}: {field}: {detail}", record.map(|r| format!(", record {r}")).unwrap_or_default())]
    Corruption {
        /// The block.
        block: u32,
        /// The record, if the fault is in one: its index in the block when
        /// the block is validated, its byte offset when a relocation reads it.
        record: Option<u32>,
        /// The field, as format-spec/ names it.
        field: &'static str,
        /// What is wrong.
        detail: String,
    },
    /// Another process holds the writer's lock: it is writing the file.
    #[error("another process is writing the file: try again when it ends, or wait for it (--wait)")]
    Locked,
    /// Another process holds the writer's lock shared: a `check` of an
    /// mktree from before issue 39 (today's `check` never blocks writers).
    #[error(
        "a check by an older mktree in another process keeps writers out: try again when it ends, or wait for it (--wait)"
    )]
    LockedByCheck,
    /// A write on a file opened read-only.
    #[error("the file was opened read-only")]
    ReadOnly,
    /// A write would make the file longer than 2^32 blocks.
    #[error("the file would exceed 2^32 blocks")]
    FileTooLarge,
    /// A path that names a directory, a device or anything but a regular file.
    #[error("{path}: not a regular file")]
    NotAFile {
        /// The path.
        path: std::path::PathBuf,
    },
    /// A create on a device (a file, an application's table) that already
    /// holds bytes.
    #[error("create needs an empty device")]
    NotEmpty,
    /// Other processes committed so fast that no snapshot held still
    /// through `attempts` tries to pin one.
    #[error("no snapshot held still through {attempts} commits by other processes")]
    Contended {
        /// The tries.
        attempts: u32,
    },
    /// A file whose contents contradict each other, or that this version
    /// cannot hold (ids or counts exhausted).
    #[error("{0}")]
    Invalid(String),
    /// The application's redb database failed (the `redb` feature).
    #[cfg(feature = "redb")]
    #[error("redb: {0}")]
    Redb(#[from] redb::Error),
}

impl StorageError {
    /// A corruption in `block`'s `field`.
    pub(crate) fn corrupt(block: u32, field: &'static str, detail: impl Into<String>) -> StorageError {
        StorageError::Corruption { block, record: None, field, detail: detail.into() }
    }

    /// A corruption in record `record` of `block`.
    pub(crate) fn corrupt_record(
        block: u32,
        record: u32,
        field: &'static str,
        detail: impl Into<String>,
    ) -> StorageError {
        StorageError::Corruption { block, record: Some(record), field, detail: detail.into() }
    }

    /// True for errors that mean the file's bytes are damaged (not I/O or usage errors).
    pub fn is_corruption(&self) -> bool {
        matches!(
            self,
            StorageError::Corruption { .. }
                | StorageError::Truncated { .. }
                | StorageError::NotMktree
                | StorageError::InvalidBlockSize(_)
                | StorageError::InvalidLodLevels(_)
        )
    }
}

impl From<io::Error> for StorageError {
    fn from(e: io::Error) -> Self {
        #[cfg(feature = "object-store")]
        {
            use super::device::{Changed, Failed};
            if let Some(changed) = e.get_ref().and_then(|inner| inner.downcast_ref::<Changed>()) {
                return StorageError::ObjectChanged { url: changed.url.clone() };
            }
            if let Some(failed) = e.get_ref().and_then(|inner| inner.downcast_ref::<Failed>()) {
                return StorageError::Remote { url: failed.url.clone(), detail: failed.detail.clone() };
            }
        }
        StorageError::Io(e)
    }
}
