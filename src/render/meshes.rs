//! Pictures of chosen meshes, each in its own colour: a clash group's
//! objects for its BCF snapshot (docs/clash.md, "BCF"), drawn by the same
//! rasterizer as the view's cut.

use super::raster::{Image, Projector};
use crate::geom::ShapeError;
use crate::query::View;
use crate::scene::Mesh;

/// A picture of `meshes` as `view` sees them, each in its colour.
pub fn draw_meshes(view: &View, meshes: &[(&Mesh, [u8; 3])]) -> Result<Image, ShapeError> {
    if view.width_px == 0 || view.height_px == 0 {
        return Err(ShapeError::Invalid { what: "a picture", detail: "a viewport of 0 pixels".into() });
    }
    let p = Projector::new(view).ok_or(ShapeError::Invalid {
        what: "a picture",
        detail: "the view direction is vertical or null (up is +z)".into(),
    })?;
    let mut img = Image::new(view.width_px, view.height_px);
    for (mesh, colour) in meshes {
        for t in mesh.triangle_points() {
            p.triangle(&mut img, &t, *colour);
        }
    }
    Ok(img)
}
