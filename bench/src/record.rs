//! mktree's object record (format-spec/geometry.md, "Object record"),
//! written here from the spec: the SQLite peer stores each object as this
//! record, so its blobs hold the same bytes per object as mktree's geometry
//! runs, and the two files differ only by their indexes and paging.

use mktree::geom::{Aabb, Point, Vector};
use mktree::scene::Mesh;

/// Bytes before the vertex offsets.
const HEADER_LEN: usize = 40;
/// Bytes of one vertex offset ([f32; 3]) and of one triangle ([u32; 3]).
const TRIPLE_LEN: usize = 12;

/// Why a blob is not one object record.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum RecordError {
    /// Shorter than its header, or not the length its counts give.
    #[error("{len} bytes, but the record's counts give {expected}")]
    Length {
        /// Bytes of the blob.
        len: usize,
        /// 40 + 12 v + 12 t, or 40 when the header itself is cut.
        expected: u64,
    },
    /// The reserved bytes 12..16 are not zero.
    #[error("reserved bytes are not zero")]
    Reserved,
    /// `triangle_count` is 0.
    #[error("an object with no triangles")]
    NoTriangles,
    /// The anchor or a vertex offset is not finite.
    #[error("{field} is not finite")]
    NonFinite {
        /// "anchor" or "offset N".
        field: String,
    },
    /// A triangle names a vertex past the last.
    #[error("triangle {triangle} indexes past {vertices} vertices")]
    Index {
        /// The triangle's position.
        triangle: usize,
        /// `vertex_count`.
        vertices: usize,
    },
    /// A mesh too large for the record's u32 counts.
    #[error("{vertices} vertices and {triangles} triangles do not fit the record's u32 counts")]
    TooLarge {
        /// Vertices of the mesh.
        vertices: usize,
        /// Triangles of the mesh.
        triangles: usize,
    },
}

/// One decoded object record: the object's exact geometry as stored. Its
/// fields are private so that every record has passed [`decode`]'s checks
/// (triangle indices in range).
#[derive(Debug, Clone, PartialEq)]
pub struct Record {
    object_id: u32,
    anchor: Point,
    offsets: Vec<[f32; 3]>,
    triangles: Vec<[u32; 3]>,
}

/// The record of object `object_id` with geometry `mesh`: 40 + 12 v + 12 t bytes.
pub fn encode(object_id: u32, mesh: &Mesh) -> Result<Vec<u8>, RecordError> {
    let too_large =
        || RecordError::TooLarge { vertices: mesh.vertex_count(), triangles: mesh.triangle_count() };
    let v = u32::try_from(mesh.vertex_count()).map_err(|_| too_large())?;
    let t = u32::try_from(mesh.triangle_count()).map_err(|_| too_large())?;
    let mut out = Vec::with_capacity(HEADER_LEN + TRIPLE_LEN * (mesh.vertex_count() + mesh.triangle_count()));
    for word in [object_id, v, t, 0] {
        out.extend_from_slice(&word.to_le_bytes());
    }
    let a = mesh.anchor();
    for c in [a.x, a.y, a.z] {
        out.extend_from_slice(&c.to_le_bytes());
    }
    for c in mesh.offsets().iter().flatten() {
        out.extend_from_slice(&c.to_le_bytes());
    }
    for i in mesh.triangles().iter().flatten() {
        out.extend_from_slice(&i.to_le_bytes());
    }
    Ok(out)
}

/// The record in `bytes` (exactly one), checked against every rule of the spec.
pub fn decode(bytes: &[u8]) -> Result<Record, RecordError> {
    let word = |at: usize| -> [u8; 4] { std::array::from_fn(|i| bytes[at + i]) };
    let double = |at: usize| -> f64 { f64::from_le_bytes(std::array::from_fn(|i| bytes[at + i])) };
    if bytes.len() < HEADER_LEN {
        return Err(RecordError::Length { len: bytes.len(), expected: HEADER_LEN as u64 });
    }
    let (v, t) = (u32::from_le_bytes(word(4)) as usize, u32::from_le_bytes(word(8)) as usize);
    let expected = HEADER_LEN as u64 + TRIPLE_LEN as u64 * (v as u64 + t as u64);
    if bytes.len() as u64 != expected {
        return Err(RecordError::Length { len: bytes.len(), expected });
    }
    if word(12) != [0; 4] {
        return Err(RecordError::Reserved);
    }
    if t == 0 {
        return Err(RecordError::NoTriangles);
    }
    let anchor = Point::new(double(16), double(24), double(32));
    if !anchor.iter().all(|c| c.is_finite()) {
        return Err(RecordError::NonFinite { field: "anchor".into() });
    }
    // The length check above keeps every index below inside `bytes`.
    let triple = |at: usize| -> [[u8; 4]; 3] { std::array::from_fn(|i| word(at + 4 * i)) };
    let offsets: Vec<[f32; 3]> =
        (0..v).map(|i| triple(HEADER_LEN + TRIPLE_LEN * i).map(f32::from_le_bytes)).collect();
    if let Some(i) = offsets.iter().position(|o| !o.iter().all(|c| c.is_finite())) {
        return Err(RecordError::NonFinite { field: format!("offset {i}") });
    }
    let first = HEADER_LEN + TRIPLE_LEN * v;
    let triangles: Vec<[u32; 3]> =
        (0..t).map(|i| triple(first + TRIPLE_LEN * i).map(u32::from_le_bytes)).collect();
    if let Some(triangle) = triangles.iter().position(|tr| tr.iter().any(|&x| x as usize >= v)) {
        return Err(RecordError::Index { triangle, vertices: v });
    }
    Ok(Record { object_id: u32::from_le_bytes(word(0)), anchor, offsets, triangles })
}

