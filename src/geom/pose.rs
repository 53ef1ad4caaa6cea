//! Rigid poses of a query object: a rotation about the object's own box
//! centre, then a translation, so a pose moves an object where it stands
//! (rotating about the world origin would swing an object of a 30 m ship
//! metres away for a few degrees).

use super::{Point, ShapeError, Vector};
use nalgebra::Rotation3;

/// A rotation (about a centre the caller gives) and a translation, mm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    /// The rotation.
    pub rotation: Rotation3<f64>,
    /// The translation, mm.
    pub translation: Vector,
}

impl Default for Pose {
    fn default() -> Pose {
        Pose { rotation: Rotation3::identity(), translation: Vector::zeros() }
    }
}

impl Pose {
    /// Translation `t` (mm) and rotations in degrees about x, then y, then z.
    pub fn from_degrees(t: [f64; 3], r_deg: [f64; 3]) -> Result<Pose, ShapeError> {
        if !t.iter().chain(&r_deg).all(|x| x.is_finite()) {
            return Err(ShapeError::NotFinite { what: "a pose" });
        }
        let [rx, ry, rz] = r_deg.map(f64::to_radians);
        Ok(Pose { rotation: Rotation3::from_euler_angles(rx, ry, rz), translation: Vector::from(t) })
    }

    /// `p` rotated about `center`, then translated. Without a rotation `p`
    /// is only translated, exactly: an object posed where it stands keeps its
    /// coordinates to the bit (`c + (p - c)` need not be `p`), so it touches
    /// what it touched.
    pub fn apply(&self, center: &Point, p: &Point) -> Point {
        if self.rotation == Rotation3::identity() {
            return p + self.translation;
        }
        center + self.rotation * (p - center) + self.translation
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_quarter_turn_about_z_turns_about_the_centre_then_moves() {
        let pose = Pose::from_degrees([10.0, 0.0, 0.0], [0.0, 0.0, 90.0]).unwrap();
        let q = pose.apply(&Point::new(1.0, 1.0, 0.0), &Point::new(2.0, 1.0, 0.0));
        assert!((q - Point::new(11.0, 2.0, 0.0)).norm() < 1e-12);
        assert!(Pose::from_degrees([f64::INFINITY, 0.0, 0.0], [0.0; 3]).is_err());
    }

    #[test]
    fn no_rotation_keeps_the_point_to_the_bit() {
        let (c, p) = (Point::new(0.4, 0.4, 0.4), Point::new(0.1, 0.7, 0.1));
        assert_ne!(c + (p - c), p, "the rounding this avoids");
        assert_eq!(Pose::default().apply(&c, &p), p);
        let moved = Pose::from_degrees([1.5, 0.0, 0.0], [0.0; 3]).unwrap();
        assert_eq!(moved.apply(&c, &p), Point::new(0.1 + 1.5, 0.7, 0.1));
    }
}
