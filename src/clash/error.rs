//! Why a clash test, its status store or its BCF export failed.

use crate::query::QueryError;
use crate::store::StorageError;

/// An error of a clash test, a status store or an export.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ClashError {
    /// A query of the test failed.
    #[error(transparent)]
    Query(#[from] QueryError),
    /// The database file could not be read, or its contents are inconsistent.
    #[error(transparent)]
    Storage(#[from] StorageError),
    /// A selector that does not parse.
    #[error("selector {text:?}: {why}")]
    Selector {
        /// The selector as given.
        text: String,
        /// Why it does not parse.
        why: String,
    },
    /// A test's numbers or names out of range.
    #[error("clash test: {0}")]
    Test(String),
    /// A status store whose bytes are not a store of this version
    /// (format-spec/clash-store.md).
    #[error("clash store {path}: {why}")]
    Store {
        /// The store's path.
        path: String,
        /// What is wrong with its bytes.
        why: String,
    },
    /// Reading or writing a status store or an export.
    #[error("{path}: {source}")]
    Io {
        /// The file or folder.
        path: String,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// No test, or no recorded clash, of that name or keys.
    #[error("{0}")]
    NotFound(String),
}

impl ClashError {
    /// An I/O error on `path`.
    pub(crate) fn io(path: &std::path::Path, source: std::io::Error) -> ClashError {
        ClashError::Io { path: path.display().to_string(), source }
    }
}
