//! Block storage: the device trait, the on-disk format, the pager that reads
//! and counts blocks, the writer that lays a tree out in blocks, and `check`.
//! The format is specified in `format-spec/`.

pub mod alloc;
pub mod device;
mod error;
pub mod format;
pub mod layout;
pub mod pager;

pub use device::BlockDevice;
pub use error::StorageError;
pub use pager::{BlockCache, Pager, ReadStats};
