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
//! How: the input is read in blocks ([`Chunking`]), three at a time in a
//! pipeline: while one block is read, the one before is cut after newlines
//! into pieces that rayon parses at once, each without knowing how many
//! vertices come before it ([`Piece`]), and the one before that is stitched
//! in file order ([`Stitcher`]): vertex numbers and lines are offset by what
//! came before, objects are continued across pieces, and a piece whose
//! indices cannot be checked without that offset is parsed again knowing
//! it. The objects a block completes are built in parallel and handed on in
//! file order. Any cut gives the objects, errors and lines of the old
//! sequential parser (`obj_oracle.rs`): the tests cut inputs every few bytes.
//!
//! Memory: three blocks, a block's parsed pieces, the objects a block
//! completes, and all vertices of the file (24 bytes each, left in the
//! pieces' vectors), as any later face may use any earlier vertex. In a
//! file without `o`, the `g` groups are held to the end: an `o` line would
//! merge them into one object.

use std::io::Read;
use std::ops::Range;
use std::path::{Path, PathBuf};

use rayon::prelude::*;

use super::load::file_stem;
use super::{ImportError, Imported, Location};
use crate::geom::Point;
use crate::scene::{Object, Scene};
use crate::spill::SpillFile;

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

/// How the input is cut: blocks read at a time, and pieces parsed at once.
#[derive(Debug, Clone, Copy)]
struct Chunking {
    /// Bytes read per block (more when a line is longer).
    block: usize,
    /// Bytes per piece, up to the next newline.
    piece: usize,
}

impl Chunking {
    /// Blocks big enough that a read costs little per byte and a block has
    /// pieces for every core, small enough to stay mapped between reads and
    /// to start the cores soon; pieces small enough that the last one of a
    /// block leaves the other cores idle only briefly.
    const DEFAULT: Chunking = Chunking { block: 8 << 20, piece: 512 << 10 };
}

/// The reading loop: blocks in, objects out through `on_object`.
fn parse<R: Read + Send>(
    mut reader: R,
    source: &Path,
    grouping: Grouping,
    chunking: Chunking,
    vertices: Vertices,
    mut on_object: impl FnMut(Object),
) -> Result<usize, ImportError> {
    let mut stitcher = Stitcher::new(source, grouping, vertices);
    let mut degenerate_triangles = 0;
    let mut emit = |built: Built| -> Result<(), ImportError> {
        for result in built.objects {
            let (object, degenerate) = result?;
            degenerate_triangles += degenerate;
            on_object(object);
        }
        built.error.map_or(Ok(()), Err)
    };
    // Three blocks at once: one is read, the one before is cut into pieces
    // that are parsed, and the one before that is stitched and built.
    let mut block = Vec::new();
    let mut input = read_block(&mut reader, &mut block, chunking.block);
    let mut parsed: Option<Parsed> = None;
    let mut spare = Vec::new();
    loop {
        let complete = block.iter().rposition(|&b| b == b'\n').map_or(0, |i| i + 1);
        let end = match input {
            Input::More if complete == 0 => {
                // A line longer than the block: read on into the same block.
                input = read_block(&mut reader, &mut block, chunking.block);
                continue;
            }
            // After a failed read, the lines before it count first, as
            // they would for a reader that reads line by line.
            Input::More | Input::Failed(_) => complete,
            Input::Ended => block.len(),
        };
        let more = matches!(input, Input::More);
        if more {
            // The next block starts with this one's unfinished line.
            spare.clear();
            spare.extend_from_slice(&block[complete..]);
        }
        let text = &block[..end];
        let (built, (pieces, next)) = rayon::join(
            || parsed.as_mut().map(|parsed| stitcher.block(parsed)),
            || {
                rayon::join(
                    || Parsed::pieces(text, chunking.piece),
                    || more.then(|| read_block(&mut reader, &mut spare, chunking.block)),
                )
            },
        );
        if let Some(built) = built {
            emit(built)?;
        }
        let (ranges, pieces) = pieces;
        let text = std::mem::replace(&mut block, std::mem::take(&mut spare));
        if let Some(stitched) = parsed.replace(Parsed { text, ranges, pieces }) {
            spare = stitched.text;
        }
        let Some(next) = next else { break };
        input = next;
    }
    if let Some(mut last) = parsed {
        emit(stitcher.block(&mut last))?;
    }
    match input {
        Input::Failed(e) => Err(ImportError::Io { file: source.into(), source: e }),
        _ => {
            emit(stitcher.finish())?;
            Ok(degenerate_triangles)
        }
    }
}

/// A block's text and its pieces, parsed on their own, waiting to be
/// stitched.
struct Parsed {
    text: Vec<u8>,
    /// Where each piece lies in `text`.
    ranges: Vec<Range<usize>>,
    pieces: Vec<Piece>,
}

impl Parsed {
    /// Cuts `text` after newlines into pieces of about `size` bytes and
    /// parses them at once.
    fn pieces(text: &[u8], size: usize) -> (Vec<Range<usize>>, Vec<Piece>) {
        let size = size.max(1);
        let mut ranges = Vec::with_capacity(text.len() / size + 1);
        let mut start = 0;
        while start < text.len() {
            let end = match text.get(start + size - 1..).and_then(find_newline) {
                Some(newline) => start + size + newline,
                None => text.len(),
            };
            ranges.push(start..end);
            start = end;
        }
        let pieces = ranges.par_iter().map(|range| Piece::parse(&text[range.clone()], None)).collect();
        (ranges, pieces)
    }
}

/// What reading a block found after it.
enum Input {
    /// The block is full: more may follow.
    More,
    /// The input ended within the block.
    Ended,
    /// Reading failed after the bytes in the block.
    Failed(std::io::Error),
}

/// Appends up to `want` bytes of `reader` to `buffer`.
fn read_block<R: Read>(reader: &mut R, buffer: &mut Vec<u8>, want: usize) -> Input {
    buffer.reserve(want);
    // `read_to_end` retries interrupted reads and keeps what it read before
    // an error.
    match reader.by_ref().take(want as u64).read_to_end(buffer) {
        Ok(read) if read < want => Input::Ended,
        Ok(_) => Input::More,
        Err(e) => Input::Failed(e),
    }
}

/// A line's error, before it is placed in the file.
#[derive(Debug)]
enum LineError {
    Malformed {
        expected: &'static str,
        found: String,
    },
    NonFinite,
    /// `defined` counts the vertices of the piece before the line: the
    /// stitcher adds those before the piece.
    IndexOutOfRange {
        index: i64,
        defined: u64,
    },
}

/// A line that starts an object or group.
struct Header {
    /// `o` (else `g`).
    object: bool,
    name: String,
    /// 1-based, in the piece.
    line: u64,
    /// The piece's triangles before the line.
    triangles_before: usize,
}

/// A corner whose file index depends on the vertices before the piece.
struct Relative {
    /// Index into the piece's flattened triangles.
    corner: usize,
    /// File index less the vertices before the piece.
    offset: i64,
}

/// A corner's vertex as the piece knows it.
#[derive(Clone, Copy)]
enum Corner {
    File(u32),
    Relative(i64),
}

/// The most vertices a file may have: indices are `u32`.
const MAX_VERTICES: u64 = 1 << 32;

/// A piece of the file parsed on its own.
///
/// Without the number of vertices before it (the base), a piece still
/// reads every line, and keeps what it cannot check: positive indices are
/// file indices already, checked later against [`Piece::reach`]; negative
/// ones are offsets from the base, filled in by [`Piece::resolve`]. Given
/// the base, every index is checked on its line, so the first error is
/// found where it is.
struct Piece {
    /// Lines read (all of the piece's, unless it stopped at an error).
    lines: u64,
    vertices: Vec<Point>,
    /// All faces of the piece, as file vertex indices once resolved; the
    /// headers say which object each belongs to.
    triangles: Vec<[u32; 3]>,
    headers: Vec<Header>,
    /// The fewest vertices before the piece for which its indices are in
    /// range: the most by which an index reaches beyond the piece's
    /// vertices before its line.
    reach: i64,
    relative: Vec<Relative>,
    /// The first error and its line in the piece: parsing stopped there.
    error: Option<(u64, LineError)>,
}

