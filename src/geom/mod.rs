//! Geometry shared by every layer: axis-aligned boxes, axes, and the outward
//! rounding that keeps a box stored at lower precision conservative, and
//! the query shapes (spheres, frusta, rays, posed meshes) with their exact tests.
//!
//! `parry.rs` is the only place that imports parry; everything else uses
//! nalgebra's `Point3<f64>`. `contact.rs` holds the contact rule every query
//! decides by: closed sets, touching (distance 0) is contact, decided exactly.

mod aabb;
mod axis;
mod contact;
mod frustum;
mod parry;
mod pose;
mod ray;
mod round;
mod shape_error;
mod solid;
mod sphere;
mod triangle_box;

pub use aabb::Aabb;
pub use axis::Axis;
pub use contact::{intersects_triangle_triangle, triangles_within};
pub use frustum::{Camera, Frustum};
pub use parry::{
    SurfaceDistance, closest_points_triangle_triangle, distance_point_triangle, distance_triangle_triangle,
};
pub use pose::Pose;
pub use ray::Ray;
internal_use!(round::{round_down_f32, round_up_f32});
pub use shape_error::ShapeError;
pub use solid::{Overlap, closest, overlap, same_within, winding_number};
pub use sphere::Sphere;
pub(crate) use triangle_box::TriangleBoxTest;
pub use triangle_box::intersects_triangle_box;

/// A point in world coordinates, millimetres.
pub type Point = nalgebra::Point3<f64>;
/// A vector in world coordinates, millimetres.
pub type Vector = nalgebra::Vector3<f64>;
