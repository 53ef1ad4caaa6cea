//! The file's coordinate range, checked on every query's input: every
//! coordinate a file holds lies in [-2^53, 2^53] mm (format-spec/geometry.md,
//! "Coordinate range"), and a query stating a point outside it is refused
//! with [`QueryError::OutOfRange`] before anything is read. So no product of
//! a query's and a file's coordinates overflows: squared distances stay
//! below 3 x 2^108, far inside f64, and a distance never comes out as
//! infinity or NaN (JSON's `null`).

use super::QueryError;
use crate::geom::{Aabb, Point, ShapeError};
use crate::store::format::geometry::MAX_COORDINATE;

/// The longest length a query may state (a radius, a clearance): 2^55 mm,
/// more than the range's diagonal (2^54 x sqrt 3), so any longer one means
/// nothing more, and sums of it with a coordinate stay exact enough.
pub const MAX_LENGTH: f64 = 4.0 * MAX_COORDINATE;

/// Refuses a point with a coordinate that is not finite or lies outside
/// the file's range; `what` names the query's part ("a nearest point").
pub(crate) fn check_point(what: &'static str, p: &Point) -> Result<(), QueryError> {
    if !p.iter().all(|c| c.is_finite()) {
        return Err(ShapeError::NotFinite { what }.into());
    }
    match p.iter().find(|c| c.abs() > MAX_COORDINATE) {
        Some(&coordinate) => Err(QueryError::OutOfRange { what, coordinate }),
        None => Ok(()),
    }
}

/// Refuses a length that is not finite, negative or longer than [`MAX_LENGTH`].
pub(crate) fn check_length(what: &'static str, length: f64) -> Result<(), QueryError> {
    if !length.is_finite() {
        return Err(ShapeError::NotFinite { what }.into());
    }
    if length < 0.0 {
        return Err(ShapeError::Invalid { what, detail: format!("{length} mm < 0") }.into());
    }
    if length > MAX_LENGTH {
        return Err(QueryError::TooLong { what, length });
    }
    Ok(())
}

/// Refuses a box that is inverted (x0 > x1, y0 > y1 or z0 > z1) or has a
/// corner outside the range: the one rule of `query --box`, `batch` and
/// [`query_region`](super::query_region) alike.
pub(crate) fn check_box(what: &'static str, b: &Aabb) -> Result<(), QueryError> {
    check_point(what, &b.min)?;
    check_point(what, &b.max)?;
    if (0..3).any(|a| b.min[a] > b.max[a]) {
        let [x0, y0, z0, x1, y1, z1] = b.to_array();
        let detail =
            format!("[{x0}, {y0}, {z0}, {x1}, {y1}, {z1}] is inverted: x0 <= x1, y0 <= y1, z0 <= z1");
        return Err(ShapeError::Invalid { what, detail }.into());
    }
    Ok(())
}
