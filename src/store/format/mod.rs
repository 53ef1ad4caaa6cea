//! The on-disk format, version 10: one file per structure of `format-spec/`.
//! Records are zerocopy structs with unaligned little-endian fields; sizes are
//! checked at compile time and offsets in `tests/format_spec.rs`.

pub mod blob;
pub mod change_log;
pub mod frame;
pub mod freelist;
pub mod geometry;
pub mod group;
pub mod header;
pub mod keys;
pub mod meta;
pub mod node;
pub mod quant;
#[cfg(feature = "redb")]
pub mod table;
#[cfg(test)]
mod spec_tests;

#[cfg(not(target_endian = "little"))]
compile_error!("geometry arrays are cast with bytemuck and assume a little-endian target");

/// The format version this build writes and reads (format-spec/versions.md).
pub const FORMAT_VERSION: u32 = 10;
/// Smallest block size (format-spec/README.md).
pub const MIN_BLOCK_SIZE: u32 = 1024;
/// Largest block size.
pub const MAX_BLOCK_SIZE: u32 = 4 * 1024 * 1024;
/// The block size a file is created with unless told otherwise (the
/// README's measurements), and the one `BuildParams::default` cuts leaves for.
pub const DEFAULT_BLOCK_SIZE: u32 = 16 * 1024;
/// Most levels of detail a file can carry.
pub const MAX_LOD_LEVELS: u8 = 16;

/// Checks a block size against format-spec/README.md.
pub fn validate_block_size(size: u64) -> Result<u32, crate::store::StorageError> {
    match u32::try_from(size) {
        Ok(s) if (MIN_BLOCK_SIZE..=MAX_BLOCK_SIZE).contains(&s) && s % 16 == 0 => Ok(s),
        _ => Err(crate::store::StorageError::InvalidBlockSize(size)),
    }
}

/// Checks a number of levels of detail.
pub fn validate_lod_levels(m: u64) -> Result<u8, crate::store::StorageError> {
    match u8::try_from(m) {
        Ok(m) if (1..=MAX_LOD_LEVELS).contains(&m) => Ok(m),
        _ => Err(crate::store::StorageError::InvalidLodLevels(m)),
    }
}

/// True when every byte is zero (reserved fields).
pub(crate) fn all_zero(bytes: &[u8]) -> bool {
    bytes.iter().all(|&b| b == 0)
}
