//! The only place that imports parry: a triangle set's BVH for point
//! distances, and the triangle-triangle distances of clearance queries.
//! (Whether two triangles touch is decided exactly in `contact.rs`: parry's
//! GJK decides touching within a tolerance, and differently for (a, b) and
//! (b, a).)

use super::Point;
use parry3d_f64::math::Isometry;
use parry3d_f64::query::{ClosestPoints, PointQuery};
use parry3d_f64::shape::{Polyline, Segment, Shape, TriMesh, Triangle};

/// A triangle as parry sees it: parry's triangle routines assume area, so a
/// zero-area triangle is the segment between its two farthest corners (which
/// holds its third corner), and tests on it stay exact.
enum Simplex {
    Triangle(Triangle),
    Segment(Segment),
}

impl Simplex {
    fn of(t: &[Point; 3]) -> Simplex {
        let [a, b, c] = *t;
        if (b - a).cross(&(c - a)).norm_squared() > 0.0 {
            return Simplex::Triangle(Triangle::new(a, b, c));
        }
        let pairs = [(a, b), (b, c), (c, a)];
        let (p, q) = pairs
            .into_iter()
            .max_by(|x, y| (x.1 - x.0).norm_squared().total_cmp(&(y.1 - y.0).norm_squared()))
            .unwrap_or((a, b));
        Simplex::Segment(Segment::new(p, q))
    }

    fn shape(&self) -> &dyn Shape {
        match self {
            Simplex::Triangle(t) => t,
            Simplex::Segment(s) => s,
        }
    }

    fn distance_to_point(&self, p: &Point) -> f64 {
        match self {
            Simplex::Triangle(t) => t.distance_to_local_point(p, true),
            Simplex::Segment(s) => s.distance_to_local_point(p, true),
        }
    }
}

/// The distance between two closed triangles (about 0 when they meet:
/// within parry's rounding). The same bits for (a, b) and (b, a): the pair
/// is handed to parry in one order.
pub fn distance_triangle_triangle(a: &[Point; 3], b: &[Point; 3]) -> f64 {
    let first =
        a.iter().flat_map(|p| p.iter()).zip(b.iter().flat_map(|p| p.iter())).map(|(x, y)| x.total_cmp(y));
    let (a, b) = if first.into_iter().find(|o| o.is_ne()) == Some(std::cmp::Ordering::Greater) {
        (b, a)
    } else {
        (a, b)
    };
    let id = Isometry::identity();
    // Triangles and segments are support maps: parry supports every pair of them.
    parry3d_f64::query::distance(&id, Simplex::of(a).shape(), &id, Simplex::of(b).shape()).unwrap_or(0.0)
}

/// The distance between two closed triangles with the closest point of
/// each (`a`'s first), the pair handed to parry in one order as
/// [`distance_triangle_triangle`] does. Triangles parry calls intersecting
/// give distance 0 and a corner of `a` twice.
pub fn closest_points_triangle_triangle(a: &[Point; 3], b: &[Point; 3]) -> (f64, Point, Point) {
    let first =
        a.iter().flat_map(|p| p.iter()).zip(b.iter().flat_map(|p| p.iter())).map(|(x, y)| x.total_cmp(y));
    let swapped = first.into_iter().find(|o| o.is_ne()) == Some(std::cmp::Ordering::Greater);
    let (x, y) = if swapped { (b, a) } else { (a, b) };
    let id = Isometry::identity();
    let found = parry3d_f64::query::closest_points(
        &id,
        Simplex::of(x).shape(),
        &id,
        Simplex::of(y).shape(),
        f64::MAX,
    );
    match found {
        Ok(ClosestPoints::WithinMargin(p, q)) => {
            let (p, q) = if swapped { (q, p) } else { (p, q) };
            ((p - q).norm(), p, q)
        }
        _ => (0.0, a[0], a[0]),
    }
}

/// The distance from `p` to the closed triangle `t`.
pub fn distance_point_triangle(p: &Point, t: &[Point; 3]) -> f64 {
    Simplex::of(t).distance_to_point(p)
}

/// Distances from points to a set of triangles (the surface, not a solid),
/// through parry's BVH. Deterministic: the same triangles give the same tree.
pub struct SurfaceDistance {
    nearest: Nearest,
}

/// What distances are measured to.
enum Nearest {
    Triangles(TriMesh),
    /// The segments (or points) of zero-area triangles, when no triangle has area.
    Segments(Polyline),
    Nothing,
}

