//! Wavefront OBJ import: a streaming line parser for mktree's scene form
//! (`o NAME`, `v x y z` in millimetres, `f a b c`; see `scene::export`)
//! that also reads common OBJ from other tools.
//!
//! Why not `tobj`: it reads coordinates as f32 (our models need f64 before
//! the anchor/offset split), gives no line numbers in errors, splits objects
//! by its own o/g rule, and builds whole models in memory per material. This
//! parser reads lines where they lie in the reader's buffer, parses numbers
//! without allocating (eight digits at a time, rounded exactly; std's parser
//! for exponents and the like), and turns each object into a [`Mesh`] as
//! soon as the next one starts.
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
//! Memory: all vertices of the file are kept (24 bytes each), as any later
//! face may use any earlier vertex.

use std::io::BufRead;
use std::path::{Path, PathBuf};

use super::load::file_stem;
use super::{ImportError, Imported, Location};
use crate::geom::Point;
use crate::scene::{Object, Scene};

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
pub fn read_obj<R: BufRead>(reader: R, source: &Path) -> Result<Imported, ImportError> {
    let parser = Parser::new(source, Grouping::ByObjectLines);
    let (objects, degenerate_triangles) = parser.parse(reader)?;
    if objects.is_empty() {
        return Err(ImportError::EmptyScene { file: source.into() });
    }
    Ok(Imported { scene: Scene::new(objects), degenerate_triangles })
}

/// Reads a whole OBJ file as one object named by the file stem, ignoring
/// its `o` and `g` lines (a directory scene has one object per file).
/// Returns the object and its count of zero-area triangles.
pub(super) fn read_obj_as_one_object<R: BufRead>(
    reader: R,
    source: &Path,
) -> Result<(Object, usize), ImportError> {
    let (objects, degenerate_triangles) = Parser::new(source, Grouping::WholeFile).parse(reader)?;
    // The whole-file grouping builds exactly one object or fails.
    let object = objects.into_iter().next().ok_or_else(|| ImportError::EmptyScene { file: source.into() })?;
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
        let object = super::load::object(&self.file, name, line, &points, triangles)?;
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
    if let Some(fast) = scan_plain_decimal(s) {
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
/// file has 10^18 vertices). A digit at a time: indices are short, and
/// most end their line, where an eight-byte load would need padding.
fn scan_index(s: &[u8]) -> Option<(i64, &[u8])> {
    let (negative, mut rest) = split_sign(s);
    let mut value: i64 = 0;
    let mut digits = 0;
    while let Some((&b, after)) = rest.split_first() {
        let digit = b.wrapping_sub(b'0');
        if digit > 9 {
            break;
        }
        value = value.wrapping_mul(10).wrapping_add(i64::from(digit));
        digits += 1;
        rest = after;
    }
    if !(1..=18).contains(&digits) {
        return None;
    }
    if rest.first() == Some(&b'/') {
        rest = &rest[token_at(rest).len()..];
    }
    if !rest.first().is_none_or(u8::is_ascii_whitespace) {
        return None;
    }
    Some((if negative { -value } else { value }, rest))
}

fn split_sign(s: &[u8]) -> (bool, &[u8]) {
    match s.split_first() {
        Some((b'-', body)) => (true, body),
        Some((b'+', body)) => (false, body),
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
    const ZEROS: u64 = 0x3030_3030_3030_3030;
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
        // A byte's high bit is set here iff it is not a digit; bytes after
        // the first non-digit may be garbled by borrows, but are not used.
        let non_digits =
            (chunk.wrapping_sub(ZEROS) | chunk.wrapping_add(0x4646_4646_4646_4646)) & 0x8080_8080_8080_8080;
        let digits = (non_digits.trailing_zeros() / 8) as usize;
        if digits == 0 {
            return (value, count, s);
        }
        // The run's digits into the top bytes, '0's below them.
        let shift = 8 * (8 - digits) as u32;
        let aligned = chunk.checked_shl(shift).unwrap_or(0) | ZEROS.checked_shr(64 - shift).unwrap_or(0);
        value = value.wrapping_mul(POWERS_OF_TEN[digits]).wrapping_add(eight_digits(aligned));
        count += digits;
        s = &s[digits..];
        if digits < 8 {
            return (value, count, s);
        }
    }
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

    /// A whole token as a number, as the parser reads it.
    fn parse_f64(token: &[u8]) -> Option<f64> {
        scan_f64(token).filter(|(_, rest)| rest.is_empty()).map(|(value, _)| value)
    }

    fn parse_i64(token: &[u8]) -> Option<i64> {
        scan_index(token).filter(|(_, rest)| rest.is_empty()).map(|(value, _)| value)
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
