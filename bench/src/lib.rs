//! # mktree-bench
//!
//! Benchmark scaffolding for mktree, kept out of the engine's public API:
//! the query workloads of `mktree bench-build` and `mktree bench-queries`
//! (random boxes, cubes and collision boxes from a seed, and the leaves a
//! box query reaches in a tree held in memory).

#![deny(unsafe_code)]
#![deny(missing_docs)]

mod query_sets;
mod rng;
mod workload;

pub use query_sets::{
    COLLISION_MARGIN_MM, QueryKind, TreeQueryCount, collision_boxes, count_in_tree, random_cubes,
};
pub use workload::{WorkloadStats, random_boxes, run_boxes};
