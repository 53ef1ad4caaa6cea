//! Queries through the paged file. Each returns its answer and the blocks it
//! read, counted by the pager where the reads happen. Every single-shape
//! query (region, collide, navigate, tradeoff) runs `traverse.rs`; clash
//! runs the tree against itself in `clash.rs` with the same tests.

mod brute_force;
mod clash;
mod collide;
mod error;
mod navigate;
mod region;
mod shape;
mod tradeoff;
mod traverse;

pub use brute_force::{brute_force_clash, brute_force_collide, brute_force_region};
pub use clash::{ClashAnswer, ClashOptions, clash};
pub use collide::{CollideOptions, collide, object_mesh, object_meshes};
pub use error::QueryError;
pub use navigate::{NavigateStep, navigate, parse_path};
pub use region::{BoxQuery, QueryStats, brute_force_box, query_box, query_region};
pub use shape::{Region, Triangles};
pub use tradeoff::{TRADEOFF_SHIFT_MM, TradeoffRow, collision_workload, tradeoff};
pub use traverse::{ObjectLevel, QueryAnswer, QueryOptions, TraverseStats};
