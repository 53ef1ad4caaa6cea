//! A triangle mesh stored as an f64 anchor plus f32 offsets.
//!
//! Why: f32 world coordinates lose sub-millimetre detail beyond ~16 m from
//! the origin (a 1 km plant model would be quantised to 0.06 mm), and f64
//! everywhere doubles the bytes per block. Offsets from the object's own
//! lower corner keep f32's 24-bit mantissa relative to the object's size
//! (a 10 m pipe keeps ~1 µm) at 12 bytes per vertex. All geometry is read
//! back as exact f64 world points (`anchor + offset`), so every test and
//! bound is computed in f64 on the same numbers the file stores.

use crate::geom::{Aabb, Point, Vector};

/// Why a mesh was refused. Import errors wrap this with the file and object.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum MeshError {
    /// A vertex with a NaN or infinite coordinate.
    #[error("vertex {vertex} has a non-finite coordinate")]
    NonFiniteVertex {
        /// The vertex's index (0-based).
        vertex: usize,
    },
    /// A triangle names a vertex the mesh does not have.
    #[error("triangle {triangle} uses vertex index {index}, but the object has {vertices} vertices")]
    IndexOutOfRange {
        /// The triangle's index (0-based).
        triangle: usize,
        /// The vertex index it names.
        index: u32,
        /// The mesh's number of vertices.
        vertices: usize,
    },
    /// The mesh has no triangles.
    #[error("object has no triangles")]
    NoTriangles,
    /// More vertices than a u32 index addresses.
    #[error("object has {vertices} vertices, more than the 2^32 an index can address")]
    TooManyVertices {
        /// The number of vertices.
        vertices: usize,
    },
    /// Offsets from the anchor are f32: an object wider than f32's range has none.
    #[error("vertex {vertex} lies {offset:e} mm from the object's lower corner, beyond the {max:e} mm of an f32 offset", max = f32::MAX)]
    TooWide {
        /// The vertex's index (0-based).
        vertex: usize,
        /// Its distance from the object's lower corner, mm.
        offset: f64,
    },
}

/// A triangle mesh: vertex positions and triangles as index triples.
#[derive(Debug, Clone, PartialEq)]
pub struct Mesh {
    anchor: Point,
    offsets: Vec<[f32; 3]>,
    triangles: Vec<[u32; 3]>,
    aabb: Aabb,
}

