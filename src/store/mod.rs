//! Block storage: the device trait, the on-disk format, the pager that reads
//! and counts blocks, the shared cache of verified blocks, and the layout of
//! a tree in node blocks. The format is specified in `format-spec/`.

pub mod alloc;
pub mod cache;
pub mod device;
mod error;
pub mod format;
pub mod layout;
pub(crate) mod lock;
pub mod pager;

pub use cache::{Block, BlockCache};
pub use device::BlockDevice;
pub use error::StorageError;
pub use pager::{Pager, ReadStats};
