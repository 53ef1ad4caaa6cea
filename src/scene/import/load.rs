//! The entry point: `load` picks the reader from the path (a directory, or
//! the extension), and the options and result every reader shares.

use std::fs::{self, File};
use std::path::Path;

use super::{ImportError, dir, gltf, obj, stl};
use crate::geom::Point;
use crate::scene::{Mesh, Object, Scene};

/// How to read the formats whose units or conventions differ from ours.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImportOptions {
    /// glTF coordinates are multiplied by this after the node transforms.
    /// glTF is in metres by specification, so the default, 1000.0, gives
    /// millimetres; use 1.0 for files whose authors wrote millimetres
    /// anyway (the Khronos "2 Cylinder Engine" sample is one).
    pub gltf_scale: f64,
}

impl Default for ImportOptions {
    fn default() -> ImportOptions {
        ImportOptions { gltf_scale: 1000.0 }
    }
}

/// An imported scene and what the caller should warn about.
#[derive(Debug, Clone, PartialEq)]
pub struct Imported {
    /// The objects, ids in input order.
    pub scene: Scene,
    /// Zero-area triangles (repeated corner or collinear corners). They are
    /// kept; callers print the count as a warning.
    pub degenerate_triangles: usize,
}

/// Imports the scene at `path`:
///
/// - a directory: every `.obj` and `.stl` file in it (not recursive), in
///   file-name order, one object per file named by the file stem;
/// - `.obj`: one object per `o` line (or per `g` line in a file without
///   `o`), see [`read_obj`](super::read_obj);
/// - `.stl` (ASCII or binary): one object named by the file stem;
/// - `.gltf` or `.glb`: one object per mesh instance of the default scene,
///   world transforms applied, scaled by [`ImportOptions::gltf_scale`].
///
/// Extensions are matched without regard to case.
///
/// ```
/// use mktree::scene::import::{ImportOptions, load};
/// # let dir = tempfile::tempdir().unwrap();
/// # let path = dir.path().join("plate.obj");
/// std::fs::write(&path, "o plate\nv 0 0 0\nv 10 0 0\nv 0 10 0\nf 1 2 3\n").unwrap();
/// let imported = load(&path, &ImportOptions::default()).unwrap();
/// assert_eq!(imported.scene.objects()[0].name, "plate");
/// assert_eq!(imported.scene.triangle_count(), 1);
/// ```
pub fn load(path: &Path, options: &ImportOptions) -> Result<Imported, ImportError> {
    let metadata = regular(path)?;
    if metadata.is_dir() {
        return dir::load(path);
    }
    match Format::of(path) {
        Some(Format::Obj) => load_obj(path),
        Some(Format::Stl) => {
            let (object, degenerate_triangles) = stl::load(path)?;
            Ok(Imported { scene: Scene::new(vec![object]), degenerate_triangles })
        }
        Some(Format::Gltf) => gltf::load(path, options.gltf_scale),
        None => Err(ImportError::UnsupportedExtension { file: path.into() }),
    }
}

/// [`load`] handing each object to `on_object` in id order, and returning
/// the count of zero-area triangles. OBJ files are streamed: in memory are
/// the objects being parsed and, since a face may name any earlier vertex,
/// the file's vertices, all of them without `spill_dir`, the newest 64 MB
/// with it (the others in a spill file there, read back when named). The
/// other formats are read whole first.
pub fn load_each(
    path: &Path,
    options: &ImportOptions,
    spill_dir: Option<&Path>,
    on_object: &mut dyn FnMut(Object),
) -> Result<usize, ImportError> {
    let metadata = regular(path)?;
    if !metadata.is_dir() && Format::of(path) == Some(Format::Obj) {
        return obj::each_obj_object(open(path)?, path, spill_dir, on_object);
    }
    let imported = load(path, options)?;
    imported.scene.into_objects().into_iter().for_each(on_object);
    Ok(imported.degenerate_triangles)
}

