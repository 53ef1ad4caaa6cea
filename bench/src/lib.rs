//! # mktree-bench
//!
//! Benchmark scaffolding for mktree, kept out of the engine's public API:
//! the query workloads of `mktree bench-build` and `mktree bench-queries`
//! (random boxes, cubes and collision boxes from a seed, and the leaves a
//! box query reaches in a tree held in memory), every bulk loader compared
//! on them (`mktree bench-build`), a file's answers against a scan of its
//! scene (`mktree verify`), and the peer benchmark of
//! `mktree bench-peers`, the piecewise replacement of `mktree
//! bench-replace`, the change commits against SQLite of `mktree
//! bench-changes`, and the view query's sweep of `mktree bench-view`; what
//! the levels of detail decide in exact collision queries (`mktree demo`);
//! and, with the feature `object-store`, a file read at a URL through a
//! proxy that adds a round trip (`mktree bench-remote`).

#![deny(unsafe_code)]
#![deny(missing_docs)]

mod bench_peers;
mod changes;
mod error;
mod levels;
mod loaders;
pub mod peers;
mod proxy;
mod query_sets;
pub mod record;
#[cfg(feature = "redb")]
mod redb_backend;
#[cfg(feature = "object-store")]
mod remote;
mod replace;
mod rng;
pub mod stream;
mod verify;
mod view;
mod workload;

pub use bench_peers::{
    DEFAULT_QUERIES, PeerOptions, PeerRow, QuerySet, bench_scene, parse_query_file, standard_sets,
};
pub use changes::{ChangeOptions, ChangeRow, ChangesReport, bench_changes};
pub use error::BenchError;
pub use levels::{LevelsQuery, clearance_workload, collision_levels};
pub use loaders::{
    FileResult, LoaderBench, LoaderOptions, LoaderScene, MethodResult, SetResult, bench_loaders, leaf_rule,
};
pub use proxy::LatencyProxy;
pub use query_sets::{
    COLLISION_MARGIN_MM, QueryKind, TreeQueryCount, collision_boxes, count_in_tree, random_cubes,
};
#[cfg(feature = "redb")]
pub use redb_backend::{RedbRow, bench_redb, redb_table};
#[cfg(feature = "object-store")]
pub use remote::{
    Cache, DEFAULT_LATENCIES_MS, LocalSet, RemoteBench, RemoteBenchOptions, RemoteRow, Transfer, bench_remote,
};
pub use replace::{ReplaceOptions, ReplaceReport, ReplaceRow, bench_replace};
pub use verify::{Verification, verify_tree};
pub use view::{BudgetRow, TauRow, ViewBench, ViewBenchOptions, bench_view, flight, orbit, triangles, views};
pub use workload::{WorkloadStats, random_boxes, run_boxes};
