//! Object records: the exact geometry of a leaf's objects (format-spec/geometry.md).

use zerocopy::byteorder::little_endian::{F64, U32};
use zerocopy::{FromBytes, Immutable, IntoBytes, KnownLayout, Unaligned};

use super::frame::FRAME_LEN;
use crate::geom::Point;
use crate::scene::{Mesh, ObjectId};
use crate::store::StorageError;

#[derive(Debug, Clone, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
#[repr(C)]
pub(crate) struct ObjectHeader {
    pub(crate) object_id: U32,
    pub(crate) vertex_count: U32,
    pub(crate) triangle_count: U32,
    pub(crate) reserved: [u8; 4],
    pub(crate) anchor: [F64; 3],
}
/// Bytes of an object record's header.
pub const HEADER_LEN: usize = 40;
const _: () = assert!(size_of::<ObjectHeader>() == HEADER_LEN);

/// The format's coordinate range, mm (format-spec/geometry.md): every
/// anchor and vertex coordinate lies in `[-MAX_COORDINATE, MAX_COORDINATE]`,
/// 2^53, where f64 still holds every whole millimetre. Far inside f64's
/// range, so the products of coordinates that distances and exact contact
/// tests (parry's GJK) form stay finite.
pub const MAX_COORDINATE: f64 = 9_007_199_254_740_992.0;

/// Encoded bytes of one object record: 40 + 12 v + 12 t.
pub fn record_len(mesh: &Mesh) -> u64 {
    HEADER_LEN as u64 + 12 * mesh.vertex_count() as u64 + 12 * mesh.triangle_count() as u64
}

/// Appends the record of object `id` to `stream`.
pub fn encode_object(id: ObjectId, mesh: &Mesh, stream: &mut Vec<u8>) {
    let a = mesh.anchor();
    let h = ObjectHeader {
        object_id: id.0.into(),
        vertex_count: (mesh.vertex_count() as u32).into(),
        triangle_count: (mesh.triangle_count() as u32).into(),
        reserved: [0; 4],
        anchor: [a.x.into(), a.y.into(), a.z.into()],
    };
    stream.extend_from_slice(h.as_bytes());
    stream.extend_from_slice(bytemuck::cast_slice(mesh.offsets()));
    stream.extend_from_slice(bytemuck::cast_slice(mesh.triangles()));
}

/// The vertex count in the header of the record at the start of `bytes`.
pub fn record_vertex_count(bytes: &[u8]) -> Option<u64> {
    let h = ObjectHeader::read_from_bytes(bytes.get(..HEADER_LEN)?).ok()?;
    Some(u64::from(h.vertex_count.get()))
}

/// `mesh`, larger than a geometry block, as parts that fill blocks (format-
/// spec/geometry.md, "Parts"): its triangles in Morton order of their
/// centres, cut so that the first part fills `room` bytes (what is left of
/// the current block) and each next part a whole block of `payload` bytes.
/// So no part straddles two blocks, blocks stay full, and each part is a
/// compact piece of the surface whose box a query tests before reading it.
/// Every part keeps the mesh's anchor and its vertices' exact offsets, so
/// each vertex is the same f64 point in every part.
pub fn parts(mesh: &Mesh, room: u64, payload: u64) -> Vec<Mesh> {
    let b = mesh.aabb();
    let e = b.extent();
    let key = |t: &[u32; 3]| {
        let [p, q, r] = t.map(|i| mesh.vertex(i as usize));
        let cell = |a: usize, c: f64| {
            let x = if e[a] > 0.0 { (c / 3.0 - b.min[a]) / e[a] } else { 0.0 };
            (x.clamp(0.0, 1.0) * f64::from((1u32 << 21) - 1)) as u64
        };
        let c = [p.x + q.x + r.x, p.y + q.y + r.y, p.z + q.z + r.z];
        morton(cell(0, c[0]), cell(1, c[1]), cell(2, c[2]))
    };
    let mut tris = mesh.triangles().to_vec();
    tris.sort_by_cached_key(key);
    let mut out = Vec::new();
    let mut room = room;
    let mut start = 0;
    let mut used = std::collections::HashSet::new();
    while start < tris.len() {
        used.clear();
        let mut end = start;
        while end < tris.len() {
            // The triangle's distinct vertices not yet in the part.
            let t = &tris[end];
            let new = (0..3).filter(|&k| !used.contains(&t[k]) && !t[..k].contains(&t[k])).count();
            let len = HEADER_LEN as u64 + 12 * (used.len() + new) as u64 + 12 * (end - start + 1) as u64;
            // A part holds at least one triangle, even in a room too small for it.
            if len > room && end > start {
                break;
            }
            used.extend(tris[end]);
            end += 1;
        }
        out.push(sub_mesh(mesh, &tris[start..end]));
        start = end;
        room = payload;
    }
    out
}

