//! The fuzz input read as a stream of choices, and the edits it chooses:
//! a field of a structure set to a value (small, shifted, a boundary, a
//! special float, another field's, a block id), raw bytes, or a chunk
//! copied from one place of a structure to another. Deterministic: the same
//! input makes the same edits.

use crate::forge::Image;

/// The input as choices; past its end every choice is 0.
#[derive(Debug, Clone)]
pub struct Choices<'a> {
    data: &'a [u8],
}

impl<'a> Choices<'a> {
    pub fn new(data: &'a [u8]) -> Choices<'a> {
        Choices { data }
    }

    /// True when the input is used up.
    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }

    pub fn u8(&mut self) -> u8 {
        match self.data.split_first() {
            Some((&b, rest)) => {
                self.data = rest;
                b
            }
            None => 0,
        }
    }

    pub fn u16(&mut self) -> u16 {
        u16::from_le_bytes([self.u8(), self.u8()])
    }

    pub fn u32(&mut self) -> u32 {
        u32::from(self.u16()) | u32::from(self.u16()) << 16
    }

    pub fn u64(&mut self) -> u64 {
        u64::from(self.u32()) | u64::from(self.u32()) << 32
    }

    /// A number below `n` (0 when `n` is 0), taking as few bytes as `n` needs.
    pub fn below(&mut self, n: usize) -> usize {
        match n {
            0 => 0,
            1..=256 => usize::from(self.u8()) % n,
            257..=65536 => usize::from(self.u16()) % n,
            _ => self.u32() as usize % n,
        }
    }

    /// `n` bytes.
    pub fn bytes(&mut self, n: usize) -> Vec<u8> {
        (0..n).map(|_| self.u8()).collect()
    }
}

/// How a field is stored.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Width {
    U8,
    U16,
    U32,
    U64,
    F32,
    F64,
}

impl Width {
    fn len(self) -> usize {
        match self {
            Width::U8 => 1,
            Width::U16 => 2,
            Width::U32 | Width::F32 => 4,
            Width::U64 | Width::F64 => 8,
        }
    }
}

/// A field of a structure: its absolute offset in the image and its type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Field {
    pub at: usize,
    pub width: Width,
}

/// The fields and byte ranges of one structure of a file, and the places
/// (record and entry starts) chunks are copied between.
#[derive(Debug, Clone, Default)]
pub struct Catalog {
    pub fields: Vec<Field>,
    /// (start, length), absolute.
    pub ranges: Vec<(usize, usize)>,
    pub anchors: Vec<usize>,
}

impl Catalog {
    /// Adds fields of `width` at `at` + each of `offsets`.
    pub fn add(&mut self, at: usize, width: Width, offsets: impl IntoIterator<Item = usize>) {
        self.fields.extend(offsets.into_iter().map(|o| Field { at: at + o, width }));
    }
}

const INTERESTING: [u64; 27] = [
    0,
    1,
    2,
    3,
    4,
    7,
    8,
    16,
    24,
    0x7f,
    0x80,
    0xff,
    0x100,
    0x3ff,
    0x400,
    0xfff,
    0x1000,
    0x7fff,
    0x8000,
    0xffff,
    0x1_0000,
    0x7fff_ffff,
    0x8000_0000,
    0xffff_fffe,
    0xffff_ffff,
    u64::MAX / 2,
    u64::MAX,
];

const SPECIAL: [f64; 24] = [
    0.0,
    -0.0,
    1.0,
    -1.0,
    0.5,
    2.0,
    1e-9,
    1e-30,
    1e-300,
    f64::MIN_POSITIVE,
    5e-324,
    1e9,
    1e30,
    1e300,
    f64::MAX,
    -f64::MAX,
    f64::INFINITY,
    f64::NEG_INFINITY,
    f64::NAN,
    65535.0,
    65536.0,
    4096.0,
    -1e30,
    3.4e38,
];

fn read(img: &Image, f: Field) -> u64 {
    (0..f.width.len()).fold(0, |v, i| v | u64::from(img.u8(f.at + i)) << (8 * i))
}

fn write(img: &mut Image, f: Field, v: u64) {
    img.put(f.at, &v.to_le_bytes()[..f.width.len()]);
}

fn as_float(w: Width, bits: u64) -> f64 {
    match w {
        Width::F32 => f64::from(f32::from_bits(bits as u32)),
        _ => f64::from_bits(bits),
    }
}

fn float_bits(w: Width, x: f64) -> u64 {
    match w {
        Width::F32 => u64::from((x as f32).to_bits()),
        _ => x.to_bits(),
    }
}

/// Sets one field of `catalog`, chosen by the input, to a value it chooses.
pub fn edit_field(img: &mut Image, catalog: &Catalog, c: &mut Choices) {
    let Some(&f) = catalog.fields.get(c.below(catalog.fields.len())) else { return };
    let cur = read(img, f);
    let float = matches!(f.width, Width::F32 | Width::F64);
    let v = match c.u8() % 7 {
        0 if float => float_bits(f.width, f64::from(c.u8() as i8)),
        0 => u64::from(c.u8()),
        1 if float => {
            let x = as_float(f.width, cur);
            float_bits(f.width, x + x * f64::from(c.u8() as i8) / 64.0 + f64::from(c.u8() as i8) / 16.0)
        }
        1 => cur.wrapping_add(c.u8() as i8 as u64),
        2 if float => float_bits(f.width, SPECIAL[c.below(SPECIAL.len())]),
        2 => INTERESTING[c.below(INTERESTING.len())],
        3 => c.u64(),
        4 => {
            let other = catalog.fields[c.below(catalog.fields.len())];
            read(img, other)
        }
        5 => cur ^ 1 << (c.u8() as usize % (8 * f.width.len())),
        _ => c.below(img.blocks() as usize + 2) as u64,
    };
    write(img, f, v);
}

/// Overwrites up to 8 bytes somewhere in one of `catalog`'s ranges.
pub fn edit_raw(img: &mut Image, catalog: &Catalog, c: &mut Choices) {
    let Some(&(start, len)) = catalog.ranges.get(c.below(catalog.ranges.len())) else { return };
    let at = start + c.below(len);
    let n = (1 + c.below(8)).min(start + len - at);
    let bytes = c.bytes(n);
    img.put(at, &bytes);
}

/// Copies up to 256 bytes from one anchor of `catalog` to another, within their blocks.
pub fn copy_chunk(img: &mut Image, catalog: &Catalog, c: &mut Choices) {
    let n = catalog.anchors.len();
    let (from, to) = (catalog.anchors.get(c.below(n)).copied(), catalog.anchors.get(c.below(n)).copied());
    let len = 1 + c.below(256);
    if let (Some(from), Some(to)) = (from, to) {
        // Within the blocks of both ends: a chunk moves a structure's bytes, not frames.
        let len = len.min(img.bs - from % img.bs).min(img.bs - to % img.bs);
        let len = len.min(img.bytes.len().saturating_sub(from)).min(img.bytes.len().saturating_sub(to));
        img.bytes.copy_within(from..from + len, to);
    }
}