impl Piece {
    fn parse(text: &[u8], base: Option<u64>) -> Piece {
        // Our own files have about one vertex per 50 bytes and one face per
        // 20: reserving that saves most of the growing.
        let mut piece = Piece {
            lines: 0,
            vertices: Vec::with_capacity(text.len() / 48),
            triangles: Vec::with_capacity(text.len() / 20),
            headers: Vec::new(),
            reach: 0,
            relative: Vec::new(),
            error: None,
        };
        let mut s = text;
        while !s.is_empty() {
            piece.lines += 1;
            // The statements that make up nearly all of a file are read in
            // place; they stop at the end of their line or before.
            let statement = match s {
                [b'v', b' ' | b'\t', rest @ ..] => piece.vertex(rest, base),
                [b'f', b' ' | b'\t', rest @ ..] => piece.face(rest, base),
                _ => {
                    let line = line_at(s);
                    piece.statement(line, base).map(|()| &s[line.len()..])
                }
            };
            match statement {
                Ok(rest) => s = after_line(rest),
                Err(e) => {
                    piece.error = Some((piece.lines, e));
                    break;
                }
            }
        }
        piece
    }

    /// Any line but a plain `v` or `f` one.
    fn statement(&mut self, line: &[u8], base: Option<u64>) -> Result<(), LineError> {
        let line = line.trim_ascii();
        let (keyword, rest) = match line.iter().position(u8::is_ascii_whitespace) {
            Some(end) => (&line[..end], line[end..].trim_ascii_start()),
            None => (line, &line[line.len()..]),
        };
        match keyword {
            b"v" => self.vertex(rest, base).map(drop),
            b"f" => self.face(rest, base).map(drop),
            b"o" | b"g" => {
                let name = String::from_utf8_lossy(rest).into_owned();
                let object = keyword == b"o";
                let triangles_before = self.triangles.len();
                self.headers.push(Header { object, name, line: self.lines, triangles_before });
                Ok(())
            }
            _ => Ok(()),
        }
    }

    /// Reads the coordinates that start `rest`; returns the bytes after them.
    fn vertex<'a>(&mut self, rest: &'a [u8], base: Option<u64>) -> Result<&'a [u8], LineError> {
        let mut s = rest;
        let mut xyz = [0.0; 3];
        for c in &mut xyz {
            s = skip_blanks(s);
            if at_line_end(s) {
                return Err(malformed("3 coordinates after `v`", line_at(rest).trim_ascii()));
            }
            let (value, after) = scan_f64(s).ok_or_else(|| malformed("a number", token_at(s)))?;
            *c = value;
            s = after;
        }
        if !xyz.iter().all(|c| c.is_finite()) {
            return Err(LineError::NonFinite);
        }
        if base.is_some_and(|base| base + self.vertices.len() as u64 >= MAX_VERTICES) {
            return Err(malformed("at most 2^32 vertices in one file", b"v"));
        }
        self.vertices.push(Point::from(xyz));
        Ok(s)
    }

    /// Reads the corners that start `rest` as a fan of triangles; returns
    /// the bytes after them (the end of the line, or a comment).
    fn face<'a>(&mut self, rest: &'a [u8], base: Option<u64>) -> Result<&'a [u8], LineError> {
        let mut corners = 0usize;
        let mut first = Corner::File(0);
        let mut previous = first;
        let mut s = rest;
        loop {
            s = skip_blanks(s);
            let (written, after) = match short_index(s) {
                Some(scanned) => scanned,
                None if at_line_end(s) || s[0] == b'#' => break,
                None => scan_index(s)
                    .ok_or_else(|| malformed("a vertex index (v, v/vt, v//vn or v/vt/vn)", token_at(s)))?,
            };
            s = after;
            let vertex = self.corner(written, base)?;
            match corners {
                0 => first = vertex,
                1 => {}
                _ => self.triangle([first, previous, vertex]),
            }
            previous = vertex;
            corners += 1;
        }
        if corners < 3 {
            return Err(malformed("at least 3 vertex indices after `f`", line_at(rest).trim_ascii()));
        }
        Ok(s)
    }

    /// The vertex that index `written` (1-based, or negative to count back)
    /// names; with the base, checked here, else as far as the piece can.
    fn corner(&mut self, written: i64, base: Option<u64>) -> Result<Corner, LineError> {
        let here = self.vertices.len() as u64;
        let out_of_range = LineError::IndexOutOfRange { index: written, defined: here };
        match (written, base) {
            (1.., Some(base)) => {
                let index = written.unsigned_abs() - 1;
                if index >= base + here {
                    return Err(out_of_range);
                }
                // Below the file's vertex count, so below 2^32.
                u32::try_from(index).map(Corner::File).map_err(|_| out_of_range)
            }
            (1.., None) => {
                // Beyond 2^32 an index is out of range whatever the base.
                let index = u32::try_from(written - 1).map_err(|_| out_of_range)?;
                self.reach = self.reach.max(written - here as i64);
                Ok(Corner::File(index))
            }
            (..0, Some(base)) => (base + here)
                .checked_sub(written.unsigned_abs())
                .and_then(|index| u32::try_from(index).ok())
                .map(Corner::File)
                .ok_or(out_of_range),
            (..0, None) => {
                // At most 18 digits: no overflow.
                let offset = here as i64 + written;
                self.reach = self.reach.max(-offset);
                Ok(Corner::Relative(offset))
            }
            (0, _) => Err(out_of_range),
        }
    }

    fn triangle(&mut self, corners: [Corner; 3]) {
        if let [Corner::File(a), Corner::File(b), Corner::File(c)] = corners {
            self.triangles.push([a, b, c]);
            return;
        }
        let at = 3 * self.triangles.len();
        self.triangles.push(corners.map(|c| match c {
            Corner::File(index) => index,
            Corner::Relative(_) => 0,
        }));
        for (i, c) in corners.into_iter().enumerate() {
            if let Corner::Relative(offset) = c {
                self.relative.push(Relative { corner: at + i, offset });
            }
        }
    }

    /// Fills in the relative corners for `base` vertices before the piece;
    /// false when an index or the vertex count is out of range with this
    /// base (the piece must then be parsed again knowing it).
    fn resolve(&mut self, base: u64) -> bool {
        if u64::try_from(self.reach).is_ok_and(|reach| reach > base)
            || base + self.vertices.len() as u64 > MAX_VERTICES
        {
            return false;
        }
        let corners = self.triangles.as_flattened_mut();
        for r in &self.relative {
            let Some(index) = base.checked_add_signed(r.offset).and_then(|i| u32::try_from(i).ok()) else {
                return false;
            };
            corners[r.corner] = index;
        }
        true
    }
}

/// Skips the blanks within a line (any ASCII whitespace but `\n`).
fn skip_blanks(mut s: &[u8]) -> &[u8] {
    while let [b' ' | b'\t' | b'\r' | b'\x0c', rest @ ..] = s {
        s = rest;
    }
    s
}

fn at_line_end(s: &[u8]) -> bool {
    matches!(s.first(), None | Some(b'\n'))
}

/// The line that starts `s`, without its newline.
fn line_at(s: &[u8]) -> &[u8] {
    &s[..find_newline(s).unwrap_or(s.len())]
}

/// The bytes after the line that `s` is within.
fn after_line(s: &[u8]) -> &[u8] {
    // Most statements end right at their newline.
    match s {
        [b'\n', rest @ ..] => rest,
        _ => find_newline(s).map_or(&[], |end| &s[end + 1..]),
    }
}

fn malformed(expected: &'static str, found: &[u8]) -> LineError {
    // Keep messages short when a binary file is read as OBJ.
    const SHOWN: usize = 60;
    let mut shown = String::from_utf8_lossy(&found[..found.len().min(SHOWN)]).into_owned();
    if found.len() > SHOWN {
        shown.push_str("...");
    }
    LineError::Malformed { expected, found: shown }
}

/// An object whose faces are still being read, with file vertex indices.
///
/// Its triangles from earlier blocks are copied out; those of the block
/// being read stay in its pieces until the object is built. All of the
/// first come before all of the second in the file, merged groups too.
struct Pending {
    name: String,
    /// The line of its `o` or `g`; `None` for the object named by the file.
    line: Option<u64>,
    earlier: Vec<[u32; 3]>,
    /// Ranges of triangles of the block's pieces, by piece.
    runs: Vec<(usize, Range<usize>)>,
}

