//! glTF 2.0 import (`.gltf` with embedded or external buffers, `.glb`)
//! through the `gltf` crate: one object per mesh instance in the default
//! scene's node hierarchy (every scene's, in order, when there is no
//! default), depth first, children in listed order. Each object gets its
//! node's world transform (parent * child, computed in f64), then the
//! import scale (glTF is in metres), and all triangle primitives of the mesh
//! merged; strips and fans become triangles; points and lines are skipped,
//! and an instance of a mesh without any triangle primitive makes no object.
//! Objects are named `<mesh name>_node<node index>`, or
//! `mesh<mesh index>_node<node index>` for an unnamed mesh.
//!
//! Guards: the `gltf` crates trust some input they do not validate (an
//! accessor's byte range, a GLB header's length, a buffer URI's percent
//! escapes, a POSITION accessor index during validation) and would panic on
//! it, so those are checked here first. Buffer files are opened here, not by
//! `gltf`, which would follow any path and read any stream to its end: only
//! regular files in the glTF file's folder are read, and only up to the
//! buffer's `byteLength`. Images are not needed for geometry and never read. Sparse and quantised (non-f32)
//! position accessors are refused with a message.
//! A mirroring transform (negative determinant) reverses the winding, as
//! the glTF specification asks, so faces keep their orientation.

use std::fs::File;
use std::io::Read;
use std::path::{Component, Path, PathBuf};

use ::gltf::accessor::{DataType, Dimensions};
use ::gltf::mesh::Mode;
use ::gltf::{Accessor, Document, Gltf, Node, Primitive, buffer};
use nalgebra::Matrix4;
use rayon::prelude::*;

use super::{ImportError, Imported, Location, UriRefusal};
use crate::geom::Point;
use crate::scene::{MeshError, Object, Scene};

/// Reads the glTF or GLB file at `path`; coordinates are multiplied by
/// `scale` after the node transforms.
pub(super) fn load(path: &Path, scale: f64) -> Result<Imported, ImportError> {
    let bytes = std::fs::read(path).map_err(|source| ImportError::Io { file: path.into(), source })?;
    let gltf_error = |message: String| ImportError::Gltf { file: path.into(), message };
    check_glb_header(&bytes).map_err(gltf_error)?;
    let Gltf { document, blob } =
        Gltf::from_slice_without_validation(&bytes).map_err(|e| gltf_error(e.to_string()))?;
    drop(bytes);
    check_position_references(document.as_json()).map_err(gltf_error)?;
    let document = Document::from_json(document.into_json()).map_err(|e| gltf_error(e.to_string()))?;
    let buffers = load_buffers(&document, path, blob)?;

    // Instances are built at once, then taken in order: the first error in
    // file order is the one reported, as if built one by one.
    let built: Vec<Result<Option<(Object, usize)>, ImportError>> = instances(&document, scale)
        .map_err(gltf_error)?
        .par_iter()
        .map(|instance| {
            let object = instance.object(&buffers, path)?;
            Ok(object.map(|object| {
                let degenerate = object.mesh.degenerate_triangles();
                (object, degenerate)
            }))
        })
        .collect();
    let mut scene = Scene::default();
    let mut degenerate_triangles = 0;
    for result in built {
        if let Some((object, degenerate)) = result? {
            degenerate_triangles += degenerate;
            scene.push(object);
        }
    }
    if scene.is_empty() {
        return Err(ImportError::EmptyScene { file: path.into() });
    }
    Ok(Imported { scene, degenerate_triangles })
}

/// A GLB file's header must hold its own 12 bytes: `gltf` 1.4 subtracts
/// them from the declared length before comparing.
fn check_glb_header(bytes: &[u8]) -> Result<(), String> {
    if !bytes.starts_with(b"glTF") {
        return Ok(());
    }
    let declared = bytes.get(8..12).and_then(|b| b.try_into().ok()).map(u32::from_le_bytes);
    match declared {
        Some(length) if (12..=bytes.len() as u64).contains(&u64::from(length)) => Ok(()),
        Some(length) => Err(format!("GLB header declares {length} bytes, the file has {}", bytes.len())),
        None => Err(format!("GLB file of {} bytes is shorter than its 12-byte header", bytes.len())),
    }
}

/// Every POSITION attribute must name an accessor that exists: `gltf-json`
/// 1.4's validation indexes the accessors with it before checking.
fn check_position_references(root: &::gltf::json::Root) -> Result<(), String> {
    let positions = ::gltf::json::validation::Checked::Valid(::gltf::Semantic::Positions);
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            if let Some(accessor) = primitive.attributes.get(&positions)
                && accessor.value() >= root.accessors.len()
            {
                return Err(format!(
                    "mesh {m}, primitive {p}: POSITION names accessor {}, but there are {}",
                    accessor.value(),
                    root.accessors.len()
                ));
            }
        }
    }
    Ok(())
}

