//! OBJ import's statements (see `obj.rs`): a piece of the file parsed on
//! its own, line by line: `v`, `f`, `o` and `g`, and the rest skipped.

use super::number::{scan_f64, scan_index, short_index, token_at};
use crate::geom::Point;

/// A line's error, before it is placed in the file.
#[derive(Debug)]
pub(super) enum LineError {
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
pub(super) struct Header {
    /// `o` (else `g`).
    pub(super) object: bool,
    pub(super) name: String,
    /// 1-based, in the piece.
    pub(super) line: u64,
    /// The piece's triangles before the line.
    pub(super) triangles_before: usize,
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
pub(super) const MAX_VERTICES: u64 = 1 << 32;

/// A piece of the file parsed on its own.
///
/// Without the number of vertices before it (the base), a piece still
/// reads every line, and keeps what it cannot check: positive indices are
/// file indices already, checked later against [`Piece::reach`]; negative
/// ones are offsets from the base, filled in by [`Piece::resolve`]. Given
/// the base, every index is checked on its line, so the first error is
/// found where it is.
pub(super) struct Piece {
    /// Lines read (all of the piece's, unless it stopped at an error).
    pub(super) lines: u64,
    pub(super) vertices: Vec<Point>,
    /// All faces of the piece, as file vertex indices once resolved; the
    /// headers say which object each belongs to.
    pub(super) triangles: Vec<[u32; 3]>,
    pub(super) headers: Vec<Header>,
    /// The fewest vertices before the piece for which its indices are in
    /// range: the most by which an index reaches beyond the piece's
    /// vertices before its line.
    reach: i64,
    relative: Vec<Relative>,
    /// The first error and its line in the piece: parsing stopped there.
    pub(super) error: Option<(u64, LineError)>,
}

impl Piece {
    pub(super) fn parse(text: &[u8], base: Option<u64>) -> Piece {
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
    pub(super) fn resolve(&mut self, base: u64) -> bool {
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

/// The index of the first `\n` in `s`, eight bytes at a time.
pub(super) fn find_newline(s: &[u8]) -> Option<usize> {
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
