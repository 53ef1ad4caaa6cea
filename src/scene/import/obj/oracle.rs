//! The sequential OBJ parser that the block parser replaced, kept as the
//! tests' oracle: any input must give the same objects or the same error.
//! Numbers are read by the block parser's scanners, tested against std.

use std::io::BufRead;
use std::path::{Path, PathBuf};

use super::Grouping;
use super::number::{scan_f64, scan_index, token_at};
use super::statement::find_newline;
use crate::geom::Point;
use crate::scene::import::load::file_stem;
use crate::scene::import::{ImportError, Imported, Location};
use crate::scene::{Object, Scene};

pub(super) fn read_obj<R: BufRead>(reader: R, source: &Path) -> Result<Imported, ImportError> {
    let parser = Parser::new(source, Grouping::ByObjectLines);
    let (objects, degenerate_triangles) = parser.parse(reader)?;
    if objects.is_empty() {
        return Err(ImportError::EmptyScene { file: source.into() });
    }
    Ok(Imported { scene: Scene::new(objects), degenerate_triangles })
}

pub(super) fn read_obj_as_one_object<R: BufRead>(
    reader: R,
    source: &Path,
) -> Result<(Object, usize), ImportError> {
    let (objects, degenerate_triangles) = Parser::new(source, Grouping::WholeFile).parse(reader)?;
    let object = objects.into_iter().next().ok_or_else(|| ImportError::EmptyScene { file: source.into() })?;
    Ok((object, degenerate_triangles))
}

/// An object whose faces are still being read, with global vertex indices.
struct Pending {
    name: String,
    /// The line of its `o` or `g`; `None` for the object named by the file.
    line: Option<u64>,
    triangles: Vec<[u32; 3]>,
}

impl Pending {
    fn new(name: String, line: Option<u64>) -> Pending {
        Pending { name, line, triangles: Vec::new() }
    }
}

struct Parser {
    file: PathBuf,
    grouping: Grouping,
    /// Every vertex of the file so far: faces may use any earlier one.
    vertices: Vec<Point>,
    /// True once an `o` line was read: from then on `g` lines are ignored.
    seen_o: bool,
    /// The object receiving faces.
    current: Pending,
    /// In a file without `o` so far, the finished `g` groups with faces:
    /// they become objects at the end, or merge into the file's object if an
    /// `o` line turns up.
    groups: Vec<Pending>,
    objects: Vec<Object>,
    degenerate_triangles: usize,
    /// Scratch for renumbering an object's vertices, reused across objects.
    local_index: Vec<u32>,
}

impl Parser {
    fn new(source: &Path, grouping: Grouping) -> Parser {
        Parser {
            file: source.into(),
            grouping,
            vertices: Vec::new(),
            seen_o: false,
            current: Pending::new(file_stem(source), None),
            groups: Vec::new(),
            objects: Vec::new(),
            degenerate_triangles: 0,
            local_index: Vec::new(),
        }
    }

    fn parse<R: BufRead>(mut self, mut reader: R) -> Result<(Vec<Object>, usize), ImportError> {
        // Lines are parsed where they lie in the reader's buffer; only a
        // line cut by the buffer's end is copied, into `carry`.
        let mut carry = Vec::new();
        let mut line_number = 0u64;
        loop {
            let buffer = match reader.fill_buf() {
                Ok(buffer) => buffer,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                Err(source) => return Err(ImportError::Io { file: self.file.clone(), source }),
            };
            if buffer.is_empty() {
                break;
            }
            let mut start = 0;
            if !carry.is_empty() {
                match find_newline(buffer) {
                    Some(end) => {
                        carry.extend_from_slice(&buffer[..end]);
                        line_number += 1;
                        self.statement(&carry, line_number)?;
                        carry.clear();
                        start = end + 1;
                    }
                    None => {
                        carry.extend_from_slice(buffer);
                        start = buffer.len();
                    }
                }
            }
            while let Some(end) = find_newline(&buffer[start..]) {
                line_number += 1;
                self.statement(&buffer[start..start + end], line_number)?;
                start += end + 1;
            }
            carry.extend_from_slice(&buffer[start..]);
            let read = buffer.len();
            reader.consume(read);
        }
        if !carry.is_empty() {
            self.statement(&carry, line_number + 1)?;
        }
        self.finish()?;
        Ok((self.objects, self.degenerate_triangles))
    }

