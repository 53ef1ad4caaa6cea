//! Why a catalog could not be read, written, opened or queried.

use crate::query::QueryError;
use crate::store::StorageError;

/// An error of a catalog or of a query over one. A variant with a `source`
/// says which model or file; the source says what went wrong.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CatalogError {
    /// The catalog's file could not be read or written.
    #[error("catalog {path}")]
    Io {
        /// The catalog's path.
        path: String,
        /// The cause.
        source: std::io::Error,
    },
    /// A document that is not a catalog of this version, or whose entries
    /// break its rules (format-spec/catalog.md).
    #[error("catalog: {0}")]
    Invalid(String),
    /// A model's file could not be opened or read.
    #[error("model {model:?} ({location})")]
    Model {
        /// The model's key.
        model: String,
        /// Where its file lies.
        location: String,
        /// The cause.
        source: Box<StorageError>,
    },
    /// The query's region is not one (a non-finite or inverted shape).
    #[error(transparent)]
    Region(Box<QueryError>),
    /// A model's query failed.
    #[error("model {model:?}")]
    Query {
        /// The model's key.
        model: String,
        /// The cause.
        source: Box<QueryError>,
    },
    /// A model's file has moved on from the commit the catalog describes:
    /// its root box may have changed, so the catalog must be described anew.
    #[error(
        "model {model:?} is at commit {file}, but the catalog describes commit {catalog}: describe the catalog anew"
    )]
    Stale {
        /// The model's key.
        model: String,
        /// The commit the catalog describes.
        catalog: u64,
        /// The commit the file holds.
        file: u64,
    },
    /// A model's file at the catalog's commit holds another tree than its
    /// entry says (another file at that location, or an edited catalog).
    #[error("model {model:?} at commit {commit} does not match its entry: {detail}")]
    Mismatch {
        /// The model's key.
        model: String,
        /// The commit both name.
        commit: u64,
        /// What differs.
        detail: String,
    },
    /// A model index past the catalog's models.
    #[error("no model {index} in a catalog of {models}")]
    NoModel {
        /// The index asked for.
        index: usize,
        /// The catalog's models.
        models: usize,
    },
    /// A URL in a library built without the `object-store` feature.
    #[error(
        "model {model:?}: {location} is a URL, and this build reads URLs only with the object-store feature"
    )]
    NoRemote {
        /// The model's key.
        model: String,
        /// Its URL.
        location: String,
    },
}
