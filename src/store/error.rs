//! Errors of the storage layer.

use std::io;

/// Anything that can go wrong reading or writing an `.mkt` file.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum StorageError {
    #[error("I/O error")]
    Io(#[from] io::Error),
    /// The file could not be opened or created (the reason is in the message,
    /// not a source, so that printing the error alone says why).
    #[error("cannot open {}: {error}", path.display())]
    Open { path: std::path::PathBuf, error: io::Error },
    /// The spill file of a staged scene could not be created, written or read.
    #[error("spill file {}: {error}", path.display())]
    Spill { path: std::path::PathBuf, error: io::Error },
    #[error("not an MKtree file (bad magic number)")]
    NotMktree,
    #[error("unsupported format version {found} (this build reads version {supported})")]
    UnsupportedVersion { found: u32, supported: u32 },
    #[error("invalid block size {0}: it must be a multiple of 16 from 1024 to 4194304 bytes")]
    InvalidBlockSize(u64),
    #[error("invalid number of levels of detail {0}: it must be 1 to 16")]
    InvalidLodLevels(u64),
    #[error("file is truncated: {detail}")]
    Truncated { detail: String },
    /// A checksum or structural rule failed; names the block, the record (if any) and the field.
    #[error("corrupt file: block {block}{}: {field}: {detail}", record.map(|r| format!(", record {r}")).unwrap_or_default())]
    Corruption { block: u32, record: Option<u32>, field: &'static str, detail: String },
    /// Another process holds the writer's lock: it is writing the file.
    #[error("another process is writing the file: try again when it ends, or wait for it (--wait)")]
    Locked,
    /// Another process holds the writer's lock shared: a `check` of an
    /// mktree from before issue 39 (today's `check` never blocks writers).
    #[error(
        "a check by an older mktree in another process keeps writers out: try again when it ends, or wait for it (--wait)"
    )]
    LockedByCheck,
    #[error("the file was opened read-only")]
    ReadOnly,
    #[error("the file would exceed 2^32 blocks")]
    FileTooLarge,
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
