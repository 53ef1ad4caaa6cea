//! Object records: the exact geometry of a leaf's objects (format-spec/geometry.md).

use zerocopy::byteorder::little_endian::{F64, U32};
use zerocopy::{FromBytes, Immutable, IntoBytes, KnownLayout, Unaligned};

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
const HEADER_LEN: usize = 40;
const _: () = assert!(size_of::<ObjectHeader>() == HEADER_LEN);

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

/// Decodes `records` object records from a reassembled stream of `len` bytes
/// (the run starting at block `id`), checking every rule of the spec.
pub fn decode_objects(
    id: u32,
    words: &[u32],
    len: usize,
    records: u32,
) -> Result<Vec<(ObjectId, Mesh)>, StorageError> {
    let bytes: &[u8] = &bytemuck::cast_slice(words)[..len];
    let mut at = 0usize;
    let mut out = Vec::with_capacity(records as usize);
    for r in 0..records {
        let bad = |field, detail: String| StorageError::corrupt_record(id, r, field, detail);
        let h = bytes
            .get(at..at + HEADER_LEN)
            .and_then(|b| ObjectHeader::read_from_bytes(b).ok())
            .ok_or_else(|| bad("object record", "the stream ends inside a record header".into()))?;
        let (v, t) = (h.vertex_count.get() as usize, h.triangle_count.get() as usize);
        let body = 12usize.checked_mul(v).and_then(|a| a.checked_add(12usize.checked_mul(t)?));
        let end = body.and_then(|b| (at + HEADER_LEN).checked_add(b)).filter(|&e| e <= len);
        let Some(end) = end else {
            return Err(bad("vertex_count", format!("{v} vertices and {t} triangles overrun the stream")));
        };
        if h.reserved != [0; 4] {
            return Err(bad("reserved", "reserved bytes are not zero".into()));
        }
        if t == 0 {
            return Err(bad("triangle_count", "an object with no triangles".into()));
        }
        let anchor = Point::new(h.anchor[0].get(), h.anchor[1].get(), h.anchor[2].get());
        if !anchor.iter().all(|c| c.is_finite()) {
            return Err(bad("anchor", "non-finite anchor".into()));
        }
        let word = (at + HEADER_LEN) / 4;
        let offsets: Vec<[f32; 3]> = bytemuck::cast_slice(&words[word..word + 3 * v]).to_vec();
        let triangles: Vec<[u32; 3]> =
            bytemuck::cast_slice(&words[word + 3 * v..word + 3 * v + 3 * t]).to_vec();
        if let Some(i) = offsets.iter().position(|o| !o.iter().all(|c| c.is_finite())) {
            return Err(bad("offsets", format!("vertex {i} is not finite")));
        }
        if let Some(i) = triangles.iter().position(|tr| tr.iter().any(|&x| x as usize >= v)) {
            return Err(bad("triangles", format!("triangle {i} indexes past {v} vertices")));
        }
        out.push((ObjectId(h.object_id.get()), Mesh::from_parts(anchor, offsets, triangles)));
        at = end;
    }
    if at != len {
        return Err(StorageError::corrupt(
            id,
            "data_bytes",
            format!("{} bytes after the last record", len - at),
        ));
    }
    Ok(out)
}

/// Appends a names-run record: length, UTF-8 bytes, zero padding to 4.
pub fn encode_name(name: &str, stream: &mut Vec<u8>) {
    stream.extend_from_slice(&(name.len() as u32).to_le_bytes());
    stream.extend_from_slice(name.as_bytes());
    stream.resize(stream.len().next_multiple_of(4), 0);
}

/// Decodes `records` names from a names-run stream starting at block `id`.
pub fn decode_names(id: u32, words: &[u32], len: usize, records: u32) -> Result<Vec<String>, StorageError> {
    let bytes: &[u8] = &bytemuck::cast_slice(words)[..len];
    let mut at = 0usize;
    let mut names = Vec::with_capacity(records as usize);
    for r in 0..records {
        let bad = |detail: &str| StorageError::corrupt_record(id, r, "name", detail.to_string());
        let n = bytes.get(at..at + 4).ok_or_else(|| bad("the stream ends inside a name"))?;
        let n = u32::from_le_bytes([n[0], n[1], n[2], n[3]]) as usize;
        let s = bytes.get(at + 4..at + 4 + n).ok_or_else(|| bad("a name overruns the stream"))?;
        names.push(std::str::from_utf8(s).map_err(|_| bad("not UTF-8"))?.to_string());
        at = (at + 4 + n).next_multiple_of(4);
    }
    if at != len {
        return Err(StorageError::corrupt(id, "data_bytes", "bytes after the last name"));
    }
    Ok(names)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::store::format::run;

    #[test]
    fn objects_round_trip_through_a_multi_block_run() {
        let p: Vec<Point> = (0..300).map(|i| Point::new(i as f64, (i * 7 % 13) as f64, 1e6)).collect();
        let tris: Vec<[u32; 3]> = (0..298).map(|i| [i, i + 1, i + 2]).collect();
        let m = Mesh::from_world(&p, tris).unwrap();
        let mut stream = Vec::new();
        encode_object(ObjectId(4), &m, &mut stream);
        encode_object(ObjectId(9), &m, &mut stream);
        assert_eq!(stream.len() as u64, 2 * record_len(&m));
        let blocks = run::encode(&stream, 2, 1024);
        assert_eq!(blocks.len() as u64, run::blocks_for(stream.len() as u64, 1024));
        let refs: Vec<&[u8]> = blocks.iter().map(|b| b.as_slice()).collect();
        let (n, words, len) = run::assemble(7, &refs).unwrap();
        let objs = decode_objects(7, &words, len, n).unwrap();
        assert_eq!(objs, vec![(ObjectId(4), m.clone()), (ObjectId(9), m)]);
    }

    #[test]
    fn names_round_trip() {
        let mut s = Vec::new();
        for n in ["", "PIPE-1", "välve"] {
            encode_name(n, &mut s);
        }
        let words: Vec<u32> = bytemuck::pod_collect_to_vec(&s);
        assert_eq!(decode_names(3, &words, s.len(), 3).unwrap(), vec!["", "PIPE-1", "välve"]);
    }
}
