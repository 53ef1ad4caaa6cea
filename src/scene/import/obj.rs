//! Wavefront OBJ import: a parallel block parser for mktree's scene form
//! (`o NAME`, `v x y z` in millimetres, `f a b c`; see `scene::export`)
//! that also reads common OBJ from other tools.
//!
//! Why not `tobj`: it reads coordinates as f32 (our models need f64 before
//! the anchor/offset split), gives no line numbers in errors, splits objects
//! by its own o/g rule, and builds whole models in memory per material. This
//! parser reads lines where they lie in its block, parses numbers without
//! allocating (eight digits at a time, rounded exactly; std's parser for
//! exponents and the like), and builds objects on every core.
//!
//! Rules:
//! - each `o` line starts an object named by the rest of the line (trimmed);
//!   in a file with no `o` line, each `g` line starts one instead, and a `g`
//!   group without faces (Maya's `g default` before its vertex list) is
//!   skipped; faces before any `o`/`g` form an object named after the file
//!   stem. An `o` object without faces is an error.
//! - polygons are triangulated as fans `(1, i, i+1)`; `v/vt/vn`, `v//vn`
//!   and `v/vt` corners are read for `v` only; negative indices count back
//!   from the last vertex defined. An index must refer to a vertex defined
//!   on an earlier line.
//! - `v` takes the first three numbers (a `w` or the colours some tools add
//!   are ignored); `vn`, `vt`, `usemtl`, `mtllib`, `s`, `l`, comments and any
//!   other statement are ignored. Line continuations (`\`) are not read.
//! - an object's vertices are the file's vertices its faces use, in
//!   ascending order of their index in the file; unused vertices are
//!   dropped. So `read_obj(write_obj(scene)) == scene` for every scene whose
//!   meshes use each of their vertices.
//!
//! How: the input is read in blocks ([`chunk::Chunking`]), three at a time in a
//! pipeline: while one block is read, the one before is cut after newlines
//! into pieces that rayon parses at once, each without knowing how many
//! vertices come before it ([`statement::Piece`]), and the one before that is stitched
//! in file order ([`stitch::Stitcher`]): vertex numbers and lines are offset by what
//! came before, objects are continued across pieces, and a piece whose
//! indices cannot be checked without that offset is parsed again knowing
//! it. The objects a block completes are built in parallel and handed on in
//! file order. Any cut gives the objects, errors and lines of the old
//! sequential parser (`obj/oracle.rs`): the tests cut inputs every few bytes.
//!
//! Memory: three blocks, a block's parsed pieces, the objects a block
//! completes, and all vertices of the file (24 bytes each, left in the
//! pieces' vectors), as any later face may use any earlier vertex. In a
//! file without `o`, the `g` groups are held to the end: an `o` line would
//! merge them into one object.

mod chunk;
mod number;
mod statement;
mod stitch;
mod vertices;

#[cfg(test)]
mod oracle;
#[cfg(test)]
mod tests;

use std::io::Read;
use std::path::Path;

use super::{ImportError, Imported};
use crate::scene::{Object, Scene};
use crate::spill::SpillFile;
use chunk::{Chunking, parse};
use vertices::{RESIDENT_VERTEX_BYTES, Vertices};

/// Reads an OBJ scene from `reader`; `source` names the file in errors and
/// gives the name of an object made of faces before any `o` or `g`.
///
/// ```
/// use std::path::Path;
/// use mktree::scene::import::read_obj;
///
/// let text = "o deck\nv 0 0 0\nv 1000 0 0\nv 1000 500 0\nv 0 500 0\nf 1 2 3 4\n";
/// let imported = read_obj(text.as_bytes(), Path::new("deck.obj")).unwrap();
/// let deck = &imported.scene.objects()[0];
/// assert_eq!((deck.name.as_str(), deck.mesh.triangle_count()), ("deck", 2));
/// ```
pub fn read_obj<R: Read + Send>(reader: R, source: &Path) -> Result<Imported, ImportError> {
    let mut objects = Vec::new();
    let degenerate_triangles = each_obj_object(reader, source, None, &mut |object| objects.push(object))?;
    Ok(Imported { scene: Scene::new(objects), degenerate_triangles })
}

/// [`read_obj`] handing each object to `on_object` as it is parsed, in
/// input order, so the scene need never be in memory whole; with
/// `spill_dir`, all but the newest vertices wait there for a late face.
/// Returns the count of zero-area triangles.
pub(super) fn each_obj_object<R: Read + Send>(
    reader: R,
    source: &Path,
    spill_dir: Option<&Path>,
    on_object: &mut dyn FnMut(Object),
) -> Result<usize, ImportError> {
    let spill = spill_dir.map(|dir| SpillFile::create_in(dir, "vertices")).transpose().map_err(|e| {
        ImportError::Io { file: spill_dir.map(Path::to_path_buf).unwrap_or_default(), source: e }
    })?;
    let vertices = spill.map_or_else(Vertices::default, |s| Vertices::spilling(s, RESIDENT_VERTEX_BYTES));
    let mut any = false;
    let degenerate_triangles =
        parse(reader, source, Grouping::ByObjectLines, Chunking::DEFAULT, vertices, |object| {
            any = true;
            on_object(object);
        })?;
    if !any {
        return Err(ImportError::EmptyScene { file: source.into() });
    }
    Ok(degenerate_triangles)
}

/// Reads a whole OBJ file as one object named by the file stem, ignoring
/// its `o` and `g` lines (a directory scene has one object per file).
/// Returns the object and its count of zero-area triangles.
pub(super) fn read_obj_as_one_object<R: Read + Send>(
    reader: R,
    source: &Path,
) -> Result<(Object, usize), ImportError> {
    let mut whole = None;
    let degenerate_triangles =
        parse(reader, source, Grouping::WholeFile, Chunking::DEFAULT, Vertices::default(), |object| {
            whole = Some(object);
        })?;
    // The whole-file grouping builds exactly one object or fails.
    let object = whole.ok_or_else(|| ImportError::EmptyScene { file: source.into() })?;
    Ok((object, degenerate_triangles))
}

/// How lines are grouped into objects.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Grouping {
    /// `o` starts an object; `g` does in a file without `o`.
    ByObjectLines,
    /// The whole file is one object.
    WholeFile,
}
