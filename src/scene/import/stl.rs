//! STL import (ASCII and binary) through `stl_io`: one object per file,
//! named by the file stem. STL has no units; we take them as millimetres, as
//! CAD exporters write them.
//!
//! Two real-world departures from `stl_io`'s format test are settled here,
//! before it sees the bytes: several CAD exporters write the word `solid`
//! at the start of a *binary* header, which `stl_io` would read as ASCII,
//! so a file whose size is exactly what its binary header announces
//! (84 + 50 n bytes) is read as binary; and an ASCII file that opens with
//! `solid` alone on its line (no name) gets the space `stl_io` expects.
//! Vertices are shared between facets when their coordinates are equal bit
//! for bit, in order of first use.

use std::io::Cursor;
use std::path::Path;

use super::load::file_stem;
use super::{ImportError, Location};
use crate::geom::Point;
use crate::scene::{MeshError, Object};

const BINARY_HEADER_BYTES: u64 = 84;
const BINARY_FACET_BYTES: u64 = 50;

/// Reads the STL file at `path` as one object; returns it with its count
/// of zero-area triangles.
pub(super) fn load(path: &Path) -> Result<(Object, usize), ImportError> {
    let bytes = std::fs::read(path).map_err(|source| ImportError::Io { file: path.into(), source })?;
    let bytes = prepare(bytes, path)?;
    let name = file_stem(path);
    let stl_error = |message: String| ImportError::Stl { file: path.into(), message };

    let mut cursor = Cursor::new(bytes);
    let facets = stl_io::create_stl_reader(&mut cursor).map_err(|e| stl_error(e.to_string()))?;
    let mut points: Vec<Point> = Vec::new();
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    // Fx rather than std's DoS-proof hash: the keys are coordinates, and
    // hashing them is most of the reading.
    let mut index_of: rustc_hash::FxHashMap<[u32; 3], u32> = Default::default();
    for (facet, read) in facets.enumerate() {
        let facet = facet as u64;
        let triangle = read.map_err(|e| stl_error(format!("facet {facet}: {e}")))?;
        let mut corners = [0u32; 3];
        for (corner, vertex) in corners.iter_mut().zip(triangle.vertices) {
            if !vertex.0.iter().all(|c| c.is_finite()) {
                return Err(ImportError::NonFiniteCoordinate {
                    file: path.into(),
                    object: name,
                    at: Location::Facet(facet),
                });
            }
            let next = u32::try_from(points.len()).map_err(|_| ImportError::Mesh {
                file: path.into(),
                object: name.clone(),
                source: MeshError::TooManyVertices { vertices: points.len() + 1 },
            })?;
            *corner = *index_of.entry(vertex.0.map(f32::to_bits)).or_insert_with(|| {
                points.push(Point::new(vertex[0].into(), vertex[1].into(), vertex[2].into()));
                next
            });
        }
        triangles.push(corners);
    }
    let object = super::load::object(path, name, None, &points, triangles)?;
    let degenerate_triangles = object.mesh.degenerate_triangles();
    Ok((object, degenerate_triangles))
}