impl Pending {
    fn new(name: String, line: Option<u64>) -> Pending {
        Pending { name, line, earlier: Vec::new(), runs: Vec::new() }
    }

    fn is_empty(&self) -> bool {
        self.earlier.is_empty() && self.runs.is_empty()
    }

    fn run(&mut self, piece: usize, triangles: Range<usize>) {
        if !triangles.is_empty() {
            self.runs.push((piece, triangles));
        }
    }

    /// Adds the faces of `other`, which follow.
    fn append(&mut self, mut other: Pending) {
        self.earlier.append(&mut other.earlier);
        self.runs.append(&mut other.runs);
    }

    /// Its triangles, in file order.
    fn parts<'a>(&'a self, pieces: &'a [Piece]) -> impl Iterator<Item = &'a [[u32; 3]]> + Clone {
        let runs = self.runs.iter().map(|(piece, range)| &pieces[*piece].triangles[range.clone()]);
        std::iter::once(self.earlier.as_slice()).chain(runs)
    }

    /// Copies the triangles it has in `pieces` out, before they go.
    fn settle(&mut self, pieces: &[Piece]) {
        let runs = std::mem::take(&mut self.runs);
        for (piece, range) in runs {
            self.earlier.extend_from_slice(&pieces[piece].triangles[range]);
        }
    }
}

/// The objects a block completed, built, and the error that ended the
/// file there, if any.
struct Built {
    /// In file order, each with its count of zero-area triangles; the first
    /// failure ends the file (they are handed on as they are, not copied).
    objects: Vec<Result<(Object, usize), ImportError>>,
    error: Option<ImportError>,
}

/// Puts parsed pieces together in file order: the file's vertices, line
/// numbers and objects.
struct Stitcher {
    file: PathBuf,
    grouping: Grouping,
    /// Every vertex of the file so far: faces may use any earlier one.
    vertices: Vertices,
    /// Lines before the next piece.
    lines: u64,
    /// True once an `o` line was read: from then on `g` lines are ignored.
    seen_o: bool,
    /// The object receiving faces.
    current: Pending,
    /// In a file without `o` so far, the finished `g` groups with faces:
    /// they become objects at the end, or merge into the file's object if an
    /// `o` line turns up.
    groups: Vec<Pending>,
    /// Objects complete but not yet built, in file order.
    complete: Vec<Pending>,
}

impl Stitcher {
    fn new(source: &Path, grouping: Grouping, vertices: Vertices) -> Stitcher {
        Stitcher {
            file: source.into(),
            grouping,
            vertices,
            lines: 0,
            seen_o: false,
            current: Pending::new(file_stem(source), None),
            groups: Vec::new(),
            complete: Vec::new(),
        }
    }

    /// Stitches a parsed block and builds the objects it completes; its
    /// pieces are freed here, off the reading loop.
    fn block(&mut self, parsed: &mut Parsed) -> Built {
        let pieces = &mut parsed.pieces;
        let mut error = None;
        for (index, range) in parsed.ranges.iter().enumerate() {
            if let Err(e) = self.add(index, &parsed.text[range.clone()], &mut pieces[index]) {
                error = Some(e);
                break;
            }
        }
        let mut built = self.build(pieces);
        // Objects completed before the line at fault were built first.
        built.error = built.error.or(error);
        self.current.settle(pieces);
        for group in &mut self.groups {
            group.settle(pieces);
        }
        pieces.clear();
        built
    }

    /// Adds piece `index` after those before it; an error ends the file there.
    fn add(&mut self, index: usize, text: &[u8], piece: &mut Piece) -> Result<(), ImportError> {
        let base = self.vertices.len();
        if !piece.resolve(base) {
            *piece = Piece::parse(text, Some(base));
        }
        if let Err(source) = self.vertices.append(std::mem::take(&mut piece.vertices)) {
            return Err(ImportError::Io { file: self.vertices.spill_path(), source });
        }
        let mut start = 0;
        for header in std::mem::take(&mut piece.headers) {
            self.current.run(index, start..header.triangles_before);
            start = header.triangles_before;
            self.header(header);
        }
        self.current.run(index, start..piece.triangles.len());
        let Some((line, error)) = piece.error.take() else {
            self.lines += piece.lines;
            return Ok(());
        };
        let (file, object, at) = (self.file.clone(), self.current.name.clone(), self.lines + line);
        Err(match error {
            LineError::Malformed { expected, found } => {
                ImportError::Malformed { file, line: at, expected, found }
            }
            LineError::NonFinite => ImportError::NonFiniteCoordinate { file, object, at: Location::Line(at) },
            LineError::IndexOutOfRange { index, defined } => ImportError::IndexOutOfRange {
                file,
                object,
                at: Location::Line(at),
                index,
                vertices: (base + defined) as usize,
            },
        })
    }

    fn header(&mut self, header: Header) {
        let line = Some(self.lines + header.line);
        match self.grouping {
            Grouping::ByObjectLines if header.object => self.start_object(Pending::new(header.name, line)),
            Grouping::ByObjectLines if !self.seen_o => self.start_group(Pending::new(header.name, line)),
            _ => {}
        }
    }

    fn start_object(&mut self, next: Pending) {
        let previous = std::mem::replace(&mut self.current, next);
        if self.seen_o {
            self.complete.push(previous);
            return;
        }
        // The first `o`: `g` lines so far did not start objects after all;
        // every face before this line belongs to the object named by the file.
        self.seen_o = true;
        let mut merged = Pending::new(file_stem(&self.file), None);
        for group in std::mem::take(&mut self.groups).into_iter().chain([previous]) {
            merged.append(group);
        }
        if !merged.is_empty() {
            self.complete.push(merged);
        }
    }

    fn start_group(&mut self, next: Pending) {
        let previous = std::mem::replace(&mut self.current, next);
        if !previous.is_empty() {
            self.groups.push(previous);
        }
    }

    /// Completes the objects left at the end of the file and builds them.
    fn finish(&mut self) -> Built {
        let last = std::mem::replace(&mut self.current, Pending::new(String::new(), None));
        match self.grouping {
            Grouping::ByObjectLines if !self.seen_o => {
                let groups = std::mem::take(&mut self.groups).into_iter().chain([last]);
                self.complete.extend(groups.filter(|group| !group.is_empty()));
            }
            _ => self.complete.push(last),
        }
        self.build(&[])
    }

    /// Builds the complete objects in parallel.
    fn build(&mut self, pieces: &[Piece]) -> Built {
        let (file, vertices) = (&self.file, &self.vertices);
        let objects = std::mem::take(&mut self.complete)
            .into_par_iter()
            .map_init(Scratch::default, |scratch, pending| build(file, vertices, pieces, pending, scratch))
            .collect();
        Built { objects, error: None }
    }
}

/// Buffers that building objects reuses, one set per thread.
#[derive(Default)]
struct Scratch {
    /// An object's own number for each file vertex in its span.
    local_index: Vec<u32>,
    /// The object's vertices.
    points: Vec<Point>,
}

/// Turns a complete object into a mesh over the vertices it uses, with its
/// count of zero-area triangles.
fn build(
    file: &Path,
    vertices: &Vertices,
    pieces: &[Piece],
    pending: Pending,
    scratch: &mut Scratch,
) -> Result<(Object, usize), ImportError> {
    let triangles = renumber(vertices, pending.parts(pieces), scratch)
        .map_err(|source| ImportError::Io { file: vertices.spill_path(), source })?;
    let object = super::load::object(file, pending.name, pending.line, &scratch.points, triangles)?;
    let degenerate = object.mesh.degenerate_triangles();
    Ok((object, degenerate))
}