/// Interleaves the low 21 bits of x, y and z.
fn morton(x: u64, y: u64, z: u64) -> u64 {
    let spread = |mut v: u64| {
        v &= 0x1f_ffff;
        v = (v | v << 32) & 0x1f_0000_0000_ffff;
        v = (v | v << 16) & 0x1f_0000_ff00_00ff;
        v = (v | v << 8) & 0x100f_00f0_0f00_f00f;
        v = (v | v << 4) & 0x10c3_0c30_c30c_30c3;
        (v | v << 2) & 0x1249_2492_4924_9249
    };
    spread(x) | spread(y) << 1 | spread(z) << 2
}

/// The object whose parts are `parts` (as [`parts`] made them, one anchor):
/// their vertices and triangles in order. A vertex two parts share appears
/// twice, at the same point.
pub fn join(parts: &[Mesh]) -> Option<Mesh> {
    let first = parts.first()?;
    let mut offsets = Vec::new();
    let mut triangles = Vec::new();
    for p in parts {
        let base = offsets.len() as u32;
        offsets.extend_from_slice(p.offsets());
        triangles.extend(p.triangles().iter().map(|t| t.map(|v| v + base)));
    }
    Some(Mesh::from_parts(first.anchor(), offsets, triangles))
}

/// The part of `mesh` made of `tris`: the vertices they use, with the
/// mesh's anchor and offsets.
fn sub_mesh(mesh: &Mesh, tris: &[[u32; 3]]) -> Mesh {
    let mut index = std::collections::HashMap::new();
    let mut offsets = Vec::new();
    let triangles = tris
        .iter()
        .map(|t| {
            t.map(|v| {
                *index.entry(v).or_insert_with(|| {
                    offsets.push(mesh.offsets()[v as usize]);
                    (offsets.len() - 1) as u32
                })
            })
        })
        .collect();
    Mesh::from_parts(mesh.anchor(), offsets, triangles)
}

/// Where geometry records go in the stream of geometry blocks' payloads
/// (format-spec/geometry.md, "Placement"): a record that fits a block never
/// straddles two; a larger one starts in the current block when that costs
/// it no extra block, and the next record starts right after it.
#[derive(Debug, Clone)]
pub struct Placement {
    payload: u64,
    at: u64,
}

impl Placement {
    /// An empty stream of blocks of `block_size` bytes.
    pub fn new(block_size: u32) -> Placement {
        Placement { payload: payload(block_size), at: 0 }
    }

    /// Places a record of `len` bytes; returns its stream offset.
    pub fn place(&mut self, len: u64) -> u64 {
        let p = self.payload;
        let used = self.at % p;
        let fresh = len.div_ceil(p);
        let here = if used == 0 { fresh } else { 1 + len.saturating_sub(p - used).div_ceil(p) };
        if used != 0 && (used + len > p && len <= p || here > fresh) {
            self.at += p - used;
        }
        let pos = self.at;
        self.at += len;
        pos
    }

    /// Starts the next record at a block's start: a leaf's span holds no
    /// other leaf's records (format-spec/geometry.md), so a change commit
    /// rewrites a leaf's blocks without touching its neighbours'.
    pub fn start_block(&mut self) {
        self.at = self.at.next_multiple_of(self.payload);
    }

    /// Bytes left in the current block (a whole block at a block's start).
    pub fn room(&self) -> u64 {
        self.payload - self.at % self.payload
    }

    /// Bytes of the stream so far.
    pub fn end(&self) -> u64 {
        self.at
    }
}

/// Stream bytes a geometry block holds.
pub fn payload(block_size: u32) -> u64 {
    u64::from(block_size) - FRAME_LEN as u64
}

/// The geometry blocks (indices from the span's first block) that hold
/// stream bytes `[start, end)`.
pub fn blocks_of(start: u64, end: u64, block_size: u32) -> std::ops::RangeInclusive<u64> {
    let p = payload(block_size);
    start / p..=(end.max(start + 1) - 1) / p
}