/// Decides ASCII or binary and returns bytes that `stl_io` reads that way,
/// or the error for a binary file shorter than its header announces.
fn prepare(mut bytes: Vec<u8>, path: &Path) -> Result<Vec<u8>, ImportError> {
    let actual_bytes = bytes.len() as u64;
    let announced_facets =
        bytes.get(80..84).and_then(|b| b.try_into().ok()).map(|b: [u8; 4]| u64::from(u32::from_le_bytes(b)));
    let binary_bytes = announced_facets.map(|n| BINARY_HEADER_BYTES + BINARY_FACET_BYTES * n);
    let says_solid = bytes.starts_with(b"solid") && bytes.get(5).is_none_or(u8::is_ascii_whitespace);

    if says_solid && binary_bytes == Some(actual_bytes) {
        // A binary header that starts with "solid": blank it (binary readers
        // ignore the header) so stl_io does not take the file for ASCII.
        bytes[0] = b'_';
        return Ok(bytes);
    }
    if says_solid {
        if !bytes.starts_with(b"solid ") {
            bytes.insert(5, b' ');
        }
        return Ok(bytes);
    }
    match (announced_facets, binary_bytes) {
        (Some(facets), Some(expected_bytes)) if actual_bytes < expected_bytes => {
            Err(ImportError::Truncated { file: path.into(), facets, expected_bytes, actual_bytes })
        }
        (Some(_), Some(_)) => Ok(bytes),
        _ => Err(ImportError::Stl {
            file: path.into(),
            message: format!(
                "not ASCII STL (no \"solid\") and shorter ({actual_bytes} bytes) than a binary STL header \
                 ({BINARY_HEADER_BYTES} bytes)"
            ),
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn binary(header: &[u8], facets: &[[[f32; 3]; 3]], announced: u32) -> Vec<u8> {
        let mut bytes = header.to_vec();
        bytes.resize(80, b' ');
        bytes.extend_from_slice(&announced.to_le_bytes());
        for facet in facets {
            bytes.extend_from_slice(&[0u8; 12]);
            for c in facet.as_flattened() {
                bytes.extend_from_slice(&c.to_le_bytes());
            }
            bytes.extend_from_slice(&[0u8; 2]);
        }
        bytes
    }

    fn load_bytes(bytes: &[u8]) -> Result<(Object, usize), ImportError> {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("part.stl");
        std::fs::write(&path, bytes).unwrap();
        load(&path)
    }

    const TRIANGLE: [[f32; 3]; 3] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    const SECOND: [[f32; 3]; 3] = [[1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]];

    #[test]
    fn binary_facets_share_equal_vertices() {
        let (object, degenerate) = load_bytes(&binary(b"exporter", &[TRIANGLE, SECOND], 2)).unwrap();
        assert_eq!(object.name, "part");
        assert_eq!((object.mesh.vertex_count(), object.mesh.triangles()), (4, &[[0, 1, 2], [1, 3, 2]][..]));
        assert_eq!(degenerate, 0);
    }

    #[test]
    fn a_binary_header_starting_with_solid_is_still_binary() {
        let (object, _) = load_bytes(&binary(b"solid part by a CAD tool", &[TRIANGLE], 1)).unwrap();
        assert_eq!(object.mesh.triangle_count(), 1);
    }

    #[test]
    fn ascii_with_a_bare_solid_line_is_read() {
        let text = "solid\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\n\
                    endloop\nendfacet\nendsolid\n";
        let (object, _) = load_bytes(text.as_bytes()).unwrap();
        assert_eq!(object.mesh.triangle_count(), 1);
    }

    #[test]
    fn a_short_binary_file_is_truncated_with_the_counts() {
        let mut bytes = binary(b"x", &[TRIANGLE, SECOND], 3);
        bytes.truncate(bytes.len() - 1);
        let err = load_bytes(&bytes).unwrap_err().to_string();
        assert!(
            err.ends_with(
                "part.stl: truncated: the header announces 3 facets (234 bytes), but the file has 183 bytes"
            ),
            "{err}"
        );
        let err = load_bytes(b"tiny").unwrap_err().to_string();
        assert!(err.contains("shorter (4 bytes) than a binary STL header"), "{err}");
    }

    #[test]
    fn a_nan_vertex_names_the_facet() {
        let nan = [[0.0, 0.0, 0.0], [f32::NAN, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let err = load_bytes(&binary(b"x", &[TRIANGLE, nan], 2)).unwrap_err().to_string();
        assert!(
            err.ends_with("part.stl: facet 1: object \"part\" has a NaN or infinite coordinate"),
            "{err}"
        );
    }

    #[test]
    fn no_facets_is_an_object_without_triangles() {
        let err = load_bytes(&binary(b"x", &[], 0)).unwrap_err().to_string();
        assert!(err.ends_with("part.stl: object \"part\" has no triangles"), "{err}");
    }

    #[test]
    fn malformed_ascii_names_the_facet_and_what_was_expected() {
        let text = "solid s\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0\n";
        let err = load_bytes(text.as_bytes()).unwrap_err().to_string();
        assert!(err.contains("part.stl: STL: facet 0: vertex f32 f32 f32"), "{err}");
    }
}
