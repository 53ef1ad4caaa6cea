//! OBJ import's stitching (see `obj.rs`): parsed pieces put together in
//! file order (vertex numbers and lines offset by what came before,
//! objects continued across pieces), and complete objects built.

use std::ops::Range;
use std::path::{Path, PathBuf};

use rayon::prelude::*;

use super::Grouping;
use super::chunk::Parsed;
use super::statement::{Header, LineError, Piece};
use super::vertices::Vertices;
use crate::geom::Point;
use crate::scene::Object;
use crate::scene::import::load::{self, file_stem};
use crate::scene::import::{ImportError, Location};

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
pub(super) struct Built {
    /// In file order, each with its count of zero-area triangles; the first
    /// failure ends the file (they are handed on as they are, not copied).
    pub(super) objects: Vec<Result<(Object, usize), ImportError>>,
    pub(super) error: Option<ImportError>,
}

/// Puts parsed pieces together in file order: the file's vertices, line
/// numbers and objects.
pub(super) struct Stitcher {
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
    pub(super) fn new(source: &Path, grouping: Grouping, vertices: Vertices) -> Stitcher {
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
    pub(super) fn block(&mut self, parsed: &mut Parsed) -> Built {
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
    pub(super) fn finish(&mut self) -> Built {
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
    let object = load::object(file, pending.name, pending.line, &scratch.points, triangles)?;
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
