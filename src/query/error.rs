//! Why a query failed: the file, the query's numbers, or its inputs.

use crate::geom::ShapeError;
use crate::store::StorageError;

/// An error of a query (region, collide, clash, navigate, tradeoff).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum QueryError {
    #[error(transparent)]
    Storage(#[from] StorageError),
    #[error(transparent)]
    Shape(#[from] ShapeError),
    #[error("level {k} is not one of the file's levels 1..={m}")]
    Level { k: u8, m: u8 },
    #[error("the file holds no tree")]
    NoTree,
    #[error("object {id} is not in the file ({objects} objects)")]
    NoObject { id: u32, objects: u32 },
    #[error("clearance {0} is not a finite distance >= 0")]
    Clearance(f64),
    /// A coordinate the query states lies outside every file's coordinate
    /// range, [-2^53, 2^53] mm (format-spec/geometry.md).
    #[error(
        "{what}: coordinate {coordinate:e} lies outside the coordinate range [-2^53, 2^53] mm of every mktree file"
    )]
    OutOfRange { what: &'static str, coordinate: f64 },
    /// A length the query states is longer than [`MAX_LENGTH`](super::MAX_LENGTH).
    #[error("{what}: {length:e} mm is longer than 2^55 mm, past any file's coordinate range")]
    TooLong { what: &'static str, length: f64 },
    #[error("line {line}: {detail}")]
    Path { line: usize, detail: String },
    #[error("level {k} missed object {object} of query {query}: a bound lost containment")]
    Missed { k: u8, query: usize, object: u32 },
}

impl QueryError {
    /// True for errors that mean the file's bytes are damaged.
    pub fn is_corruption(&self) -> bool {
        matches!(self, QueryError::Storage(e) if e.is_corruption())
    }
}