/// Every buffer's bytes, exactly its declared `byteLength`: the GLB binary
/// chunk, a base64 `data:` URI, or a file in the glTF file's folder (see
/// [`UriRefusal`] for what is refused). Images are never read.
fn load_buffers(
    document: &Document,
    path: &Path,
    mut blob: Option<Vec<u8>>,
) -> Result<Vec<Vec<u8>>, ImportError> {
    let gltf_error = |message: String| ImportError::Gltf { file: path.into(), message };
    let mut buffers = Vec::new();
    for buffer in document.buffers() {
        let index = buffer.index();
        let declared = buffer.length();
        let mut data = match buffer.source() {
            buffer::Source::Uri(uri) => match uri.strip_prefix("data:") {
                Some(data) => {
                    decode_data_uri(data).map_err(|e| gltf_error(format!("buffer {index}: {e}")))?
                }
                None => {
                    let uri = BufferUri { gltf: path, buffer: index, uri };
                    uri.read(&uri.file()?, declared)?
                }
            },
            buffer::Source::Bin => {
                blob.take().ok_or_else(|| gltf_error(format!("buffer {index}: no GLB binary chunk")))?
            }
        };
        if data.len() < declared {
            return Err(gltf_error(format!(
                "buffer {index}: declares {declared} bytes but has {}",
                data.len()
            )));
        }
        // The specification bounds every view by byteLength, not by the padding after it.
        data.truncate(declared);
        buffers.push(data);
    }
    Ok(buffers)
}

/// The bytes of a `data:` URI after its scheme: `[media type];base64,` and
/// the base64 text (the only encoding glTF buffers use). Its length bounds
/// the allocation.
fn decode_data_uri(uri: &str) -> Result<Vec<u8>, String> {
    use base64::Engine;
    let (head, text) = uri.split_once(',').ok_or("a data: URI without a comma")?;
    if !head.ends_with(";base64") {
        return Err(format!("a data: URI that is not base64 ({head:?})"));
    }
    base64::engine::general_purpose::STANDARD.decode(text).map_err(|e| format!("its base64: {e}"))
}

/// The URI of buffer `buffer` of the glTF file at `gltf`, not a `data:` URI.
struct BufferUri<'a> {
    gltf: &'a Path,
    buffer: usize,
    uri: &'a str,
}

impl BufferUri<'_> {
    fn refused(&self, reason: UriRefusal) -> ImportError {
        ImportError::BufferUri { file: self.gltf.into(), buffer: self.buffer, uri: self.uri.into(), reason }
    }

    /// The file the URI names, resolved (symbolic links followed) and
    /// checked to be a regular file in the glTF file's folder or below.
    fn file(&self) -> Result<PathBuf, ImportError> {
        // A colon before any slash ends a scheme (RFC 3986).
        if self.uri.split('/').next().is_some_and(|first| first.contains(':')) {
            return Err(self.refused(UriRefusal::Scheme));
        }
        let decoded = percent_decode(self.uri).ok_or_else(|| self.refused(UriRefusal::NotUtf8))?;
        let relative = Path::new(&decoded);
        let mut depth = 0usize;
        for component in relative.components() {
            depth = match component {
                Component::Normal(_) => depth + 1,
                Component::CurDir => depth,
                Component::ParentDir => {
                    depth.checked_sub(1).ok_or_else(|| self.refused(UriRefusal::OutsideFolder))?
                }
                Component::RootDir | Component::Prefix(_) => return Err(self.refused(UriRefusal::Absolute)),
            };
        }
        let folder = match self.gltf.parent() {
            Some(folder) if !folder.as_os_str().is_empty() => folder,
            _ => Path::new("."),
        };
        let joined = folder.join(relative);
        // Symbolic links (and `..` after one) may lead anywhere: compare where the path truly ends.
        let root = folder.canonicalize().map_err(io_error(folder))?;
        let target = joined.canonicalize().map_err(io_error(&joined))?;
        if !target.starts_with(&root) {
            return Err(self.refused(UriRefusal::OutsideFolder));
        }
        // Checked before opening: opening a pipe waits for a writer.
        if !std::fs::metadata(&target).map_err(io_error(&target))?.is_file() {
            return Err(self.refused(UriRefusal::NotAFile));
        }
        Ok(target)
    }

    /// The first `declared` bytes of the regular file at `path`; refused
    /// when the file is shorter, so that the allocation is bounded by the file.
    fn read(&self, path: &Path, declared: usize) -> Result<Vec<u8>, ImportError> {
        let file = File::open(path).map_err(io_error(path))?;
        let metadata = file.metadata().map_err(io_error(path))?;
        // Again on the open file: the path may have been replaced since it was checked.
        if !metadata.is_file() {
            return Err(self.refused(UriRefusal::NotAFile));
        }
        let short = |actual| self.refused(UriRefusal::Short { declared: declared as u64, actual });
        if metadata.len() < declared as u64 {
            return Err(short(metadata.len()));
        }
        let mut data = Vec::with_capacity(declared);
        file.take(declared as u64).read_to_end(&mut data).map_err(io_error(path))?;
        if data.len() < declared {
            return Err(short(data.len() as u64));
        }
        Ok(data)
    }
}

