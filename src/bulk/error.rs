//! `BuildError`: why a build (or a hierarchy's validation) refused its
//! options or its input.
//!
//! Rule 5 of the style guide wants every error family to hold a
//! `Storage(StorageError)`; building is in-memory and the storage layer does
//! not exist yet, so there is no such variant until a build reads from it.

use crate::geom::Axis;
use crate::scene::ObjectId;

/// Why [`build`](super::build) refused to start.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum BuildError {
    /// `rate` (R) is not a number in [0, 0.5].
    #[error("rate R = {rate} is outside [0, 0.5]")]
    RateOutOfRange {
        /// The rejected rate.
        rate: f64,
    },
    /// The leaf rule allows no object (`mem_page` = 0) or no byte.
    #[error("the leaf capacity is zero")]
    ZeroCapacity,
    /// A node whose record, with the bounds chosen for it, does not fit a
    /// node block (format-spec/node.md): larger blocks, or fewer objects
    /// per leaf, hold it.
    #[error("node {node}'s record with its bounds takes {len} bytes and a node block holds {capacity}")]
    NodeTooLarge {
        /// The node's id.
        node: usize,
        /// The record's length, bytes.
        len: usize,
        /// What a node block holds, bytes.
        capacity: usize,
    },
    /// No object boxes were given.
    #[error("there are no objects to build from")]
    EmptyInput,
    /// More objects than node ids can number (two nodes per object).
    #[error("{objects} objects: more than the {max} a hierarchy can index")]
    TooManyObjects {
        /// Objects given.
        objects: usize,
        /// The most a build accepts.
        max: usize,
    },
    /// A box has a NaN or infinite coordinate.
    #[error("object {object} has a non-finite box coordinate")]
    NonFiniteBox {
        /// The object.
        object: ObjectId,
    },
    /// An object's coordinate is beyond the range a file holds (see
    /// [`check_range`](super::check_range)).
    #[error("object {object}: {axis} = {coordinate:e} mm is beyond the range of ±{limit} mm a file holds")]
    OutOfRange {
        /// The object.
        object: ObjectId,
        /// The axis.
        axis: Axis,
        /// The coordinate of its anchor or of a vertex.
        coordinate: f64,
        /// The range's bound, mm.
        limit: f64,
    },
    /// A box has min > max on some axis (the empty box included).
    #[error("object {object} has an inverted box (min > max on some axis)")]
    InvertedBox {
        /// The object.
        object: ObjectId,
    },
    /// `sizes` does not have one entry per box.
    #[error("{sizes} object sizes were given for {boxes} boxes")]
    SizesMismatch {
        /// Boxes given.
        boxes: usize,
        /// Sizes given.
        sizes: usize,
    },
    /// A fixed query extent with a negative or non-finite side.
    #[error("the query extent {query_extent:?} needs three finite sides >= 0 mm")]
    BadQueryExtent {
        /// The rejected sides.
        query_extent: [f64; 3],
    },
    /// `LeafRule::Bytes` was asked for without the objects' byte sizes.
    #[error("the byte leaf rule needs every object's size in bytes")]
    MissingSizes,
}
