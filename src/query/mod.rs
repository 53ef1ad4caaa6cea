//! Queries through the paged file. Each returns its answer and the blocks it
//! read, counted by the pager where the reads happen.

mod region;
mod workload;

pub use region::{BoxQuery, QueryStats, brute_force_box, query_box};
pub use workload::{WorkloadStats, random_boxes, run_boxes};