/// An object's triangles over its own vertices, from its `parts` over the
/// file's `vertices`; its vertices, those it uses in ascending file order,
/// go to `scratch.points`.
fn renumber<'a>(
    vertices: &Vertices,
    parts: impl Iterator<Item = &'a [[u32; 3]]> + Clone,
    scratch: &mut Scratch,
) -> std::io::Result<Vec<[u32; 3]>> {
    let count = parts.clone().map(<[_]>::len).sum();
    let corners = || parts.clone().flat_map(<[_]>::as_flattened).copied();
    let (lowest, highest) = corners().fold((u32::MAX, 0), |(lo, hi), c| (lo.min(c), hi.max(c)));
    let lowest = lowest.min(highest);
    let span = (highest - lowest) as usize + 1;
    let mut triangles = Vec::with_capacity(count);
    let Scratch { local_index, points } = scratch;
    points.clear();
    // An object's vertices usually sit together in the file (always, in
    // our own form): a table over their span renumbers in linear time.
    // Objects that pick vertices from all over a shared list sort instead.
    if span <= 12 * count + 1024 {
        const UNUSED: u32 = u32::MAX;
        local_index.clear();
        local_index.resize(span, UNUSED);
        for c in corners() {
            local_index[(c - lowest) as usize] = 0;
        }
        let mut slots = local_index.iter_mut();
        vertices.for_range(lowest, span, &mut |run| {
            for (slot, point) in slots.by_ref().take(run.len()).zip(run) {
                if *slot != UNUSED {
                    *slot = points.len() as u32;
                    points.push(*point);
                }
            }
        })?;
        for part in parts {
            triangles.extend(part.iter().map(|t| t.map(|c| local_index[(c - lowest) as usize])));
        }
    } else {
        let mut used: Vec<u32> = corners().collect();
        used.sort_unstable();
        used.dedup();
        // Every corner is in `used`, which is sorted.
        let local = |c: u32| used.binary_search(&c).unwrap_or_default() as u32;
        for part in parts {
            triangles.extend(part.iter().map(|t| t.map(local)));
        }
        for &i in &used {
            points.push(vertices.get(i)?);
        }
    }
    Ok(triangles)
}

/// The file's vertices, kept in the vectors its pieces parsed them into:
/// copying them into one would be a step no other core could share. A
/// face may name any earlier vertex, so all are kept; with a spill file
/// (streamed imports), runs beyond the newest [`RESIDENT_VERTEX_BYTES`]
/// go to disk and are read back only when a face names them.
#[derive(Default)]
struct Vertices {
    runs: Vec<Run>,
    /// The file index of each run's first vertex.
    starts: Vec<u64>,
    len: u64,
    spill: Option<SpillFile>,
    /// Bytes of runs kept in memory with a spill file.
    keep: usize,
    /// Bytes of the runs in memory, and the oldest of them.
    resident: usize,
    oldest_resident: usize,
}

/// Vertex bytes a streamed import keeps in memory: far more than any
/// object's own vertices, which faces name in practice.
const RESIDENT_VERTEX_BYTES: usize = 64 << 20;

/// Bytes of a vertex in the spill file: three f64.
const SPILLED_VERTEX: usize = 24;

enum Run {
    Resident(Vec<Point>),
    Spilled { offset: u64, len: usize },
}

impl Run {
    fn len(&self) -> usize {
        match self {
            Run::Resident(points) => points.len(),
            Run::Spilled { len, .. } => *len,
        }
    }
}

impl Vertices {
    fn spilling(spill: SpillFile, keep: usize) -> Vertices {
        Vertices { spill: Some(spill), keep, ..Vertices::default() }
    }

    fn len(&self) -> u64 {
        self.len
    }

    fn append(&mut self, run: Vec<Point>) -> std::io::Result<()> {
        if run.is_empty() {
            return Ok(());
        }
        self.starts.push(self.len);
        self.len += run.len() as u64;
        self.resident += run.len() * SPILLED_VERTEX;
        self.runs.push(Run::Resident(run));
        let Some(spill) = &mut self.spill else { return Ok(()) };
        // The newest run always stays: the next faces most likely name it.
        while self.resident > self.keep && self.oldest_resident + 1 < self.runs.len() {
            let run = &mut self.runs[self.oldest_resident];
            if let Run::Resident(points) = run {
                let bytes: Vec<u8> =
                    points.iter().flat_map(|p| p.coords.iter()).flat_map(|c| c.to_le_bytes()).collect();
                let offset = spill.append(&bytes)?;
                self.resident -= points.len() * SPILLED_VERTEX;
                *run = Run::Spilled { offset, len: points.len() };
            }
            self.oldest_resident += 1;
        }
        spill.flush()
    }

    /// The run holding vertex `index`, and where in it; past the end, the
    /// end of the last run.
    fn locate(&self, index: u32) -> (usize, usize) {
        let run = self.starts.partition_point(|&start| start <= u64::from(index)).saturating_sub(1);
        let at = u64::from(index).saturating_sub(self.starts.get(run).copied().unwrap_or(0));
        (run, (at as usize).min(self.runs.get(run).map_or(0, Run::len)))
    }

    /// Vertex `index`, which the faces' checks put below `len`.
    fn get(&self, index: u32) -> std::io::Result<Point> {
        let mut point = Point::origin();
        self.for_range(index, 1, &mut |run| point = run.first().copied().unwrap_or(point))?;
        Ok(point)
    }

    /// Hands `f` the vertices from `index` on, run by run, up to `count`
    /// of them (fewer at the end), reading spilled runs back.
    fn for_range(&self, index: u32, count: usize, f: &mut dyn FnMut(&[Point])) -> std::io::Result<()> {
        let (first, mut at) = self.locate(index);
        let mut left = count;
        let mut buffer = Vec::new();
        for run in self.runs.get(first..).unwrap_or_default() {
            if left == 0 {
                break;
            }
            let take = left.min(run.len().saturating_sub(at));
            match run {
                Run::Resident(points) => f(&points[at..at + take]),
                Run::Spilled { offset, .. } => {
                    let spill = self.spill.as_ref().ok_or_else(|| std::io::Error::other("no spill file"))?;
                    let mut bytes = vec![0u8; take * SPILLED_VERTEX];
                    spill.read_exact_at(&mut bytes, offset + (at * SPILLED_VERTEX) as u64)?;
                    buffer.clear();
                    buffer.extend(bytes.chunks_exact(SPILLED_VERTEX).map(|v| {
                        let c =
                            |i: usize| f64::from_le_bytes(v[8 * i..8 * i + 8].try_into().unwrap_or([0; 8]));
                        Point::new(c(0), c(1), c(2))
                    }));
                    f(&buffer);
                }
            }
            left -= take;
            at = 0;
        }
        Ok(())
    }

    fn spill_path(&self) -> PathBuf {
        self.spill.as_ref().map_or_else(PathBuf::new, |s| s.path().to_path_buf())
    }
}

/// The index of the first `\n` in `s`, eight bytes at a time.
fn find_newline(s: &[u8]) -> Option<usize> {
    const NEWLINES: u64 = 0x0A0A_0A0A_0A0A_0A0A;
    let mut offset = 0;
    while let Some(chunk) = s.get(offset..).and_then(<[u8]>::first_chunk::<8>) {
        // A zero byte of `x` is a newline; the lowest flagged byte is exact.
        let x = u64::from_le_bytes(*chunk) ^ NEWLINES;
        let zeros = x.wrapping_sub(0x0101_0101_0101_0101) & !x & 0x8080_8080_8080_8080;
        if zeros != 0 {
            return Some(offset + (zeros.trailing_zeros() / 8) as usize);
        }
        offset += 8;
    }
    s.get(offset..)?.iter().position(|&b| b == b'\n').map(|p| offset + p)
}

/// The bytes of `s` up to the first whitespace.
fn token_at(s: &[u8]) -> &[u8] {
    &s[..s.iter().position(u8::is_ascii_whitespace).unwrap_or(s.len())]
}

/// The number that starts `s`, and the bytes after it. The number must end
/// at whitespace or at the end of `s`.
///
/// Plain decimals (no exponent) of up to 19 digits, the form our scenes
/// are written in, are read in one pass and rounded exactly here (see
/// [`exact_quotient`]). Anything else (an exponent, more digits, `inf`,
/// `nan`) goes to std's parser, which is exact too.
fn scan_f64(s: &[u8]) -> Option<(f64, &[u8])> {
    if let Some(fast) = short_decimal(s).or_else(|| scan_plain_decimal(s)) {
        return Some(fast);
    }
    let token = token_at(s);
    let value = std::str::from_utf8(token).ok()?.parse().ok()?;
    Some((value, &s[token.len()..]))
}