impl Mesh {
    /// A mesh from world-space vertices (mm) and 0-based triangle indices.
    /// Checks that coordinates are finite, indices in range, and that there
    /// is at least one triangle. Unused vertices are kept.
    pub fn from_world(vertices: &[Point], triangles: Vec<[u32; 3]>) -> Result<Mesh, MeshError> {
        if let Some(vertex) = vertices.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
            return Err(MeshError::NonFiniteVertex { vertex });
        }
        if u32::try_from(vertices.len()).is_err() {
            return Err(MeshError::TooManyVertices { vertices: vertices.len() });
        }
        if triangles.is_empty() {
            return Err(MeshError::NoTriangles);
        }
        // The highest index first, in one pass the compiler vectorises; the
        // triangle at fault only when there is one.
        if triangles.as_flattened().iter().max().is_some_and(|&i| i as usize >= vertices.len()) {
            for (triangle, t) in triangles.iter().enumerate() {
                if let Some(&index) = t.iter().find(|&&i| i as usize >= vertices.len()) {
                    return Err(MeshError::IndexOutOfRange { triangle, index, vertices: vertices.len() });
                }
            }
        }
        let anchor = Aabb::from_points(vertices).min;
        let offsets: Vec<[f32; 3]> = vertices.iter().map(|p| quantize(anchor, p)).collect();
        if let Some(vertex) = offsets.iter().position(|o| !o.iter().all(|c| c.is_finite())) {
            let offset = (vertices[vertex] - anchor).amax();
            return Err(MeshError::TooWide { vertex, offset });
        }
        Ok(Mesh::from_parts(anchor, offsets, triangles))
    }

    /// The closed surface of a box: 8 corners, 12 triangles facing out.
    /// `None` for an empty or non-finite box.
    pub fn of_box(b: &Aabb) -> Option<Mesh> {
        let (lo, hi) = (b.min, b.max);
        let corners: Vec<Point> = (0..8)
            .map(|i| {
                Point::new(
                    if i & 1 == 0 { lo.x } else { hi.x },
                    if i & 2 == 0 { lo.y } else { hi.y },
                    if i & 4 == 0 { lo.z } else { hi.z },
                )
            })
            .collect();
        const FACES: [[u32; 3]; 12] = [
            [0, 2, 1],
            [1, 2, 3],
            [4, 5, 6],
            [5, 7, 6], // z low, z high
            [0, 1, 4],
            [1, 5, 4],
            [2, 6, 3],
            [3, 6, 7], // y low, y high
            [0, 4, 2],
            [2, 4, 6],
            [1, 3, 5],
            [3, 7, 5], // x low, x high
        ];
        if b.is_empty() {
            return None;
        }
        Mesh::from_world(&corners, FACES.to_vec()).ok()
    }

    /// A mesh from its stored form, already validated by the caller (the
    /// file decoder checks indices and finiteness before calling this).
    pub(crate) fn from_parts(anchor: Point, offsets: Vec<[f32; 3]>, triangles: Vec<[u32; 3]>) -> Mesh {
        // The box of the surface: each face touches a triangle, so the box can
        // witness contact (an unused vertex would break that). It is found
        // among the f32 offsets, then moved by the anchor: rounding
        // `anchor + offset` is monotone in the offset, so this is the box of
        // the world vertices exactly, without converting every corner.
        let (mut low, mut high) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
        for o in triangles.as_flattened().iter().filter_map(|&i| offsets.get(i as usize)) {
            // Comparisons rather than `f32::min`, which pays for NaN
            // (offsets are finite) on every corner.
            for k in 0..3 {
                low[k] = if o[k] < low[k] { o[k] } else { low[k] };
                high[k] = if o[k] > high[k] { o[k] } else { high[k] };
            }
        }
        let aabb = if low[0] <= high[0] {
            let world = |o: [f32; 3]| anchor + Vector::new(o[0].into(), o[1].into(), o[2].into());
            Aabb::new(world(low), world(high))
        } else {
            Aabb::EMPTY
        };
        Mesh { anchor, offsets, triangles, aabb }
    }

    /// The f64 point that the f32 offsets are relative to.
    pub fn anchor(&self) -> Point {
        self.anchor
    }

    /// The stored f32 offsets from the anchor.
    pub fn offsets(&self) -> &[[f32; 3]] {
        &self.offsets
    }

    /// Triangles as 0-based vertex index triples.
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.offsets.len()
    }

    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// Vertex `i` in world coordinates.
    pub fn vertex(&self, i: usize) -> Point {
        let o = self.offsets[i];
        self.anchor + Vector::new(o[0].into(), o[1].into(), o[2].into())
    }

    /// All vertices in world coordinates.
    pub fn vertices(&self) -> impl ExactSizeIterator<Item = Point> + '_ {
        (0..self.offsets.len()).map(|i| self.vertex(i))
    }

    /// Triangle `t` as three world points.
    pub fn triangle(&self, t: usize) -> [Point; 3] {
        self.triangles[t].map(|i| self.vertex(i as usize))
    }

    /// All triangles as world points.
    pub fn triangle_points(&self) -> impl ExactSizeIterator<Item = [Point; 3]> + '_ {
        (0..self.triangles.len()).map(|t| self.triangle(t))
    }

    /// The exact box of the triangles' stored vertices: every face of it
    /// touches the surface.
    pub fn aabb(&self) -> Aabb {
        self.aabb
    }

    /// Triangles of zero area (repeated index or collinear corners); they are
    /// kept, and importers report the count as a warning.
    pub fn degenerate_triangles(&self) -> usize {
        // World points once per vertex rather than once per corner.
        let world: Vec<Point> = self.vertices().collect();
        let zero_area = |t: &&[u32; 3]| {
            let [a, b, c] = t.map(|i| world[i as usize]);
            (b - a).cross(&(c - a)).norm_squared() == 0.0
        };
        self.triangles.iter().filter(zero_area).count()
    }
}

