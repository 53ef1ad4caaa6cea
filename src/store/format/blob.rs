//! An inline voxel blob's head and forms (format-spec/lod.md, "Inline
//! voxel blobs"), what a node block's validation reads of a blob without
//! its grid. Encoding and decoding the cells is the levels of detail's
//! (`lod/compact.rs`).

use zerocopy::{FromBytes, Immutable, IntoBytes, KnownLayout, Unaligned};

/// Form: a bitmap of the grid's cells.
pub(crate) const FORM_BITMAP: u8 = 1;
/// Form: boxes of cells, 1-byte corners.
pub(crate) const FORM_BOXES8: u8 = 2;
/// Form: boxes of cells, 2-byte corners.
pub(crate) const FORM_BOXES16: u8 = 3;

/// A blob's head: the lattice level of its grid, and its form.
#[derive(Debug, Clone, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
#[repr(C)]
pub(crate) struct BlobHead {
    pub(crate) level: u8,
    pub(crate) form: u8,
}
/// Bytes of a blob's head.
pub const HEAD_LEN: usize = 2;
const _: () = assert!(size_of::<BlobHead>() == HEAD_LEN);

/// True when `blob`'s form says it sets no cell (a bitmap with no bit set,
/// or no box), read without its grid. A blob too short for its head, or of
/// an unknown form, is left to `lod::decode` to refuse.
pub(crate) fn sets_no_cell(blob: &[u8]) -> bool {
    match BlobHead::ref_from_prefix(blob) {
        Ok((head, payload)) => match head.form {
            FORM_BITMAP => payload.iter().all(|&b| b == 0),
            FORM_BOXES8 | FORM_BOXES16 => payload.is_empty(),
            _ => false,
        },
        Err(_) => false,
    }
}
