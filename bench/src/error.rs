//! The bench's one error type: what failed in the engine, in SQLite, on
//! disk, in the inputs, in opening a file or URL, or a disagreement
//! between the peers' answers (or a URL's and the local file's).

use crate::record::RecordError;

/// An error of the peer benchmark.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum BenchError {
    /// The engine failed (build, storage or query).
    #[error(transparent)]
    Mktree(#[from] mktree::Error),
    /// SQLite failed.
    #[error("SQLite: {0}")]
    Sqlite(#[from] rusqlite::Error),
    /// A file or directory could not be made, read or removed.
    #[error("{what}: {source}")]
    Io {
        /// The file or directory and what was done to it.
        what: String,
        /// The cause.
        source: std::io::Error,
    },
    /// A geometry blob of the SQLite file is not an object record.
    #[error("geometry row {rank}: {source}")]
    Record {
        /// The row's rowid (the object's Hilbert rank).
        rank: u32,
        /// The rule it breaks.
        source: RecordError,
    },
    /// A file or URL could not be opened to read (missing, unreachable, not
    /// an MKtree file).
    #[error("opening {target}")]
    Open {
        /// The path or URL as named.
        target: String,
        /// Why.
        #[source]
        source: mktree::store::StorageError,
    },
    /// A URL the benchmark cannot read or route through its latency proxy.
    #[error("{url}: {reason}")]
    Url {
        /// The URL as named.
        url: String,
        /// What is wrong with it.
        reason: String,
    },
    /// The options or inputs cannot be measured as given.
    #[error("{0}")]
    Invalid(String),
    /// Two peers answered one query differently: a bug, never a number.
    #[error("{0}")]
    Mismatch(String),
}

impl From<mktree::store::StorageError> for BenchError {
    fn from(e: mktree::store::StorageError) -> BenchError {
        BenchError::Mktree(e.into())
    }
}

impl From<mktree::query::QueryError> for BenchError {
    fn from(e: mktree::query::QueryError) -> BenchError {
        BenchError::Mktree(e.into())
    }
}

/// `BenchError::Io` for `what`.
pub(crate) fn io(what: impl Into<String>) -> impl FnOnce(std::io::Error) -> BenchError {
    let what = what.into();
    move |source| BenchError::Io { what, source }
}