/// The f32 offset of `p` from `anchor`, chosen as a fixed point: the world
/// point it stands for (`anchor + offset`, rounded in f64) quantises back to
/// the same offset, so a mesh rebuilt from its own world vertices (as an OBJ
/// round trip does) is the same mesh bit for bit.
fn quantize(anchor: Point, p: &Point) -> [f32; 3] {
    std::array::from_fn(|i| {
        let mut off = (p[i] - anchor[i]) as f32;
        // Converges in one or two steps; the bound only guards the loop.
        for _ in 0..4 {
            let again = ((anchor[i] + f64::from(off)) - anchor[i]) as f32;
            if again == off {
                break;
            }
            off = again;
        }
        off
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn rebuilding_from_world_vertices_is_the_identity(
            base in prop::array::uniform3(-1.0e6f64..1.0e6),
            pts in prop::collection::vec(prop::array::uniform3(prop_oneof![
                -1.0e4f64..1.0e4, -1.0e-6f64..1.0e-6, Just(0.0)]), 3..12),
        ) {
            let world: Vec<Point> = pts.iter()
                .map(|d| Point::new(base[0] + d[0], base[1] + d[1], base[2] + d[2])).collect();
            let m = Mesh::from_world(&world, vec![[0, 1, 2]]).unwrap();
            let again = Mesh::from_world(&m.vertices().collect::<Vec<_>>(), vec![[0, 1, 2]]).unwrap();
            prop_assert_eq!(&m, &again);
        }

        /// The box found among the offsets is, bit for bit, the box of the
        /// world points the triangles use; unused vertices stay out.
        #[test]
        fn the_box_is_that_of_the_used_world_points(
            base in prop::array::uniform3(prop_oneof![-1.0e6f64..1.0e6, Just(0.0), Just(-0.0)]),
            pts in prop::collection::vec(prop::array::uniform3(prop_oneof![
                -1.0e4f64..1.0e4, -1.0e-6f64..1.0e-6, Just(0.0), Just(-0.0)]), 4..12),
            triangles in prop::collection::vec(prop::array::uniform3(0u32..3), 1..6),
        ) {
            let world: Vec<Point> = pts.iter()
                .map(|d| Point::new(base[0] + d[0], base[1] + d[1], base[2] + d[2])).collect();
            let m = Mesh::from_world(&world, triangles).unwrap();
            let used = m.triangles().iter().flatten().map(|&i| m.vertex(i as usize));
            let expected = used.fold(Aabb::EMPTY, |b, p| b.including(&p));
            let bits = |b: Aabb| [b.min, b.max].map(|p| p.coords.map(f64::to_bits));
            prop_assert_eq!(bits(m.aabb()), bits(expected));
        }
    }

    fn tri(points: &[[f64; 3]], t: Vec<[u32; 3]>) -> Result<Mesh, MeshError> {
        let p: Vec<Point> = points.iter().map(|&c| c.into()).collect();
        Mesh::from_world(&p, t)
    }

    #[test]
    fn bad_meshes_are_refused_with_the_culprit() {
        let ok = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        assert_eq!(tri(&ok, vec![]), Err(MeshError::NoTriangles));
        assert_eq!(
            tri(&ok, vec![[0, 1, 3]]),
            Err(MeshError::IndexOutOfRange { triangle: 0, index: 3, vertices: 3 })
        );
        let nan = [[0.0, 0.0, 0.0], [f64::NAN, 0.0, 0.0], [0.0, 1.0, 0.0]];
        assert_eq!(tri(&nan, vec![[0, 1, 2]]), Err(MeshError::NonFiniteVertex { vertex: 1 }));
    }

    #[test]
    fn far_from_origin_keeps_micrometres() {
        // A 10 m object placed 1 km from the origin keeps 1 µm detail.
        let base = 1.0e6;
        let m = tri(
            &[[base, base, base], [base + 10_000.001, base, base], [base, base + 0.001, base]],
            vec![[0, 1, 2]],
        )
        .unwrap();
        assert!((m.vertex(1).x - (base + 10_000.001)).abs() < 1e-3);
        assert!((m.vertex(2).y - (base + 0.001)).abs() < 1e-6);
    }

    #[test]
    fn degenerate_triangles_are_counted() {
        let p = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let m = tri(&p, vec![[0, 1, 2], [0, 0, 3], [0, 1, 3]]).unwrap();
        assert_eq!(m.degenerate_triangles(), 2);
    }
}
