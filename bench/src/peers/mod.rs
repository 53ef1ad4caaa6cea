//! The peers: mktree, SQLite's R*Tree with geometry blobs, and rstar.

pub mod sqlite;
