//! Why an import failed: one enum for every format, each variant naming the
//! file and the object, line, facet or glTF node at fault.

use std::fmt;
use std::io;
use std::path::PathBuf;

use crate::scene::MeshError;

/// Where in an input file an error was found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum Location {
    /// A 1-based line of an OBJ file.
    Line(u64),
    /// A 0-based facet (triangle) of an STL file.
    Facet(u64),
    /// A primitive of the mesh that a glTF node instances (all 0-based).
    Primitive {
        /// The glTF node.
        node: usize,
        /// The mesh the node instances.
        mesh: usize,
        /// The primitive within that mesh.
        primitive: usize,
    },
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Location::Line(line) => write!(f, "line {line}"),
            Location::Facet(facet) => write!(f, "facet {facet}"),
            Location::Primitive { node, mesh, primitive } => {
                write!(f, "node {node}, mesh {mesh}, primitive {primitive}")
            }
        }
    }
}

/// Why a scene could not be imported. Every message starts with the file;
/// the cause, if any, is the `source()`, not repeated in the message.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ImportError {
    /// The file or directory could not be opened or read.
    #[error("cannot read {}", file.display())]
    Io {
        /// The file or directory.
        file: PathBuf,
        /// The operating system's error.
        #[source]
        source: io::Error,
    },
    /// The path names a FIFO, socket or device, not a file or directory.
    #[error("{} is not a regular file or a directory (a FIFO, socket or device is not read)", file.display())]
    NotAFile {
        /// The path given.
        file: PathBuf,
    },
    /// A line of an OBJ file is not what the format allows there.
    #[error("{}: line {line}: expected {expected}, found {found:?}", file.display())]
    Malformed {
        /// The OBJ file.
        file: PathBuf,
        /// The 1-based line.
        line: u64,
        /// What the format allows there.
        expected: &'static str,
        /// The text found instead.
        found: String,
    },
    /// A binary STL file ends before the facets its header announces.
    #[error(
        "{}: truncated: the header announces {facets} facets ({expected_bytes} bytes), \
         but the file has {actual_bytes} bytes",
        file.display()
    )]
    Truncated {
        /// The STL file.
        file: PathBuf,
        /// The facet count in the header.
        facets: u64,
        /// The file size those facets need, in bytes.
        expected_bytes: u64,
        /// The file's size, in bytes.
        actual_bytes: u64,
    },
    /// A coordinate is NaN or infinite (after the transform, for glTF).
    #[error("{}: {at}: object {object:?} has a NaN or infinite coordinate", file.display())]
    NonFiniteCoordinate {
        /// The input file.
        file: PathBuf,
        /// The object's name.
        object: String,
        /// Where the coordinate is.
        at: Location,
    },
    /// A face refers to a vertex that does not exist. For OBJ, `index` is
    /// the index as written (1-based, or negative for relative) and
    /// `vertices` the number defined before that line.
    #[error(
        "{}: {at}: object {object:?}: vertex index {index} is out of range ({vertices} vertices)",
        file.display()
    )]
    IndexOutOfRange {
        /// The input file.
        file: PathBuf,
        /// The object's name.
        object: String,
        /// Where the face is.
        at: Location,
        /// The vertex index as written.
        index: i64,
        /// The number of vertices it may refer to.
        vertices: usize,
    },
    /// An object has no triangles; `line` is the line of its OBJ `o`.
    #[error("{}: object {object:?}{} has no triangles", file.display(), at_line(*line))]
    NoTriangles {
        /// The input file.
        file: PathBuf,
        /// The object's name.
        object: String,
        /// The 1-based line of its OBJ `o`, when it has one.
        line: Option<u64>,
    },
    /// The file or directory holds no object at all.
    #[error("{}: the scene is empty: no object has a triangle", file.display())]
    EmptyScene {
        /// The file or directory.
        file: PathBuf,
    },
    /// The file name has no extension that `load` knows.
    #[error("{}: unsupported file type (expected .obj, .stl, .gltf, .glb or a directory)", file.display())]
    UnsupportedExtension {
        /// The path given.
        file: PathBuf,
    },
    /// The STL decoder refused the file.
    #[error("{}: STL: {message}", file.display())]
    Stl {
        /// The STL file.
        file: PathBuf,
        /// The decoder's message.
        message: String,
    },
    /// The glTF decoder refused the file, or its data is inconsistent.
    #[error("{}: glTF: {message}", file.display())]
    Gltf {
        /// The glTF or GLB file.
        file: PathBuf,
        /// What is wrong, from the decoder or the importer.
        message: String,
    },
    /// A glTF buffer's URI that the importer will not follow, or whose
    /// file does not hold the buffer.
    #[error("{}: glTF: buffer {buffer}: URI {uri:?} {reason}", file.display())]
    BufferUri {
        /// The glTF file.
        file: PathBuf,
        /// The 0-based buffer index.
        buffer: usize,
        /// The buffer's URI as written.
        uri: String,
        /// Why it is refused.
        reason: UriRefusal,
    },
    /// The mesh of an object was refused (for example, too many vertices).
    #[error("{}: object {object:?}", file.display())]
    Mesh {
        /// The input file.
        file: PathBuf,
        /// The object's name.
        object: String,
        /// Why the mesh was refused.
        #[source]
        source: MeshError,
    },
}

