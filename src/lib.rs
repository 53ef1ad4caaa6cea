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

pub use build::{BuildParams, LeafRule, Method};
pub use db::{
    ChangeStats, CheckReport, Compaction, CreateOptions, Database, ReadTransaction, TreeInfo,
    WriteTransaction, check,
};
pub use error::Error;
pub use geom::{Aabb, Point, Ray, Vector};
pub use lod::LodParams;
pub use query::{
    Hit, Near, QueryAnswer, QueryOptions, RayHit, Region, Selection, View, ViewCut, ViewOptions,
};
pub use scene::{Key, KeyError, Mesh, Object, ObjectId, Scene};
pub use store::StorageError;

/// The README's examples run as doctests.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
struct ReadmeDoctests;

pub mod build;
pub mod db;
mod error;
#[cfg(any(test, feature = "internals"))]
pub mod fuzzing;
pub mod geom;
pub mod lod;
pub mod query;
#[cfg(feature = "redb")]
pub mod redb;
pub mod render;
mod rng;
pub mod scene;
mod spill;
pub mod store;
pub mod tiles;
