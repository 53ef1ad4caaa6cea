//! The stored tree as a reader sees it: a snapshot of one commit
//! ([`ReadTransaction`]), its verified, counted block reads, the node
//! records and exact objects they hold, and what the meta block says of
//! the levels of detail and group bounds (format-spec/node.md, geometry.md,
//! group.md, meta.md).
//!
//! Everything here speaks `StorageError`: only the file can fail a read.
//! `db` opens and ends snapshots and owns the commit protocol; `query`
//! runs its traversal over the reads here. Neither is named below.

pub(crate) mod codes;
mod group;
mod levels;
mod read;

pub use levels::LodInfo;
pub(crate) use read::{Owner, Snapshot, view};
pub use read::{ReadTransaction, TreeInfo};
internal_use!(read::{NodeRef, Reads});
internal_use!(codes::{method_from_code, method_to_code});