/// Why a glTF buffer URI is refused. A buffer is read only from a `data:`
/// URI or from a regular file in the glTF file's folder or below, and never
/// beyond its declared `byteLength`: a document cannot make the importer
/// read another file, a device or a pipe, or more bytes than the file has.
#[derive(Debug, Clone, PartialEq, Eq)]
#[non_exhaustive]
pub enum UriRefusal {
    /// A scheme other than `data:` (`file:`, `https:`, ...).
    Scheme,
    /// Percent escapes that do not decode to UTF-8.
    NotUtf8,
    /// An absolute path.
    Absolute,
    /// A path out of the glTF file's folder, by `..` or a symbolic link.
    OutsideFolder,
    /// Not a regular file: a folder, a device, a pipe.
    NotAFile,
    /// A file shorter than the buffer's declared `byteLength`.
    Short {
        /// The buffer's `byteLength`, in bytes.
        declared: u64,
        /// The file's size, in bytes.
        actual: u64,
    },
}

impl fmt::Display for UriRefusal {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            UriRefusal::Scheme => write!(f, "is not a relative path or a data: URI"),
            UriRefusal::NotUtf8 => write!(f, "has percent escapes that are not UTF-8"),
            UriRefusal::Absolute => {
                write!(f, "is an absolute path; buffers must be relative to the glTF file")
            }
            UriRefusal::OutsideFolder => write!(f, "leads out of the glTF file's folder"),
            UriRefusal::NotAFile => write!(f, "is not a regular file"),
            UriRefusal::Short { declared, actual } => {
                write!(f, "has {actual} bytes, fewer than the {declared} its byteLength declares")
            }
        }
    }
}

/// " (line N)" when the line is known.
fn at_line(line: Option<u64>) -> String {
    line.map(|l| format!(" (line {l})")).unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_name_the_file_and_the_place() {
        let e = ImportError::IndexOutOfRange {
            file: "ship.obj".into(),
            object: "pipe".into(),
            at: Location::Line(12),
            index: -40,
            vertices: 30,
        };
        assert_eq!(
            e.to_string(),
            "ship.obj: line 12: object \"pipe\": vertex index -40 is out of range (30 vertices)"
        );
        let e = ImportError::NoTriangles { file: "a.obj".into(), object: "x".into(), line: Some(3) };
        assert_eq!(e.to_string(), "a.obj: object \"x\" (line 3) has no triangles");
        let e = ImportError::NoTriangles { file: "a.stl".into(), object: "a".into(), line: None };
        assert_eq!(e.to_string(), "a.stl: object \"a\" has no triangles");
        let at = Location::Primitive { node: 4, mesh: 1, primitive: 0 };
        assert_eq!(at.to_string(), "node 4, mesh 1, primitive 0");
    }

    #[test]
    fn a_cause_is_the_source_and_is_not_repeated_in_the_message() {
        let e = ImportError::Io { file: "a.obj".into(), source: io::Error::other("disk on fire") };
        assert_eq!(e.to_string(), "cannot read a.obj");
        let source = std::error::Error::source(&e).map(|c| c.to_string());
        assert_eq!(source.as_deref(), Some("disk on fire"));
    }
}
