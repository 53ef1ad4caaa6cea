//! Queries through the paged file. Each returns its answer and the blocks it
//! read, counted by the pager where the reads happen. Every single-shape
//! query (region, collide, navigate, tradeoff) runs `traverse.rs`; clash
//! runs the tree against itself in `clash.rs` with the same tests.

mod bench_workload;
mod brute_force;
mod collide;
mod error;
mod region;
mod shape;
mod traverse;
mod workload;

pub use bench_workload::{
    COLLISION_MARGIN_MM, QueryKind, TreeQueryCount, collision_boxes, count_in_tree, random_cubes,
};
pub use brute_force::{brute_force_clash, brute_force_collide, brute_force_region};
pub use collide::{CollideOptions, collide, object_mesh};
pub use error::QueryError;
pub use region::{BoxQuery, QueryStats, brute_force_box, query_box, query_region};
pub use shape::{Region, Triangles};
pub use traverse::{ObjectLevel, QueryAnswer, QueryOptions, TraverseStats};
pub use workload::{WorkloadStats, random_boxes, run_boxes};