    fn statement(&mut self, line: &[u8], line_number: u64) -> Result<(), ImportError> {
        // The two statements that make up nearly all of a file, first.
        match line {
            [b'v', b' ' | b'\t', rest @ ..] => return self.vertex(rest, line_number),
            [b'f', b' ' | b'\t', rest @ ..] => return self.face(rest, line_number),
            _ => {}
        }
        let line = line.trim_ascii();
        let (keyword, rest) = match line.iter().position(u8::is_ascii_whitespace) {
            Some(end) => (&line[..end], line[end..].trim_ascii_start()),
            None => (line, &line[line.len()..]),
        };
        match keyword {
            b"v" => self.vertex(rest, line_number),
            b"f" => self.face(rest, line_number),
            b"o" if self.grouping == Grouping::ByObjectLines => self.start_object(rest, line_number),
            b"g" if self.grouping == Grouping::ByObjectLines && !self.seen_o => {
                self.start_group(rest, line_number);
                Ok(())
            }
            _ => Ok(()),
        }
    }

    fn vertex(&mut self, rest: &[u8], line_number: u64) -> Result<(), ImportError> {
        let mut s = rest;
        let mut xyz = [0.0; 3];
        for c in &mut xyz {
            s = s.trim_ascii_start();
            if s.is_empty() {
                return Err(self.malformed(line_number, "3 coordinates after `v`", rest.trim_ascii()));
            }
            let (value, after) =
                scan_f64(s).ok_or_else(|| self.malformed(line_number, "a number", token_at(s)))?;
            *c = value;
            s = after;
        }
        if !xyz.iter().all(|c| c.is_finite()) {
            return Err(ImportError::NonFiniteCoordinate {
                file: self.file.clone(),
                object: self.current.name.clone(),
                at: Location::Line(line_number),
            });
        }
        if self.vertices.len() > u32::MAX as usize {
            return Err(self.malformed(line_number, "at most 2^32 vertices in one file", b"v"));
        }
        self.vertices.push(Point::from(xyz));
        Ok(())
    }

    fn face(&mut self, rest: &[u8], line_number: u64) -> Result<(), ImportError> {
        let mut corners = 0usize;
        let mut first = 0;
        let mut previous = 0;
        let mut s = rest;
        loop {
            s = s.trim_ascii_start();
            if matches!(s.first(), None | Some(b'#')) {
                break;
            }
            let (written, after) = scan_index(s).ok_or_else(|| {
                self.malformed(line_number, "a vertex index (v, v/vt, v//vn or v/vt/vn)", token_at(s))
            })?;
            s = after;
            let vertex = self.resolve(written, line_number)?;
            match corners {
                0 => first = vertex,
                1 => {}
                _ => self.current.triangles.push([first, previous, vertex]),
            }
            previous = vertex;
            corners += 1;
        }
        if corners < 3 {
            return Err(self.malformed(
                line_number,
                "at least 3 vertex indices after `f`",
                rest.trim_ascii(),
            ));
        }
        Ok(())
    }

    /// The 0-based file index of the vertex that index `written` (1-based,
    /// or negative to count back) names on line `line_number`.
    fn resolve(&self, written: i64, line_number: u64) -> Result<u32, ImportError> {
        let defined = self.vertices.len();
        let index = match written {
            1.. => usize::try_from(written - 1).ok().filter(|&i| i < defined),
            ..0 => usize::try_from(written.unsigned_abs()).ok().and_then(|back| defined.checked_sub(back)),
            0 => None,
        };
        // `vertex` refuses files of more than u32::MAX vertices, so this fits.
        index.and_then(|i| u32::try_from(i).ok()).ok_or_else(|| ImportError::IndexOutOfRange {
            file: self.file.clone(),
            object: self.current.name.clone(),
            at: Location::Line(line_number),
            index: written,
            vertices: defined,
        })
    }

