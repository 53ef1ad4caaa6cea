//! # mktree
//!
//! A persistent spatial index for very large 3D scenes, after the MKtree
//! (Multiresolution Kd-tree) of Franquesa-Niubó and Brunet: a binary
//! bounding-volume hierarchy bulk-loaded by minimum-overlap splits, with
//! levels of detail at every node, stored in a paged file whose reads are
//! counted exactly.
//!
//! Layers point down: `build` -> `scene` -> `geom`.

// The one exception is the byte-range locks of src/store/lock.rs (fcntl).
#![deny(unsafe_code)]

pub use error::Error;

pub mod build;
pub mod db;
mod error;
pub mod fuzzing;
pub mod geom;
pub mod lod;
pub mod query;
mod rng;
pub mod scene;
pub mod store;
