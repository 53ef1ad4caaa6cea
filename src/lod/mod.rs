//! Levels of detail (paper §1.4-1.5): k = 2 is the cuberille, k >= 3 voxel
//! polyhedra at fixed lattice levels, built over objects' surfaces
//! (`voxelize.rs`), stored inline in node records as compact blobs
//! (`compact.rs`), and only where the query model says they pay
//! (`policy.rs`); and the group bounds b(S_n,k) of nodes, built bottom up
//! and stored in group blocks (`group.rs`).
//!
//! Every grid sits on one global [`Lattice`], so levels nest: a grid at
//! lattice level j over R' ⊆ R refines the grid at level j' >= j over R.
//! Blob layout: `format-spec/lod.md`.

mod boxes;
mod closed;
mod compact;
mod error;
mod error_measure;
mod faces;
mod grid;
mod group;
mod inside;
mod interior;
mod lattice;
mod plan;
mod policy;
mod voxelize;
mod voxels;

pub use closed::is_closed;
internal_use!(compact::{aligned_grid, decode, encode, encoded_len});
pub use error::LodError;
internal_use!(error_measure::ErrorProbe);
#[cfg(feature = "internals")]
pub use error_measure::measured_error;
pub use grid::{MAX_CELLS, MAX_DIM};
internal_use!(grid::Grid);
internal_use!(group::{GroupRule, LEVEL_FACTOR, leaf_group, lift_group});
pub use lattice::Lattice;
pub use plan::LodParams;
internal_use!(plan::LodPlan);
pub(crate) use policy::bound_grid;
internal_use!(policy::{EntryMesh, Layout, LeafEntries, LeafEntry, LeafShells, StoredBounds, plan_bounds});
pub use voxels::Voxels;
