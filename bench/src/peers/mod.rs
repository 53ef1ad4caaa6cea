//! The peers: mktree (the one file that calls the engine's build and query
//! API), SQLite's R*Tree with geometry blobs, and rstar as a reference line.

pub mod mktree;
pub mod rstar;
pub mod sqlite;