impl Record {
    /// `object_id`.
    pub fn object_id(&self) -> u32 {
        self.object_id
    }

    /// The f64 point the offsets are relative to (the object's lower box corner).
    pub fn anchor(&self) -> Point {
        self.anchor
    }

    /// Vertex i = anchor + `offsets()[i]`, computed in f64.
    pub fn offsets(&self) -> &[[f32; 3]] {
        &self.offsets
    }

    /// Vertex index triples, each index below `offsets().len()`.
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }

    /// Vertex `i` in world coordinates, as mktree computes it (f32 offset
    /// widened, then added in f64).
    fn vertex(&self, i: u32) -> Point {
        let o = self.offsets[i as usize];
        self.anchor + Vector::new(o[0].into(), o[1].into(), o[2].into())
    }

    /// The exact box of the stored vertices.
    pub fn aabb(&self) -> Aabb {
        Aabb::from_points(&(0..self.offsets.len() as u32).map(|i| self.vertex(i)).collect::<Vec<_>>())
    }

    /// True when some triangle meets the closed box `query` (the object's
    /// box is tested first, as mktree's exact test does).
    pub fn meets_box(&self, query: &Aabb) -> bool {
        self.aabb().intersects(query)
            && self
                .triangles
                .iter()
                .any(|t| mktree::geom::intersects_triangle_box(&t.map(|i| self.vertex(i)), query))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mktree::scene::ObjectId;
    use mktree::scene::generate::{GenOptions, Preset, generate_scene};
    use mktree::store::format::geometry::encode_object;

    #[test]
    fn records_are_mktrees_bytes_and_decode_to_the_same_geometry() {
        let scene = generate_scene(&GenOptions { preset: Preset::Tanker1, objects: None, seed: 3 }).unwrap();
        for (i, o) in scene.objects().iter().enumerate() {
            let bytes = encode(i as u32, &o.mesh).unwrap();
            let mut theirs = Vec::new();
            encode_object(ObjectId(i as u32), &o.mesh, &mut theirs);
            assert_eq!(bytes, theirs, "object {i}");
            let r = decode(&bytes).unwrap();
            assert_eq!((r.object_id, r.anchor), (i as u32, o.mesh.anchor()));
            assert_eq!((&r.offsets[..], &r.triangles[..]), (o.mesh.offsets(), o.mesh.triangles()));
            assert_eq!(r.aabb(), o.mesh.aabb());
            let mine: Vec<[Point; 3]> = r.triangles.iter().map(|t| t.map(|j| r.vertex(j))).collect();
            assert_eq!(mine, o.mesh.triangle_points().collect::<Vec<_>>());
        }
    }

    #[test]
    fn damaged_records_are_refused_with_the_rule_they_break() {
        let mesh = Mesh::of_box(&Aabb::from_array([0.0, 0.0, 0.0, 1.0, 2.0, 3.0])).unwrap();
        let good = encode(5, &mesh).unwrap();
        assert_eq!(good.len(), 40 + 12 * 8 + 12 * 12);
        let patched = |at: usize, b: &[u8]| {
            let mut x = good.clone();
            x[at..at + b.len()].copy_from_slice(b);
            decode(&x)
        };
        assert!(matches!(decode(&good[..39]), Err(RecordError::Length { .. })));
        assert!(matches!(decode(&good[..good.len() - 4]), Err(RecordError::Length { .. })));
        assert_eq!(patched(12, &[1]), Err(RecordError::Reserved));
        assert_eq!(patched(16, &f64::NAN.to_le_bytes()).unwrap_err().to_string(), "anchor is not finite");
        assert_eq!(
            patched(40 + 12 * 8, &8u32.to_le_bytes()),
            Err(RecordError::Index { triangle: 0, vertices: 8 })
        );
        let mut none = good[..40 + 12 * 8].to_vec();
        none[8..12].copy_from_slice(&0u32.to_le_bytes());
        assert_eq!(decode(&none), Err(RecordError::NoTriangles));
    }

    #[test]
    fn a_record_meets_a_box_by_its_triangles_not_its_box() {
        // One slanted triangle: the box's corner away from it is in the box of the object.
        let tri = Mesh::from_world(
            &[Point::new(0.0, 0.0, 0.0), Point::new(10.0, 0.0, 0.0), Point::new(0.0, 10.0, 0.0)],
            vec![[0, 1, 2]],
        )
        .unwrap();
        let r = decode(&encode(0, &tri).unwrap()).unwrap();
        assert!(r.meets_box(&Aabb::from_array([1.0, 1.0, -1.0, 2.0, 2.0, 1.0])));
        assert!(!r.meets_box(&Aabb::from_array([8.0, 8.0, -1.0, 9.0, 9.0, 1.0])));
        assert!(!r.meets_box(&Aabb::from_array([20.0, 0.0, 0.0, 21.0, 1.0, 1.0])));
    }
}
