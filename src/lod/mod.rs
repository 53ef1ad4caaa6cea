//! Voxel levels of detail (paper §1.4-1.5): k = 2 is the cuberille, a bitmap
//! over R(S_n); k >= 3 is the same conservative voxel solid, stored as
//! disjoint boxes and reported as a polyhedron (its boundary with coplanar
//! faces merged), the octree offset-surface family the paper cites (ABA01).
//!
//! Every grid sits on one global [`Lattice`], so levels nest: a grid at
//! lattice level j over R' ⊆ R refines the grid at level j' >= j over R.
//! Blob layout: `format-spec/lod.md`.

mod blob;
mod boxes;
mod closed;
mod error;
mod error_measure;
mod faces;

mod grid;
mod inside;
mod interior;
mod lattice;
mod levels;
mod voxelize;
mod voxels;

pub use blob::{Form, decode, decode_objects, encode, encode_objects, encoded_len};
pub use closed::is_closed;
pub use error::LodError;
pub use error_measure::{ErrorProbe, measured_error};

pub use grid::{Grid, MAX_CELLS, MAX_DIM};
pub use lattice::Lattice;
pub use levels::{Computed, Entry, LodParams, LodPlan, NodeEntries, compute};
pub use voxels::Voxels;