fn scan_plain_decimal(s: &[u8]) -> Option<(f64, &[u8])> {
    let (negative, body) = split_sign(s);
    let (whole, whole_digits, after_whole) = leading_digits(body, 0);
    let (digits, fraction_digits, rest) = match after_whole.split_first() {
        Some((b'.', fraction)) => leading_digits(fraction, whole),
        _ => (whole, 0, after_whole),
    };
    let ends = rest.first().is_none_or(u8::is_ascii_whitespace);
    // Up to 19 digits the accumulator is exact (10^19 < 2^64).
    if !ends || !(1..=19).contains(&(whole_digits + fraction_digits)) {
        return None;
    }
    let value = exact_quotient(digits, fraction_digits)?;
    Some((if negative { -value } else { value }, rest))
}

/// A plain decimal as nearly every coordinate is written: up to seven
/// digits, a point and up to seven more, then a blank or the line's end.
/// Read from two chunks; fourteen digits are below 2^53, so one division
/// rounds exactly (see [`exact_quotient`]). `None` for anything else.
#[inline(always)]
fn short_decimal(s: &[u8]) -> Option<(f64, &[u8])> {
    const POWERS_OF_TEN: [u64; 8] = [1, 10, 100, 1_000, 10_000, 100_000, 1_000_000, 10_000_000];
    let (negative, body) = split_sign(s);
    let chunk = u64::from_le_bytes(*body.first_chunk::<8>()?);
    let whole_digits = digit_run(chunk);
    if !(1..8).contains(&whole_digits) {
        return None;
    }
    let whole = run_value(chunk, whole_digits);
    let (digits, fraction_digits, rest) = match &body[whole_digits..] {
        [b'.', fraction @ ..] => {
            let chunk = u64::from_le_bytes(*fraction.first_chunk::<8>()?);
            let n = digit_run(chunk);
            let value = *POWERS_OF_TEN.get(n)? * whole + if n > 0 { run_value(chunk, n) } else { 0 };
            (value, n, &fraction[n..])
        }
        rest => (whole, 0, rest),
    };
    if !matches!(rest.first(), Some(b' ' | b'\t' | b'\n' | b'\r')) {
        return None;
    }
    let value = digits as f64 / F64_POWERS_OF_TEN[fraction_digits];
    Some((if negative { -value } else { value }, rest))
}

/// 10^k for k <= 22, all exact in f64.
const F64_POWERS_OF_TEN: [f64; 23] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18,
    1e19, 1e20, 1e21, 1e22,
];

/// `digits / 10^k` correctly rounded to f64, or `None` when this cannot
/// tell cheaply (std's parser then decides).
///
/// With at most 53 significant bits the digits are exact in f64, and so is
/// 10^k for k <= 22: one division rounds once and is exact (Clinger's fast
/// path). With more (shortest round-trip decimals often have 17 digits),
/// that quotient is within one unit in the last place; it, or its
/// neighbour towards the true value, is checked against half a unit in
/// 128-bit integers.
fn exact_quotient(digits: u64, k: usize) -> Option<f64> {
    let quotient = digits as f64 / *F64_POWERS_OF_TEN.get(k)?;
    if digits <= 1 << 53 {
        return Some(quotient);
    }
    // k <= 19 here (at most 19 digits), so 10^k fits in 64 bits.
    let power = 10u64.checked_pow(k as u32)?;
    match rounding_error(digits, power, quotient)? {
        std::cmp::Ordering::Equal => Some(quotient),
        towards => {
            let neighbour =
                f64::from_bits(if towards.is_gt() { quotient.to_bits() + 1 } else { quotient.to_bits() - 1 });
            rounding_error(digits, power, neighbour)?.is_eq().then_some(neighbour)
        }
    }
}

/// Whether the positive normal `candidate` is `digits / power` correctly
/// rounded (`Equal`), or too small (`Greater`: the true value lies above
/// half a unit over it) or too large (`Less`). `None` for a tie, a power
/// of two (whose lower half-unit is smaller), or numbers out of reach.
fn rounding_error(digits: u64, power: u64, candidate: f64) -> Option<std::cmp::Ordering> {
    let bits = candidate.to_bits();
    let biased_exponent = (bits >> 52) as i32;
    let fraction = bits & ((1 << 52) - 1);
    if !(1..0x7FF).contains(&biased_exponent) || fraction == 0 {
        return None;
    }
    // candidate = mantissa * 2^exponent exactly.
    let mantissa = fraction | (1 << 52);
    let exponent = biased_exponent - 1075;
    // (digits / power - candidate) * 2 * power * 2^max(-exponent, 0),
    // compared with half a unit, scaled alike: power * 2^max(exponent, 0).
    let up = exponent.max(0) as u32;
    let down = (-exponent).max(0) as u32;
    let shift = |value: u128, by: u32| (value.leading_zeros() > by).then(|| value << by);
    let scaled_value = shift(u128::from(digits) << 1, down)?;
    // A 53-bit mantissa times a 64-bit power: 117 bits, no overflow.
    let scaled_candidate = shift((u128::from(mantissa) * u128::from(power)) << 1, up)?;
    let half_unit = shift(u128::from(power), up)?;
    let (gap, above) = match scaled_value.checked_sub(scaled_candidate) {
        Some(gap) => (gap, true),
        None => (scaled_candidate - scaled_value, false),
    };
    match gap.cmp(&half_unit) {
        std::cmp::Ordering::Less => Some(std::cmp::Ordering::Equal),
        std::cmp::Ordering::Equal => None,
        std::cmp::Ordering::Greater if above => Some(std::cmp::Ordering::Greater),
        std::cmp::Ordering::Greater => Some(std::cmp::Ordering::Less),
    }
}

/// The vertex index that starts `s` (the `v` of `v/vt/vn`), and the bytes
/// after the whole corner. At most 18 digits, so it cannot overflow (no
/// file has 10^18 vertices).
fn scan_index(s: &[u8]) -> Option<(i64, &[u8])> {
    let (negative, body) = split_sign(s);
    let (value, digits, mut rest) = leading_digits(body, 0);
    if !(1..=18).contains(&digits) {
        return None;
    }
    if rest.first() == Some(&b'/') {
        rest = &rest[token_at(rest).len()..];
    }
    if !rest.first().is_none_or(u8::is_ascii_whitespace) {
        return None;
    }
    // 18 digits fit in an i64.
    let value = value as i64;
    Some((if negative { -value } else { value }, rest))
}

fn split_sign(s: &[u8]) -> (bool, &[u8]) {
    match s {
        [b'-', body @ ..] => (true, body),
        [b'+', body @ ..] => (false, body),
        _ => (false, s),
    }
}

/// Appends the decimal digits that start `s` to `value`; returns the new
/// value, how many digits were read, and the bytes after them. Past 19
/// digits the value wraps: callers check the count.
///
/// Eight bytes at a time, as in Lemire's fast_float but for runs of any
/// length: the first non-digit of the chunk ends the run, the digits before
/// it are shifted to the top and converted together. Coordinates written as
/// shortest round-trip decimals have 16 or 17 digits, indices 5 to 9, so a
/// byte-at-a-time loop would cost a multiply per digit.
#[inline]
fn leading_digits(mut s: &[u8], mut value: u64) -> (u64, usize, &[u8]) {
    const POWERS_OF_TEN: [u64; 9] = [1, 10, 100, 1_000, 10_000, 100_000, 1_000_000, 10_000_000, 100_000_000];
    let mut count = 0;
    loop {
        let chunk = match s.first_chunk::<8>() {
            Some(chunk) => u64::from_le_bytes(*chunk),
            None => {
                // Past the end of `s`, spaces: they end the run like any non-digit.
                let mut padded = [b' '; 8];
                for (p, &b) in padded.iter_mut().zip(s) {
                    *p = b;
                }
                u64::from_le_bytes(padded)
            }
        };
        let digits = digit_run(chunk);
        if digits == 0 {
            return (value, count, s);
        }
        value = value.wrapping_mul(POWERS_OF_TEN[digits]).wrapping_add(run_value(chunk, digits));
        count += digits;
        s = &s[digits..];
        if digits < 8 {
            return (value, count, s);
        }
    }
}

const ZEROS: u64 = 0x3030_3030_3030_3030;