fn io_error(file: &Path) -> impl FnOnce(std::io::Error) -> ImportError {
    let file = file.to_path_buf();
    move |source| ImportError::Io { file, source }
}

/// `uri` with its percent escapes decoded; `None` when that is not UTF-8.
fn percent_decode(uri: &str) -> Option<String> {
    let bytes = uri.as_bytes();
    let mut decoded = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while let Some(&b) = bytes.get(i) {
        let escaped = bytes.get(i + 1..i + 3).and_then(|hex| std::str::from_utf8(hex).ok());
        match escaped.and_then(|hex| u8::from_str_radix(hex, 16).ok()) {
            Some(byte) if b == b'%' => {
                decoded.push(byte);
                i += 3;
            }
            _ => {
                decoded.push(b);
                i += 1;
            }
        }
    }
    String::from_utf8(decoded).ok()
}

/// One node that instances a mesh, with its world transform.
struct Instance<'a> {
    node: Node<'a>,
    mesh: ::gltf::Mesh<'a>,
    /// Import scale * root transform * ... * this node's transform.
    world: Matrix4<f64>,
}

/// The mesh instances of the default scene (or of every scene), in depth
/// first order.
fn instances(document: &Document, scale: f64) -> Result<Vec<Instance<'_>>, String> {
    let scenes: Vec<_> = match document.default_scene() {
        Some(scene) => vec![scene],
        None => document.scenes().collect(),
    };
    let root = Matrix4::new_scaling(scale);
    let mut instances = Vec::new();
    for scene in scenes {
        // The hierarchy must be a forest: a node met twice is shared or in a
        // cycle, and walking it would repeat objects or never end.
        let mut seen = vec![false; document.nodes().len()];
        // An explicit stack: a deep hierarchy must not overflow the call stack.
        let mut stack: Vec<(Node, Matrix4<f64>)> = scene.nodes().map(|n| (n, root)).collect();
        stack.reverse();
        while let Some((node, parent)) = stack.pop() {
            let seen_before = seen.get_mut(node.index()).map(|s| std::mem::replace(s, true));
            if seen_before != Some(false) {
                return Err(format!(
                    "node {} occurs twice in the hierarchy of scene {}: nodes must form trees",
                    node.index(),
                    scene.index()
                ));
            }
            let world = parent * local_transform(&node);
            let first_child = stack.len();
            stack.extend(node.children().map(|child| (child, world)));
            stack[first_child..].reverse();
            if let Some(mesh) = node.mesh() {
                instances.push(Instance { node, mesh, world });
            }
        }
    }
    Ok(instances)
}

/// A node's transform in f64, composed as the specification says (T * R * S),
/// so no precision is lost to f32 before the world transform.
fn local_transform(node: &Node) -> Matrix4<f64> {
    match node.transform() {
        ::gltf::scene::Transform::Matrix { matrix } => {
            Matrix4::from_fn(|row, column| f64::from(matrix[column][row]))
        }
        ::gltf::scene::Transform::Decomposed { translation: t, rotation: r, scale: s } => {
            let [x, y, z, w] = r.map(f64::from);
            let rotation = nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(w, x, y, z));
            let t = nalgebra::Vector3::from(t.map(f64::from));
            let s = nalgebra::Vector3::from(s.map(f64::from));
            Matrix4::new_translation(&t) * rotation.to_homogeneous() * Matrix4::new_nonuniform_scaling(&s)
        }
    }
}

