//! Pictures without a GPU: a z-buffer rasterizer with flat
//! shading (`raster.rs`) and what it draws, a view's cut or one node's level
//! of detail, coloured by level (`draw.rs`). Writing an image file is left
//! to the caller (the CLI writes PNG), so no image crate reaches an
//! embedder's build.

mod draw;
mod meshes;
mod raster;

pub use draw::{draw_cut, draw_level, framing, group_bound, level_colour};
pub use meshes::draw_meshes;
pub use raster::{BACKGROUND, Image};