    fn start_object(&mut self, rest: &[u8], line_number: u64) -> Result<(), ImportError> {
        let next = Pending::new(String::from_utf8_lossy(rest).into_owned(), Some(line_number));
        let previous = std::mem::replace(&mut self.current, next);
        if self.seen_o {
            return self.build(previous);
        }
        // The first `o`: `g` lines so far did not start objects after all;
        // every face before this line belongs to the object named by the file.
        self.seen_o = true;
        let mut merged = Pending::new(file_stem(&self.file), None);
        for group in std::mem::take(&mut self.groups).into_iter().chain([previous]) {
            merged.triangles.extend_from_slice(&group.triangles);
        }
        if merged.triangles.is_empty() { Ok(()) } else { self.build(merged) }
    }

    fn start_group(&mut self, rest: &[u8], line_number: u64) {
        let next = Pending::new(String::from_utf8_lossy(rest).into_owned(), Some(line_number));
        let previous = std::mem::replace(&mut self.current, next);
        if !previous.triangles.is_empty() {
            self.groups.push(previous);
        }
    }

    fn finish(&mut self) -> Result<(), ImportError> {
        let last = std::mem::replace(&mut self.current, Pending::new(String::new(), None));
        match self.grouping {
            Grouping::ByObjectLines if self.seen_o => self.build(last),
            Grouping::ByObjectLines => {
                for group in std::mem::take(&mut self.groups).into_iter().chain([last]) {
                    if !group.triangles.is_empty() {
                        self.build(group)?;
                    }
                }
                Ok(())
            }
            Grouping::WholeFile => self.build(last),
        }
    }

    /// Turns a finished object into a mesh over the vertices it uses.
    fn build(&mut self, pending: Pending) -> Result<(), ImportError> {
        let Pending { name, line, mut triangles } = pending;
        let points = self.renumber(&mut triangles);
        let object = super::super::load::object(&self.file, name, line, &points, triangles)?;
        self.degenerate_triangles += object.mesh.degenerate_triangles();
        self.objects.push(object);
        Ok(())
    }

    /// Rewrites `triangles` from file indices to the object's own, numbered
    /// in ascending file order, and returns the object's vertices.
    fn renumber(&mut self, triangles: &mut [[u32; 3]]) -> Vec<Point> {
        let corners = triangles.as_flattened_mut();
        let lowest = corners.iter().copied().min().unwrap_or(0);
        let highest = corners.iter().copied().max().unwrap_or(0);
        let span = (highest - lowest) as usize + 1;
        // An object's vertices usually sit together in the file (always, in
        // our own form): a table over their span renumbers in linear time.
        // Objects that pick vertices from all over a shared list sort instead.
        if span <= 4 * corners.len() + 1024 {
            const UNUSED: u32 = u32::MAX;
            self.local_index.clear();
            self.local_index.resize(span, UNUSED);
            for &c in corners.iter() {
                self.local_index[(c - lowest) as usize] = 0;
            }
            let mut points = Vec::new();
            for (offset, slot) in self.local_index.iter_mut().enumerate() {
                if *slot != UNUSED {
                    *slot = points.len() as u32;
                    points.push(self.vertices[lowest as usize + offset]);
                }
            }
            for c in corners.iter_mut() {
                *c = self.local_index[(*c - lowest) as usize];
            }
            points
        } else {
            let mut used = corners.to_vec();
            used.sort_unstable();
            used.dedup();
            for c in corners.iter_mut() {
                // Every corner is in `used`, which is sorted.
                *c = used.binary_search(c).unwrap_or_default() as u32;
            }
            used.iter().map(|&i| self.vertices[i as usize]).collect()
        }
    }

    fn malformed(&self, line_number: u64, expected: &'static str, found: &[u8]) -> ImportError {
        // Keep messages short when a binary file is read as OBJ.
        const SHOWN: usize = 60;
        let mut shown = String::from_utf8_lossy(&found[..found.len().min(SHOWN)]).into_owned();
        if found.len() > SHOWN {
            shown.push_str("...");
        }
        ImportError::Malformed { file: self.file.clone(), line: line_number, expected, found: shown }
    }
}
