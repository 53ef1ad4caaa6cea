//! Why a query failed: the file, the query's numbers, or its inputs.

use crate::geom::ShapeError;
use crate::store::StorageError;

/// An error of a query (region, collide, clash, navigate, tradeoff).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum QueryError {
    /// The file could not be read, or its bytes are damaged.
    #[error(transparent)]
    Storage(#[from] StorageError),
    /// A shape the query states (a box, a ray, a mesh, a pose) is not valid.
    #[error(transparent)]
    Shape(#[from] ShapeError),
    /// Level `k` is not one of the file's levels of detail.
    #[error("level {k} is not one of the file's levels 1..={m}")]
    Level {
        /// The level asked for.
        k: u8,
        /// M, the file's number of levels.
        m: u8,
    },
    /// The file holds no tree (an empty database).
    #[error("the file holds no tree")]
    NoTree,
    /// An object id the file does not hold.
    #[error("object {id} is not in the file ({objects} objects)")]
    NoObject {
        /// The id asked for.
        id: u32,
        /// The number of objects the file holds.
        objects: u32,
    },
    /// A node id the tree does not hold (ids lie below `bound`; after a
    /// change commit split or merged a leaf, some below it are gone too).
    #[error("node {id} is not in the tree (its ids lie below {bound})")]
    NoNode {
        /// The id asked for.
        id: u32,
        /// The bound below which the tree's ids lie.
        bound: u32,
    },
    /// A clearance (mm) that is negative, NaN or infinite.
    #[error("clearance {0} is not a finite distance >= 0")]
    Clearance(f64),
    /// A coordinate the query states lies outside every file's coordinate
    /// range, [-2^53, 2^53] mm (format-spec/geometry.md).
    #[error(
        "{what}: coordinate {coordinate:e} lies outside the coordinate range [-2^53, 2^53] mm of every mktree file"
    )]
    OutOfRange {
        /// What the coordinate is (the query's input that holds it).
        what: &'static str,
        /// The coordinate, mm.
        coordinate: f64,
    },
    /// A length the query states is longer than [`MAX_LENGTH`](super::MAX_LENGTH).
    #[error("{what}: {length:e} mm is longer than 2^55 mm, past any file's coordinate range")]
    TooLong {
        /// What the length is.
        what: &'static str,
        /// The length, mm.
        length: f64,
    },
    /// A camera path's line that is not six finite numbers (`navigate::parse_path`).
    #[error("line {line}: {detail}")]
    Path {
        /// The 1-based line; 0 when the path has no camera at all.
        line: usize,
        /// What is wrong with it.
        detail: String,
    },
    /// A stored bound at level `k` lost an object the exact query finds: the
    /// tradeoff measurement's containment check failed.
    #[error("level {k} missed object {object} of query {query}: a bound lost containment")]
    Missed {
        /// The level.
        k: u8,
        /// The index of the query.
        query: usize,
        /// The object missed.
        object: u32,
    },
}

impl QueryError {
    /// True for errors that mean the file's bytes are damaged.
    pub fn is_corruption(&self) -> bool {
        matches!(self, QueryError::Storage(e) if e.is_corruption())
    }
}