impl SurfaceDistance {
    /// The surface of `triangles`. Zero-area triangles are dropped (parry
    /// cannot project onto them) when any triangle has area: they lie on
    /// their neighbours' edges in any mesh that has area, so distances only
    /// grow where one stood alone. Without area, the surface is the
    /// segments and points they span.
    pub fn new(triangles: impl IntoIterator<Item = [Point; 3]>) -> SurfaceDistance {
        let mut vertices = Vec::new();
        let mut indices = Vec::new();
        let mut segments = Vec::new();
        for t in triangles {
            match Simplex::of(&t) {
                Simplex::Triangle(_) => {
                    let n = vertices.len() as u32;
                    vertices.extend(t);
                    indices.push([n, n + 1, n + 2]);
                }
                Simplex::Segment(s) if indices.is_empty() => segments.extend([s.a, s.b]),
                Simplex::Segment(_) => {}
            }
        }
        let nearest = match TriMesh::new(vertices, indices) {
            Ok(mesh) => Nearest::Triangles(mesh),
            Err(_) if !segments.is_empty() => {
                let ends = (0..segments.len() as u32 / 2).map(|i| [2 * i, 2 * i + 1]).collect();
                Nearest::Segments(Polyline::new(segments, Some(ends)))
            }
            Err(_) => Nearest::Nothing,
        };
        SurfaceDistance { nearest }
    }

    /// The distance from `p` to the nearest triangle (infinite when there is none).
    pub fn distance(&self, p: &Point) -> f64 {
        let projection = match &self.nearest {
            Nearest::Triangles(mesh) => mesh.project_local_point(p, false),
            Nearest::Segments(lines) => lines.project_local_point(p, false),
            Nearest::Nothing => return f64::INFINITY,
        };
        (p - projection.point).norm()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distance_to_a_triangle_from_its_plane_edge_and_corner_regions() {
        let s = SurfaceDistance::new([[
            Point::new(0.0, 0.0, 0.0),
            Point::new(1.0, 0.0, 0.0),
            Point::new(0.0, 1.0, 0.0),
        ]]);
        assert!((s.distance(&Point::new(0.2, 0.2, 3.0)) - 3.0).abs() < 1e-12);
        assert!((s.distance(&Point::new(0.5, -2.0, 0.0)) - 2.0).abs() < 1e-12);
        assert!((s.distance(&Point::new(-3.0, -4.0, 0.0)) - 5.0).abs() < 1e-12);
        assert_eq!(SurfaceDistance::new([]).distance(&Point::origin()), f64::INFINITY);
    }

    #[test]
    fn a_surface_without_area_is_its_segments_and_points() {
        let p = Point::new;
        let segment = [p(0.0, 0.0, 0.0), p(2.0, 0.0, 0.0), p(1.0, 0.0, 0.0)];
        let point = [p(5.0, 5.0, 5.0); 3];
        let s = SurfaceDistance::new([segment, point]);
        assert!((s.distance(&p(1.0, 3.0, 0.0)) - 3.0).abs() < 1e-12);
        assert!((s.distance(&p(-4.0, 0.0, 3.0)) - 5.0).abs() < 1e-12);
        assert!((s.distance(&p(5.0, 5.0, 6.0)) - 1.0).abs() < 1e-12);
        // With area, a zero-area triangle is dropped.
        let flat = [p(0.0, 0.0, 10.0), p(1.0, 0.0, 10.0), p(0.0, 1.0, 10.0)];
        let s = SurfaceDistance::new([point, flat]);
        assert!((s.distance(&p(0.0, 0.0, 12.0)) - 2.0).abs() < 1e-12);
    }

    #[test]
    fn triangle_pairs_apart_and_degenerate() {
        let p = Point::new;
        let flat = [p(0.0, 0.0, 0.0), p(2.0, 0.0, 0.0), p(0.0, 2.0, 0.0)];
        let above = [p(0.5, 0.5, 3.0), p(1.5, 0.5, 3.0), p(0.5, 1.5, 3.0)];
        assert!((distance_triangle_triangle(&flat, &above) - 3.0).abs() < 1e-9);
        // A zero-area "triangle" is the segment it spans.
        let segment = [p(0.5, 0.5, 4.0), p(0.5, 0.5, 6.0), p(0.5, 0.5, 5.0)];
        assert!((distance_triangle_triangle(&segment, &above) - 1.0).abs() < 1e-9);
        assert!((distance_point_triangle(&p(0.5, 0.5, 2.0), &segment) - 2.0).abs() < 1e-12);
        assert!((distance_point_triangle(&p(0.5, 0.5, 2.0), &flat) - 2.0).abs() < 1e-12);
    }

    #[test]
    fn distance_is_the_same_bits_either_way() {
        // Coplanar faces of tanker2 that parry measured differently by order.
        let p = Point::new;
        let a = [p(4330.5, 0.0, 3651.4375), p(4330.5, 14.0, 3651.4375), p(14.0, 14.0, 3651.4375)];
        let b = [p(2830.5, 14.0, 14.0), p(2840.5, 14.0, 14.0), p(2840.5, 14.0, 5470.1875)];
        assert_eq!(
            distance_triangle_triangle(&a, &b).to_bits(),
            distance_triangle_triangle(&b, &a).to_bits()
        );
    }
}
