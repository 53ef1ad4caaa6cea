//! Block storage: the device trait, the on-disk format, the pager that reads
//! and counts blocks, the shared cache of verified blocks, and the layout of
//! a tree in node blocks. The format is specified in `format-spec/`.

/// Modules public only with the `internals` feature (fuzz targets, tests,
/// benches); an embedder sees the device trait, the cache and the errors.
macro_rules! internal_mods {
    ($($name:ident),*) => {$(
        #[cfg(feature = "internals")]
        pub mod $name;
        #[cfg(not(feature = "internals"))]
        pub(crate) mod $name;
    )*};
}

pub mod cache;
pub mod device;
mod error;
pub(crate) mod lock;
internal_mods!(alloc, format, layout, pager);

pub use cache::{Block, BlockCache};
pub use device::{BlockDevice, TransferCounts};
pub use error::StorageError;
internal_use!(pager::Pager);
pub use pager::ReadStats;