impl Instance<'_> {
    fn name(&self) -> String {
        match self.mesh.name() {
            Some(name) if !name.is_empty() => format!("{name}_node{}", self.node.index()),
            _ => format!("mesh{}_node{}", self.mesh.index(), self.node.index()),
        }
    }

    /// The object of this instance, or `None` when its mesh has no triangle
    /// primitive (only points or lines).
    fn object(&self, buffers: &[Vec<u8>], path: &Path) -> Result<Option<Object>, ImportError> {
        let name = self.name();
        let mirrored = self.world.fixed_view::<3, 3>(0, 0).determinant() < 0.0;
        let mut points: Vec<Point> = Vec::new();
        let mut triangles: Vec<[u32; 3]> = Vec::new();
        let mut any_triangle_primitive = false;
        for primitive in self.mesh.primitives() {
            if !matches!(primitive.mode(), Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan) {
                continue;
            }
            any_triangle_primitive = true;
            let at = Location::Primitive {
                node: self.node.index(),
                mesh: self.mesh.index(),
                primitive: primitive.index(),
            };
            let gltf_error = |message: String| ImportError::Gltf {
                file: path.into(),
                message: format!("{at}: {message}"),
            };
            let (positions, corners) = read_primitive(&primitive, buffers).map_err(gltf_error)?;
            if let Some(&index) = corners.iter().find(|&&i| i as usize >= positions.len()) {
                return Err(ImportError::IndexOutOfRange {
                    file: path.into(),
                    object: name,
                    at,
                    index: index.into(),
                    vertices: positions.len(),
                });
            }
            // Indices are u32: the merged mesh must stay addressable.
            let vertices = points.len() + positions.len();
            if u32::try_from(vertices).is_err() {
                return Err(ImportError::Mesh {
                    file: path.into(),
                    object: name,
                    source: MeshError::TooManyVertices { vertices },
                });
            }
            let base = points.len() as u32;
            let start = points.len();
            points
                .extend(positions.iter().map(|p| self.world.transform_point(&Point::from(p.map(f64::from)))));
            if !points[start..].iter().all(|p| p.iter().all(|c| c.is_finite())) {
                return Err(ImportError::NonFiniteCoordinate { file: path.into(), object: name, at });
            }
            let assembled = assemble(primitive.mode(), &corners).map_err(gltf_error)?;
            triangles.extend(assembled.into_iter().map(|t| {
                let [a, b, c] = t.map(|i| base + i);
                if mirrored { [a, c, b] } else { [a, b, c] }
            }));
        }
        if !any_triangle_primitive {
            return Ok(None);
        }
        super::load::object(path, name, None, &points, triangles).map(Some)
    }
}

/// A primitive's positions and its vertex order (its indices, or 0..n).
fn read_primitive(primitive: &Primitive, buffers: &[Vec<u8>]) -> Result<(Vec<[f32; 3]>, Vec<u32>), String> {
    let positions_accessor = primitive.get(&::gltf::Semantic::Positions).ok_or("no POSITION attribute")?;
    check_accessor(&positions_accessor, buffers, &[DataType::F32], Dimensions::Vec3)?;
    let reader = primitive.reader(|b| buffers.get(b.index()).map(Vec::as_slice));
    let positions: Vec<[f32; 3]> =
        reader.read_positions().ok_or("the POSITION accessor could not be read")?.collect();
    let corners: Vec<u32> = match primitive.indices() {
        Some(accessor) => {
            check_accessor(
                &accessor,
                buffers,
                &[DataType::U8, DataType::U16, DataType::U32],
                Dimensions::Scalar,
            )?;
            reader.read_indices().ok_or("the index accessor could not be read")?.into_u32().collect()
        }
        None => (0..u32::try_from(positions.len()).map_err(|_| "too many vertices")?).collect(),
    };
    Ok((positions, corners))
}

/// Checks what `gltf`'s accessor reader assumes and does not check: the
/// element type, and that every element lies inside its view and buffer.
fn check_accessor(
    accessor: &Accessor,
    buffers: &[Vec<u8>],
    types: &[DataType],
    dimensions: Dimensions,
) -> Result<(), String> {
    let index = accessor.index();
    if !types.contains(&accessor.data_type()) || accessor.dimensions() != dimensions {
        return Err(format!(
            "accessor {index} is {:?} {:?}, expected {dimensions:?} of {types:?}",
            accessor.dimensions(),
            accessor.data_type()
        ));
    }
    if accessor.sparse().is_some() {
        return Err(format!("accessor {index} is sparse, which is not supported"));
    }
    let view = accessor.view().ok_or_else(|| format!("accessor {index} has no buffer view"))?;
    let element = accessor.size();
    let stride = view.stride().unwrap_or(element);
    let last = accessor.count().checked_sub(1).ok_or_else(|| format!("accessor {index} is empty"))?;
    let end = stride
        .checked_mul(last)
        .and_then(|s| s.checked_add(element))
        .and_then(|s| s.checked_add(accessor.offset()));
    let view_end = view.offset().checked_add(view.length());
    let buffer_length = buffers.get(view.buffer().index()).map(|b| b.len());
    match (end, view_end, buffer_length) {
        _ if stride < element => Err(format!("accessor {index}: stride {stride} is smaller than an element")),
        (Some(end), Some(view_end), Some(buffer_length))
            if end <= view.length() && view_end <= buffer_length =>
        {
            Ok(())
        }
        _ => Err(format!("accessor {index} reaches past the end of buffer view {}", view.index())),
    }
}