/// How many digits start `chunk` (first byte lowest), 0 to 8.
#[inline(always)]
fn digit_run(chunk: u64) -> usize {
    // A byte's high bit is set here iff it is not a digit; bytes after the
    // first non-digit may be garbled by borrows, but are not used.
    let non_digits =
        (chunk.wrapping_sub(ZEROS) | chunk.wrapping_add(0x4646_4646_4646_4646)) & 0x8080_8080_8080_8080;
    (non_digits.trailing_zeros() / 8) as usize
}

/// The number that the first `digits` (1 to 8) bytes of `chunk` spell.
#[inline(always)]
fn run_value(chunk: u64, digits: usize) -> u64 {
    // The run's digits into the top bytes, '0's below them.
    let shift = 8 * (8 - digits) as u32;
    eight_digits(chunk.checked_shl(shift).unwrap_or(0) | ZEROS.checked_shr(64 - shift).unwrap_or(0))
}

/// A corner as nearly every file writes it: a positive index of at most
/// seven digits, then a blank or the line's end. Read from one chunk, it
/// skips [`scan_index`]'s sign, slash and length checks; `None` for
/// anything else, which [`scan_index`] then reads.
#[inline(always)]
fn short_index(s: &[u8]) -> Option<(i64, &[u8])> {
    let chunk = u64::from_le_bytes(*s.first_chunk::<8>()?);
    let digits = digit_run(chunk);
    let ends = matches!(s.get(digits), Some(b' ' | b'\t' | b'\n' | b'\r'));
    if !(1..8).contains(&digits) || !ends {
        return None;
    }
    // Seven digits fit in an i64.
    Some((run_value(chunk, digits) as i64, &s[digits..]))
}

/// The number that eight ASCII digits (first digit in the lowest byte)
/// spell: pairs, then quads, then all eight, by multiply and shift.
#[inline]
fn eight_digits(chunk: u64) -> u64 {
    let d = chunk.wrapping_sub(0x3030_3030_3030_3030);
    let pairs = d.wrapping_mul(10).wrapping_add(d >> 8);
    let low = (pairs & 0x0000_00FF_0000_00FF).wrapping_mul(0x000F_4240_0000_0064);
    let high = ((pairs >> 16) & 0x0000_00FF_0000_00FF).wrapping_mul(0x0000_2710_0000_0001);
    u64::from((low.wrapping_add(high) >> 32) as u32)
}