/// The metadata of `path` (links followed) if it is a regular file or a
/// directory. A FIFO, socket or device is refused before it is opened:
/// opening or reading one may wait for ever (a FIFO no one writes).
fn regular(path: &Path) -> Result<fs::Metadata, ImportError> {
    let metadata = fs::metadata(path).map_err(|source| ImportError::Io { file: path.into(), source })?;
    if !metadata.is_file() && !metadata.is_dir() {
        return Err(ImportError::NotAFile { file: path.into() });
    }
    Ok(metadata)
}

/// The file formats `load` reads, by extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Format {
    Obj,
    Stl,
    /// `.gltf` (JSON) and `.glb` (binary) alike: the decoder tells them apart.
    Gltf,
}

impl Format {
    /// The format named by the path's extension, if any (case-insensitive).
    pub(super) fn of(path: &Path) -> Option<Format> {
        let extension = path.extension()?.to_str()?.to_ascii_lowercase();
        match extension.as_str() {
            "obj" => Some(Format::Obj),
            "stl" => Some(Format::Stl),
            "gltf" | "glb" => Some(Format::Gltf),
            _ => None,
        }
    }
}

/// Opens a file to read, naming it in the error. OBJ files are read
/// unbuffered: the parser reads blocks of megabytes.
pub(super) fn open(path: &Path) -> Result<File, ImportError> {
    File::open(path).map_err(|source| ImportError::Io { file: path.into(), source })
}

fn load_obj(path: &Path) -> Result<Imported, ImportError> {
    obj::read_obj(open(path)?, path)
}

/// The name of an object that a whole file makes: the file name without
/// its extension.
pub(super) fn file_stem(path: &Path) -> String {
    path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default()
}

/// One imported object from its vertices and triangles, for every reader:
/// no triangles is an error naming the object (and its line, where the
/// format has lines); a mesh the object model refuses is wrapped likewise.
pub(super) fn object(
    file: &Path,
    name: String,
    line: Option<u64>,
    points: &[Point],
    triangles: Vec<[u32; 3]>,
) -> Result<Object, ImportError> {
    if triangles.is_empty() {
        return Err(ImportError::NoTriangles { file: file.into(), object: name, line });
    }
    let mesh = Mesh::from_world(points, triangles).map_err(|source| ImportError::Mesh {
        file: file.into(),
        object: name.clone(),
        source,
    })?;
    Ok(Object::new(name, mesh))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn extensions_are_matched_without_case() {
        assert_eq!(Format::of(Path::new("a/B.OBJ")), Some(Format::Obj));
        assert_eq!(Format::of(Path::new("b.Stl")), Some(Format::Stl));
        assert_eq!(Format::of(Path::new("c.glb")), Some(Format::Gltf));
        assert_eq!(Format::of(Path::new("c.GLTF")), Some(Format::Gltf));
        assert_eq!(Format::of(Path::new("d.ply")), None);
        assert_eq!(Format::of(Path::new("obj")), None);
    }

    #[test]
    fn an_unknown_extension_is_refused_by_name() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("scene.ply");
        std::fs::write(&path, "ply\n").unwrap();
        let err = load(&path, &ImportOptions::default()).unwrap_err();
        assert!(matches!(err, ImportError::UnsupportedExtension { .. }), "{err}");
        assert!(err.to_string().contains("scene.ply"), "{err}");
    }

    #[test]
    fn a_missing_file_is_an_io_error_naming_it() {
        let err = load(Path::new("/nonexistent/ship.obj"), &ImportOptions::default()).unwrap_err();
        assert!(matches!(err, ImportError::Io { .. }), "{err}");
        assert!(err.to_string().contains("/nonexistent/ship.obj"), "{err}");
    }

    #[test]
    fn file_stem_drops_folder_and_extension() {
        assert_eq!(file_stem(Path::new("/a/b/pump.room.obj")), "pump.room");
        assert_eq!(file_stem(Path::new("")), "");
    }
}
