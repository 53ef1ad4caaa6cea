//! Queries through the paged file. Each returns its answer and the blocks it
//! read, counted by the pager where the reads happen.

mod bench_workload;
mod region;
mod workload;

pub use bench_workload::{
    COLLISION_MARGIN_MM, QueryKind, TreeQueryCount, collision_boxes, count_in_tree, random_cubes,
};
pub use region::{BoxQuery, QueryStats, brute_force_box, query_box};
pub use workload::{WorkloadStats, random_boxes, run_boxes};
