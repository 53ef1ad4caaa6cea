//! `LodError`: why a level-of-detail grid, lift or blob was refused.

/// Why a voxel level of detail could not be built, lifted or decoded.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum LodError {
    /// The grid would have more cells than [`MAX_CELLS`](super::MAX_CELLS) or a side
    /// longer than [`MAX_DIM`](super::MAX_DIM).
    #[error("grid at lattice level {level} has {cells} cells ({dims:?}): more than allowed")]
    TooLarge {
        /// The lattice level asked for.
        level: u8,
        /// Cells per axis (saturated at u32::MAX when estimated).
        dims: [u32; 3],
        /// Total cells (saturated).
        cells: u64,
    },
    /// The bounds are empty or not finite.
    #[error("bounds {0:?} are empty or not finite")]
    BadBounds([f64; 6]),
    /// The lattice has a non-finite origin or a cell size that is not positive and finite.
    #[error("lattice with origin {origin:?} and cell {cell} is invalid")]
    BadLattice {
        /// The lattice origin.
        origin: [f64; 3],
        /// The lattice cell size.
        cell: f64,
    },
    /// A lift or subset test between grids that do not nest.
    #[error("grid at level {from_level} over {from:?} does not nest into level {to_level} over {to:?}")]
    NotNested {
        /// The source grid's level.
        from_level: u8,
        /// The source grid's bounds.
        from: [f64; 6],
        /// The target grid's level.
        to_level: u8,
        /// The target grid's bounds.
        to: [f64; 6],
    },
    /// Parameters that cannot build levels of detail (the eps list, M).
    #[error("level-of-detail parameters: {0}")]
    Params(String),
    /// An object's mesh could not be read (a staged scene's spill file).
    #[error("reading an object's mesh: {0}")]
    Mesh(String),
    /// A blob that is not a valid encoding: the message names the field.
    #[error("level-of-detail blob is corrupt: {0}")]
    Corrupt(String),
}