/// Triangles from a primitive's vertex order, as the specification's
/// section 3.7.2.1 lists them for each mode.
fn assemble(mode: Mode, v: &[u32]) -> Result<Vec<[u32; 3]>, String> {
    let n = v.len();
    Ok(match mode {
        Mode::Triangles if !n.is_multiple_of(3) => {
            return Err(format!("{n} vertex indices do not make whole triangles"));
        }
        Mode::Triangles => v.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect(),
        Mode::TriangleStrip => v
            .windows(3)
            .enumerate()
            .map(|(i, t)| if i % 2 == 0 { [t[0], t[1], t[2]] } else { [t[0], t[2], t[1]] })
            .collect(),
        Mode::TriangleFan => v.get(1..).unwrap_or_default().windows(2).map(|t| [t[0], t[1], v[0]]).collect(),
        _ => Vec::new(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn data_uris_are_base64_or_refused() {
        assert_eq!(decode_data_uri("application/octet-stream;base64,AAEC"), Ok(vec![0, 1, 2]));
        assert_eq!(decode_data_uri("application/gltf-buffer;base64,"), Ok(vec![]));
        assert!(decode_data_uri("application/octet-stream,%00%01").unwrap_err().contains("not base64"));
        assert!(decode_data_uri("application/octet-stream;base64,A$==").unwrap_err().contains("base64"));
        assert!(decode_data_uri("no comma").unwrap_err().contains("comma"));
    }

    #[test]
    fn strips_and_fans_follow_the_specification() {
        assert_eq!(
            assemble(Mode::TriangleStrip, &[0, 1, 2, 3, 4]).unwrap(),
            [[0, 1, 2], [1, 3, 2], [2, 3, 4]]
        );
        assert_eq!(assemble(Mode::TriangleFan, &[0, 1, 2, 3]).unwrap(), [[1, 2, 0], [2, 3, 0]]);
        assert_eq!(assemble(Mode::Triangles, &[5, 6, 7]).unwrap(), [[5, 6, 7]]);
        assert!(assemble(Mode::Triangles, &[5, 6]).is_err());
        assert!(assemble(Mode::TriangleStrip, &[5, 6]).unwrap().is_empty());
        assert!(assemble(Mode::TriangleFan, &[]).unwrap().is_empty());
        assert!(assemble(Mode::Lines, &[1, 2]).unwrap().is_empty());
    }

    #[test]
    fn a_glb_header_shorter_than_itself_is_refused() {
        let mut bytes = b"glTF\x02\0\0\0\x04\0\0\0".to_vec();
        assert!(check_glb_header(&bytes).unwrap_err().contains("declares 4 bytes"));
        bytes.truncate(9);
        assert!(check_glb_header(&bytes).unwrap_err().contains("shorter than its 12-byte header"));
        assert!(check_glb_header(b"{\"asset\":{}}").is_ok());
    }

    #[test]
    fn percent_escapes_are_decoded_and_checked_for_utf8() {
        assert_eq!(percent_decode("buffer%20one.bin").as_deref(), Some("buffer one.bin"));
        assert_eq!(percent_decode("100%.bin").as_deref(), Some("100%.bin"));
        assert_eq!(percent_decode("%C3%A9.bin").as_deref(), Some("é.bin"));
        assert_eq!(percent_decode("%FF.bin"), None);
    }

    #[test]
    fn decomposed_transforms_are_translation_rotation_scale() {
        let json = r#"{"asset":{"version":"2.0"},"nodes":[{"translation":[1,2,3],"rotation":[0,0,1,0],"scale":[2,2,2]}]}"#;
        let gltf = Gltf::from_slice(json.as_bytes()).unwrap();
        let node = gltf.document.nodes().next().unwrap();
        let m = local_transform(&node);
        // 180 degrees about z, then doubled, then moved.
        let p = m.transform_point(&Point::new(1.0, 0.0, 0.0));
        assert!((p - Point::new(-1.0, 2.0, 3.0)).norm() < 1e-12, "{p}");
    }
}