#[cfg(test)]
#[path = "obj_oracle.rs"]
mod oracle;

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn read(text: &str) -> Result<Imported, ImportError> {
        read_obj(text.as_bytes(), Path::new("dir/test.obj"))
    }

    fn summary(imported: &Imported) -> Vec<(String, usize, usize)> {
        imported
            .scene
            .objects()
            .iter()
            .map(|o| (o.name.clone(), o.mesh.vertex_count(), o.mesh.triangle_count()))
            .collect()
    }

    fn owned(rows: &[(&str, usize, usize)]) -> Vec<(String, usize, usize)> {
        rows.iter().map(|&(n, v, t)| (n.to_string(), v, t)).collect()
    }

    const SQUARE: &str = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n";

    #[test]
    fn o_lines_start_objects_and_g_lines_are_then_ignored() {
        let text = format!("{SQUARE}f 1 2 3\no a\ng x\nf 1 2 3 4\no b c \ng y\nf -1 -2 -3\n");
        let imported = read(&text).unwrap();
        assert_eq!(summary(&imported), owned(&[("test", 3, 1), ("a", 4, 2), ("b c", 3, 1)]));
    }

    #[test]
    fn g_lines_start_objects_in_a_file_without_o() {
        let text = format!("g default\n{SQUARE}f 1 2 3\ng left\nf 1 2 3\ng empty\ng right\nf 2 3 4\n");
        let imported = read(&text).unwrap();
        assert_eq!(summary(&imported), owned(&[("default", 3, 1), ("left", 3, 1), ("right", 3, 1)]));
    }

    #[test]
    fn an_o_after_groups_merges_the_groups_into_the_file_object() {
        let text = format!("{SQUARE}g a\nf 1 2 3\ng b\nf 2 3 4\no real\nf 1 3 4\n");
        let imported = read(&text).unwrap();
        assert_eq!(summary(&imported), owned(&[("test", 4, 2), ("real", 3, 1)]));
    }

    #[test]
    fn corners_with_texture_and_normal_indices_use_the_position() {
        let text = format!("{SQUARE}vt 0 0\nvn 0 0 1\nusemtl steel\ns 1\nl 1 2\nf 1/1/1 2//1 3/1 4/1/1\n");
        let imported = read(&text).unwrap();
        assert_eq!(imported.scene.objects()[0].mesh.triangles(), &[[0, 1, 2], [0, 2, 3]]);
    }

    #[test]
    fn object_vertices_are_the_used_ones_in_file_order() {
        // Faces name vertices 4, 2 and 3 (1-based) out of order; 1 is unused.
        let text = "v 9 9 9\nv 1 0 0\nv 0 1 0\nv 0 0 1\no t\nf 4 2 3\n";
        let imported = read(text).unwrap();
        let mesh = &imported.scene.objects()[0].mesh;
        assert_eq!(mesh.triangles(), &[[2, 0, 1]]);
        assert_eq!(mesh.vertex(0), Point::new(1.0, 0.0, 0.0));
    }

    #[test]
    fn scattered_vertices_are_renumbered_by_sorting() {
        let mut text = String::from("v 0 0 0\nv 1 0 0\n");
        for i in 0..5000 {
            text.push_str(&format!("v {i} 5 0\n"));
        }
        text.push_str("v 0 1 0\no far\nf 1 2 -1\n");
        let imported = read(&text).unwrap();
        let mesh = &imported.scene.objects()[0].mesh;
        assert_eq!(mesh.triangles(), &[[0, 1, 2]]);
        assert_eq!(mesh.vertex(2), Point::new(0.0, 1.0, 0.0));
    }

    #[test]
    fn degenerate_triangles_are_kept_and_counted() {
        let text = format!("{SQUARE}f 1 1 2\nf 1 2 3\n");
        let imported = read(&text).unwrap();
        assert_eq!((imported.scene.triangle_count(), imported.degenerate_triangles), (2, 1));
    }

    #[test]
    fn crlf_tabs_and_comments_are_accepted() {
        let text = "# header\r\n\r\no\tpart one \r\nv 0 0 0 1\r\nv\t1 0 0\r\nv 0 1 0\r\nf 1 2 3 # tri\r\n";
        let imported = read(text).unwrap();
        assert_eq!(summary(&imported), owned(&[("part one", 3, 1)]));
    }

    #[test]
    fn each_error_names_the_line() {
        let cases: [(&str, &str); 8] = [
            ("v 1 2\n", "test.obj: line 1: expected 3 coordinates after `v`"),
            ("v 1 2 x\n", "line 1: expected a number, found \"x\""),
            ("v 0 0 0\nv nan 0 0\n", "line 2: object \"test\" has a NaN or infinite coordinate"),
            ("v 0 0 1e999\n", "line 1: object \"test\" has a NaN or infinite coordinate"),
            ("v 0 0 0\no p\nf 1 1 2\n", "line 3: object \"p\": vertex index 2 is out of range (1 vertices)"),
            ("v 0 0 0\nf 1 1 -2\n", "vertex index -2 is out of range"),
            ("v 0 0 0\nf 0 1 1\n", "vertex index 0 is out of range"),
            ("v 0 0 0\nf 1 1\n", "line 2: expected at least 3 vertex indices after `f`"),
        ];
        for (text, message) in cases {
            let err = read(text).unwrap_err().to_string();
            assert!(err.contains(message), "{text:?}: {err}");
        }
        let err = read(&format!("{SQUARE}f 1 x/2 3\n")).unwrap_err();
        assert!(err.to_string().contains("line 5: expected a vertex index"), "{err}");
    }

    #[test]
    fn an_o_without_faces_is_refused_with_its_line() {
        let err = read(&format!("{SQUARE}o full\nf 1 2 3\no hollow\no next\nf 1 2 3\n")).unwrap_err();
        assert_eq!(err.to_string(), "dir/test.obj: object \"hollow\" (line 7) has no triangles");
        let err = read(&format!("{SQUARE}o last\n")).unwrap_err();
        assert!(err.to_string().contains("\"last\" (line 5)"), "{err}");
    }

    #[test]
    fn a_file_without_faces_is_an_empty_scene() {
        for text in ["", "# nothing\n", SQUARE, "g a\ng b\n"] {
            let err = read(text).unwrap_err();
            assert!(matches!(err, ImportError::EmptyScene { .. }), "{text:?}: {err}");
        }
    }

    #[test]
    fn a_whole_file_is_one_object_named_by_its_stem() {
        let text = format!("{SQUARE}o a\nf 1 2 3\ng b\nf 1 3 4\n");
        let (object, _) = read_obj_as_one_object(text.as_bytes(), Path::new("d/pump.obj")).unwrap();
        assert_eq!((object.name.as_str(), object.mesh.triangle_count()), ("pump", 2));
        let err = read_obj_as_one_object(SQUARE.as_bytes(), Path::new("d/pump.obj")).unwrap_err();
        assert_eq!(err.to_string(), "d/pump.obj: object \"pump\" has no triangles");
    }

    /// A whole token as a number, as the parser reads it: at the end of
    /// the text, and before a blank (the short forms' path), which agree.
    fn parse_f64(token: &[u8]) -> Option<f64> {
        let at_end = scan_f64(token).filter(|(_, rest)| rest.is_empty()).map(|(value, _)| value);
        let line = [token, b" 1"].concat();
        let in_line = scan_f64(&line).filter(|(_, rest)| *rest == b" 1").map(|(value, _)| value);
        assert_eq!(at_end.map(f64::to_bits), in_line.map(f64::to_bits), "{}", String::from_utf8_lossy(token));
        at_end
    }

    fn parse_i64(token: &[u8]) -> Option<i64> {
        let at_end = scan_index(token).filter(|(_, rest)| rest.is_empty()).map(|(value, _)| value);
        let line = [token, b" 1"].concat();
        let in_line = short_index(&line).or_else(|| scan_index(&line));
        assert_eq!(at_end, in_line.filter(|(_, rest)| *rest == b" 1").map(|(value, _)| value));
        at_end
    }

    #[test]
    fn digit_runs_of_every_length_stop_at_any_non_digit() {
        for length in 0..=20 {
            let digits: String = (0..length).map(|i| char::from(b'0' + (i * 7 % 10) as u8)).collect();
            for stop in [b' ', b'.', b'/', b'e', 0xff, 0x80, 0xba, b'9' + 1, b'0' - 1] {
                let mut bytes = digits.clone().into_bytes();
                bytes.push(stop);
                bytes.extend_from_slice(b"123");
                let (value, count, rest) = leading_digits(&bytes, 0);
                assert_eq!((count, rest[0]), (length, stop), "{digits} then {stop}");
                if length <= 19 {
                    assert_eq!(value, digits.parse::<u64>().unwrap_or(0), "{digits} then {stop}");
                }
            }
            let (value, count, rest) = leading_digits(digits.as_bytes(), 7);
            assert_eq!((count, rest.len()), (length, 0));
            if length <= 18 {
                assert_eq!(value, format!("7{digits}").parse::<u64>().unwrap());
            }
        }
    }

    #[test]
    fn newlines_are_found_at_every_offset() {
        for length in 0..40 {
            let mut bytes = vec![b'x'; length];
            assert_eq!(find_newline(&bytes), None);
            for at in 0..length {
                bytes[at] = b'\n';
                assert_eq!(find_newline(&bytes), Some(at), "{length} {at}");
                bytes[at] = 0x8A;
            }
        }
    }

    #[test]
    fn lines_cut_by_the_reader_buffer_are_joined() {
        let text = format!("{SQUARE}o cut here\nf 1 2 3\nf 1 3 4");
        for capacity in [1, 2, 3, 7, 64] {
            let reader = std::io::BufReader::with_capacity(capacity, text.as_bytes());
            let imported = read_obj(reader, Path::new("cut.obj")).unwrap();
            assert_eq!(summary(&imported), owned(&[("cut here", 4, 2)]), "capacity {capacity}");
        }
    }

    /// A reader that fails after `good` bytes, some reads interrupted.
    struct Failing<'a> {
        text: &'a [u8],
        good: usize,
        reads: usize,
    }

    impl std::io::Read for Failing<'_> {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            self.reads += 1;
            if self.reads.is_multiple_of(3) {
                return Err(std::io::ErrorKind::Interrupted.into());
            }
            if self.good == 0 {
                return Err(std::io::Error::other("disk on fire"));
            }
            let n = buf.len().min(self.good).min(self.text.len()).min(5);
            buf[..n].copy_from_slice(&self.text[..n]);
            (self.text, self.good) = (&self.text[n..], self.good - n);
            Ok(n)
        }
    }

    #[test]
    fn a_failed_read_ends_the_file_after_the_lines_before_it() {
        // The read fails after line 5 or inside line 7: line 5's own error
        // (a bad index) comes first, as it did line by line.
        let text = format!("{SQUARE}f 1 2 9\no p\nf 1 2 3\n");
        for (good, chunking) in
            [(40, Chunking { block: 3, piece: 2 }), (40, Chunking::DEFAULT), (49, Chunking::DEFAULT)]
        {
            let reader = Failing { text: text.as_bytes(), good, reads: 0 };
            let mut objects = Vec::new();
            let ours = parse(
                reader,
                Path::new("f.obj"),
                Grouping::ByObjectLines,
                chunking,
                Vertices::default(),
                |o| objects.push(o),
            );
            let old = oracle::read_obj(
                std::io::BufReader::with_capacity(4, Failing { text: text.as_bytes(), good, reads: 0 }),
                Path::new("f.obj"),
            );
            let (ours, old) = (ours.unwrap_err().to_string(), old.unwrap_err().to_string());
            assert_eq!(ours, old, "{good} bytes");
            assert!(ours.contains("line 5"), "{ours}");
        }
        let reader = Failing { text: SQUARE.as_bytes(), good: 10, reads: 0 };
        let err = read_obj(reader, Path::new("f.obj")).unwrap_err();
        assert!(matches!(err, ImportError::Io { .. }), "{err}");
    }

    #[test]
    fn numbers_end_at_whitespace() {
        assert_eq!(scan_f64(b"1.5 2").map(|(v, rest)| (v, rest.len())), Some((1.5, 2)));
        assert_eq!(scan_f64(b"1e3\t2").map(|(v, rest)| (v, rest.len())), Some((1000.0, 2)));
        assert_eq!(scan_index(b"7/1/2 8").map(|(v, rest)| (v, rest.len())), Some((7, 2)));
        assert_eq!(scan_index(b"-7//2").map(|(v, rest)| (v, rest.len())), Some((-7, 0)));
        assert_eq!(scan_index(b"7x 8"), None);
        assert_eq!(scan_index(b"/7"), None);
    }

    #[test]
    fn integers_are_parsed_with_sign_and_overflow_checks() {
        assert_eq!(parse_i64(b"42"), Some(42));
        assert_eq!(parse_i64(b"-7"), Some(-7));
        assert_eq!(parse_i64(b"+7"), Some(7));
        assert_eq!(parse_i64(b"-"), None);
        assert_eq!(parse_i64(b""), None);
        assert_eq!(parse_i64(b"1234567890123456789"), None);
        assert_eq!(parse_i64(b"-123456789012345678"), Some(-123_456_789_012_345_678));
        assert_eq!(parse_i64(b"1a"), None);
    }

    #[test]
    fn decimals_that_std_refuses_are_refused() {
        for bad in
            ["", "-", ".", "1..2", "1.2.3", "--1", "1-", "0x10", "1,5", "12345678.9a", "1234567/", ":2345678"]
        {
            assert_eq!(parse_f64(bad.as_bytes()), None, "{bad:?}");
        }
        assert_eq!(parse_f64(b"-0").map(f64::is_sign_negative), Some(true));
    }

    /// Everything a parse gives: the objects and the zero-area count, or
    /// the error as printed and as built.
    fn outcome(text: &[u8], grouping: Grouping, chunking: Chunking) -> Result<(Vec<Object>, usize), String> {
        outcome_over(text, grouping, chunking, Vertices::default())
    }

    /// [`outcome`] with every vertex run but the newest in a spill file.
    fn outcome_spilled(
        text: &[u8],
        grouping: Grouping,
        chunking: Chunking,
    ) -> Result<(Vec<Object>, usize), String> {
        let spill =
            SpillFile::create_in(&std::env::temp_dir(), "test-vertices").map_err(|e| e.to_string())?;
        outcome_over(text, grouping, chunking, Vertices::spilling(spill, 0))
    }

    fn outcome_over(
        text: &[u8],
        grouping: Grouping,
        chunking: Chunking,
        vertices: Vertices,
    ) -> Result<(Vec<Object>, usize), String> {
        let mut objects = Vec::new();
        parse(text, Path::new("cut/test.obj"), grouping, chunking, vertices, |object| objects.push(object))
            .map(|degenerate| (objects, degenerate))
            .map_err(|e| format!("{e} / {e:?}"))
    }

    /// A random OBJ line, its indices still as shares of the vertices
    /// before it: mostly valid, with every statement, index form and fault
    /// the parser tells apart.
    #[derive(Debug, Clone)]
    enum Line {
        Vertex {
            xyz: Vec<String>,
            separator: &'static str,
        },
        /// Each corner: `Ok((from the end, share, suffix))` or a raw token.
        Face {
            corners: Vec<Result<(bool, f64, &'static str), &'static str>>,
            separator: &'static str,
            comment: bool,
        },
        Header {
            keyword: &'static str,
            separator: &'static str,
            name: &'static str,
        },
        Other(&'static str),
    }

    fn obj_line() -> impl Strategy<Value = Line> {
        let number = prop_oneof![
            200 => (-3i32..40).prop_map(|i| i.to_string()),
            100 => (-40_000i32..40_000).prop_map(|i| format!("{}", f64::from(i) / 16.0)),
            2 => prop::sample::select(vec!["1e3", "-0", "+2.5", ".5", "7."]).prop_map(String::from),
            1 => prop::sample::select(vec!["nan", "1e999", "x", "1..2", "-inf", "1e400"]).prop_map(String::from),
        ];
        let corner = prop_oneof![
            200 => (prop::bool::weighted(0.3), 0.0..1.0f64, prop::sample::select(vec!["", "", "/1", "//2", "/3/1"]))
                .prop_map(Ok),
            1 => prop::sample::select(vec!["0", "x", "4294967297", "-99999999999", "1/x", "99", "-99"]).prop_map(Err),
        ];
        let separator = prop::sample::select(vec![" ", " ", " ", "  ", "\t", " \t"]);
        prop_oneof![
            10 => (prop::collection::vec(number, 3..=4), separator.clone())
                .prop_map(|(xyz, separator)| Line::Vertex { xyz, separator }),
            8 => (prop::collection::vec(corner, 3..=6), separator.clone(), prop::bool::weighted(0.1))
                .prop_map(|(corners, separator, comment)| Line::Face { corners, separator, comment }),
            2 => (
                prop::sample::select(vec!["o", "o", "g", "g", " o", "g\t"]),
                separator,
                prop::sample::select(vec!["", "a", "b c", "a", "pipe 1", "ü"]),
            )
                .prop_map(|(keyword, separator, name)| Line::Header { keyword, separator, name }),
            1 => prop::sample::select(vec![
                "", "# note", "vt 0 0", "vn 0 0 1", "s 1", "usemtl m", "  ", "v", "f", "v 1 2", "f 1 2", "l 1 2"
            ])
            .prop_map(Line::Other),
        ]
    }

    /// OBJ text from random lines: indices become numbers of vertices
    /// defined before their line (a few reach past them).
    fn obj_text() -> impl Strategy<Value = String> {
        (0..8usize, prop::collection::vec(obj_line(), 0..80), prop::bool::ANY, prop::bool::ANY).prop_map(
            |(first_vertices, lines, crlf, final_newline)| {
                // Most files define vertices before their first face.
                let first =
                    (0..first_vertices).map(|i| Line::Vertex { xyz: vec![i.to_string(); 3], separator: " " });
                let mut vertices = 0;
                let rendered: Vec<String> = first
                    .chain(lines)
                    .map(|line| match line {
                        Line::Vertex { xyz, separator } => {
                            vertices += 1;
                            format!("v{separator}{}", xyz.join(separator))
                        }
                        Line::Face { corners, separator, comment } => {
                            let corners: Vec<String> = corners
                                .into_iter()
                                .map(|c| match c {
                                    Ok((back, share, suffix)) => {
                                        // One past the vertices now and then.
                                        let n = (share * (vertices as f64 + 0.02)) as i64 + 1;
                                        format!("{}{n}{suffix}", if back { "-" } else { "" })
                                    }
                                    Err(raw) => raw.to_string(),
                                })
                                .collect();
                            format!(
                                "f{separator}{}{}",
                                corners.join(separator),
                                if comment { " # c" } else { "" }
                            )
                        }
                        Line::Header { keyword, separator, name } => format!("{keyword}{separator}{name}"),
                        Line::Other(text) => text.to_string(),
                    })
                    .collect();
                let mut text = rendered.join(if crlf { "\r\n" } else { "\n" });
                if final_newline && !text.is_empty() {
                    text.push('\n');
                }
                text
            },
        )
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(30000))]

        /// The sequential parser's result, whatever the cut: blocks and
        /// pieces of a few bytes end inside lines, between `\r` and `\n`,
        /// and around `o`/`g` lines.
        #[test]
        fn any_cut_of_the_input_gives_the_sequential_result(
            text in obj_text(),
            block in 1usize..48,
            piece in 1usize..24,
            whole_file in prop::bool::ANY,
        ) {
            let source = Path::new("cut/test.obj");
            let expected = if whole_file {
                oracle::read_obj_as_one_object(text.as_bytes(), source).map(|(object, d)| (vec![object], d))
            } else {
                match oracle::read_obj(text.as_bytes(), source) {
                    // `parse` leaves an empty scene to its callers.
                    Err(ImportError::EmptyScene { .. }) => Ok((Vec::new(), 0)),
                    old => old.map(|imported| (imported.scene.into_objects(), imported.degenerate_triangles)),
                }
            };
            let expected = expected.map_err(|e| format!("{e} / {e:?}"));
            let grouping = if whole_file { Grouping::WholeFile } else { Grouping::ByObjectLines };
            prop_assert_eq!(outcome(text.as_bytes(), grouping, Chunking { block, piece }), expected.clone());
            // Vertices read back from a spill file, run by run.
            prop_assert_eq!(outcome_spilled(text.as_bytes(), grouping, Chunking { block, piece }), expected.clone());
            prop_assert_eq!(outcome(text.as_bytes(), grouping, Chunking::DEFAULT), expected);
        }
    }

    proptest! {
        #[test]
        fn digit_runs_parse_as_std_does(text in "[-+]?[0-9]{0,20}(\\.[0-9]{0,20})?") {
            let std: Option<f64> = text.parse().ok();
            prop_assert_eq!(parse_f64(text.as_bytes()).map(f64::to_bits), std.map(f64::to_bits), "{}", text);
            // parse_i64 takes up to 18 digits.
            if text.trim_start_matches(['-', '+']).len() <= 18 {
                prop_assert_eq!(parse_i64(text.as_bytes()), text.parse().ok());
            }
        }

        #[test]
        fn long_decimals_round_exactly_as_std_does(digits in 1u64..10_000_000_000_000_000_000, k in 0usize..=22) {
            let text = format!("{digits}");
            let text = if k >= text.len() { format!("0.{}{text}", "0".repeat(k - text.len())) } else {
                format!("{}.{}", &text[..text.len() - k], &text[text.len() - k..])
            };
            let std: f64 = text.parse().unwrap();
            prop_assert_eq!(parse_f64(text.as_bytes()).map(f64::to_bits), Some(std.to_bits()), "{}", text);
        }

        #[test]
        fn decimals_parse_exactly_as_std_does(
            x in prop_oneof![any::<f64>(), -1.0e7f64..1.0e7, (-100_000i64..100_000).prop_map(|i| i as f64 / 1000.0)],
            digits in 0usize..8,
        ) {
            for text in [format!("{x}"), format!("{x:.digits$}"), format!("{x:e}")] {
                let std: Option<f64> = text.parse().ok();
                let ours = parse_f64(text.as_bytes());
                prop_assert_eq!(ours.map(f64::to_bits), std.map(f64::to_bits), "{}", text);
            }
        }
    }
}