/// Decodes the object record at the start of `bytes` (stream bytes
/// `[start, end)` of a span: the record and the zero padding after it),
/// read from geometry blocks starting at block `id`, checking every rule.
pub fn decode_object(id: u32, bytes: &[u8]) -> Result<(ObjectId, Mesh), StorageError> {
    let bad = |field, detail: String| StorageError::corrupt(id, field, detail);
    let h = bytes
        .get(..HEADER_LEN)
        .and_then(|b| ObjectHeader::read_from_bytes(b).ok())
        .ok_or_else(|| bad("object record", "the span ends inside a record header".into()))?;
    let (v, t) = (h.vertex_count.get() as usize, h.triangle_count.get() as usize);
    // The counts are bounded by the bytes at hand before anything is sized from them.
    let body = 12usize.checked_mul(v).and_then(|a| a.checked_add(12usize.checked_mul(t)?));
    let end = body.and_then(|b| HEADER_LEN.checked_add(b)).filter(|&e| e <= bytes.len());
    let Some(end) = end else {
        return Err(bad("vertex_count", format!("{v} vertices and {t} triangles overrun the record's span")));
    };
    if h.reserved != [0; 4] || !super::all_zero(&bytes[end..]) {
        return Err(bad("reserved", "reserved or padding bytes are not zero".into()));
    }
    if t == 0 {
        return Err(bad("triangle_count", "an object with no triangles".into()));
    }
    let anchor = Point::new(h.anchor[0].get(), h.anchor[1].get(), h.anchor[2].get());
    if !anchor.iter().all(|c| c.abs() <= MAX_COORDINATE) {
        return Err(bad("anchor", format!("{anchor:?} is outside the format's range (2^53 mm)")));
    }
    let arrays = &bytes[HEADER_LEN..end];
    let offsets: Vec<[f32; 3]> = arrays[..12 * v]
        .chunks_exact(12)
        .map(|c| {
            std::array::from_fn(|i| f32::from_le_bytes([c[4 * i], c[4 * i + 1], c[4 * i + 2], c[4 * i + 3]]))
        })
        .collect();
    let triangles: Vec<[u32; 3]> = arrays[12 * v..]
        .chunks_exact(12)
        .map(|c| {
            std::array::from_fn(|i| u32::from_le_bytes([c[4 * i], c[4 * i + 1], c[4 * i + 2], c[4 * i + 3]]))
        })
        .collect();
    // The anchor is the vertices' lower corner, so offsets are >= 0 and the
    // anchor bounds every vertex from below; from above, each is checked.
    let in_range =
        |o: &[f32; 3]| (0..3).all(|a| o[a] >= 0.0 && anchor[a] + f64::from(o[a]) <= MAX_COORDINATE);
    if let Some(i) = offsets.iter().position(|o| !in_range(o)) {
        return Err(bad(
            "offsets",
            format!("vertex {i} lies below the anchor or outside the format's range"),
        ));
    }
    if let Some(i) = triangles.iter().position(|tr| tr.iter().any(|&x| x as usize >= v)) {
        return Err(bad("triangles", format!("triangle {i} indexes past {v} vertices")));
    }
    Ok((ObjectId(h.object_id.get()), Mesh::from_parts(anchor, offsets, triangles)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_object_round_trips_and_its_padding_is_checked() {
        let p: Vec<Point> = (0..300).map(|i| Point::new(i as f64, (i * 7 % 13) as f64, 1e6)).collect();
        let tris: Vec<[u32; 3]> = (0..298).map(|i| [i, i + 1, i + 2]).collect();
        let m = Mesh::from_world(&p, tris).unwrap();
        let mut stream = Vec::new();
        encode_object(ObjectId(4), &m, &mut stream);
        assert_eq!(stream.len() as u64, record_len(&m));
        stream.extend_from_slice(&[0; 8]);
        assert_eq!(decode_object(7, &stream).unwrap(), (ObjectId(4), m));
        *stream.last_mut().unwrap() = 1;
        assert!(decode_object(7, &stream).is_err());
        assert!(decode_object(7, &stream[..100]).is_err());
    }

    #[test]
    fn anchors_and_vertices_outside_the_format_range_are_corrupt() {
        let m = Mesh::from_world(
            &[Point::new(1.0, 2.0, 3.0), Point::new(4.0, 2.0, 3.0), Point::new(1.0, 5.0, 3.0)],
            vec![[0, 1, 2]],
        )
        .unwrap();
        let mut good = Vec::new();
        encode_object(ObjectId(0), &m, &mut good);
        let far = MAX_COORDINATE + 2.0;
        // (byte, bytes): the anchor's x far out, its y far below; a vertex
        // below the anchor; a vertex past the range from an anchor inside it.
        let cases: [(usize, Vec<u8>); 4] = [
            (16, far.to_le_bytes().to_vec()),
            (24, (-far).to_le_bytes().to_vec()),
            (40 + 12, (-1.0f32).to_le_bytes().to_vec()),
            (16, (MAX_COORDINATE - 1.0).to_le_bytes().to_vec()),
        ];
        for (i, (at, bytes)) in cases.into_iter().enumerate() {
            let mut rec = good.clone();
            rec[at..at + bytes.len()].copy_from_slice(&bytes);
            assert!(decode_object(7, &rec).is_err(), "case {i}");
        }
        let mut edge = good.clone();
        edge[16..24].copy_from_slice(&(-MAX_COORDINATE).to_le_bytes());
        assert!(decode_object(7, &edge).is_ok(), "the range's ends are in it");
    }

    #[test]
    fn parts_fit_keep_every_triangle_and_every_point_exactly() {
        let p: Vec<Point> = (0..400)
            .map(|i| Point::new(i as f64 * 1.37, (i * 7 % 13) as f64, 1e6 + (i % 5) as f64))
            .collect();
        let tris: Vec<[u32; 3]> = (0..398).map(|i| [i, i + 1, i + 2]).collect();
        let m = Mesh::from_world(&p, tris).unwrap();
        let split = parts(&m, 300, 1024);
        assert!(split.len() > 1);
        assert!(record_len(&split[0]) <= 300);
        assert!(split.iter().all(|x| record_len(x) <= 1024));
        // Blocks are filled: every part but the last leaves less than a triangle's bytes.
        assert!(split[1..split.len() - 1].iter().all(|x| record_len(x) > 1024 - 48));
        let mut all: Vec<[Point; 3]> = split.iter().flat_map(|x| x.triangle_points()).collect();
        let mut want: Vec<[Point; 3]> = m.triangle_points().collect();
        let key = |t: &[Point; 3]| t.map(|p| (p.x.to_bits(), p.y.to_bits(), p.z.to_bits()));
        all.sort_by_key(key);
        want.sort_by_key(key);
        assert_eq!(all, want, "the same triangles, bit for bit");
        let joined = join(&split).unwrap();
        assert_eq!(joined.aabb(), m.aabb());
        assert_eq!(joined.triangle_count(), m.triangle_count());
        assert_eq!(parts(&m, u64::MAX, u64::MAX).len(), 1);
    }

    #[test]
    fn a_vertex_a_triangle_names_twice_is_stored_once() {
        // Degenerate triangles of two fresh vertices each: 24 bytes of
        // vertices and 12 of indices, so a part is full within 36 bytes.
        let p: Vec<Point> = (0..400).map(|i| Point::new(i as f64, (i % 7) as f64, 0.0)).collect();
        let tris: Vec<[u32; 3]> = (0..200).map(|i| [2 * i, 2 * i + 1, 2 * i + 1]).collect();
        let m = Mesh::from_world(&p, tris).unwrap();
        for room in 600..700 {
            let split = parts(&m, room, 1024);
            let first = record_len(&split[0]);
            assert!(first > room - 36 && first <= room, "room {room}: the first part takes {first} bytes");
            assert_eq!(split.iter().map(Mesh::triangle_count).sum::<usize>(), 200);
        }
    }

    #[test]
    fn placement_fills_blocks_and_never_splits_a_small_record() {
        let bs = 1024;
        let p = payload(bs);
        let mut pl = Placement::new(bs);
        assert_eq!(pl.place(600), 0);
        assert_eq!(pl.place(600), p, "600 more would straddle: the next block");
        assert_eq!(pl.place(400), p + 600);
        // A large record goes on in the current block when that costs no extra block.
        let big = pl.place(2 * p);
        assert_eq!(big, 2 * p, "here it would take three blocks, fresh two");
        let after = pl.place(3 * p - 100);
        assert_eq!(after, 4 * p, "at a boundary");
        assert_eq!(pl.place(50), 7 * p - 100, "the large record's tail block is shared");
        assert_eq!(blocks_of(0, p, bs), 0..=0);
        assert_eq!(blocks_of(p - 4, p + 4, bs), 0..=1);
    }
}
