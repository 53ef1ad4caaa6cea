//! The bytes a node's level of detail stores: one voxel set (b(S_n,k)) or a
//! list of per-object sets (B(S_n,k)). Layout: `format-spec/lod.md`.
//! Decoding never panics and never allocates more than MAX_CELLS bits.

use super::{Grid, Lattice, LodError, Voxels};
use crate::geom::Aabb;

/// How a voxel set is stored.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Form {
    /// One bit per cell (k = 2, the cuberille).
    Bitmap,
    /// Disjoint cell boxes, [`Voxels::boxes`] (k >= 3).
    Boxes,
}

const HEADER: usize = 68;
const BOX_BYTES: usize = 12;

impl Form {
    fn code(self) -> u8 {
        match self {
            Form::Bitmap => 1,
            Form::Boxes => 2,
        }
    }
}

fn bitmap_bytes(cells: u64) -> usize {
    (cells as usize).div_ceil(32) * 4
}

/// The bytes [`encode`] appends for `v` in `form`.
pub fn encoded_len(v: &Voxels, form: Form) -> usize {
    HEADER
        + match form {
            Form::Bitmap => bitmap_bytes(v.grid.cells()),
            Form::Boxes => v.boxes().len() * BOX_BYTES,
        }
}

/// Appends the blob of `v` in `form` to `out` (a multiple of 4 bytes).
pub fn encode(v: &Voxels, form: Form, out: &mut Vec<u8>) {
    let g = &v.grid;
    let boxes = if form == Form::Boxes { v.boxes() } else { Vec::new() };
    let payload = match form {
        Form::Bitmap => bitmap_bytes(g.cells()),
        Form::Boxes => boxes.len() * BOX_BYTES,
    };
    out.extend_from_slice(&[form.code(), g.level(), 0, 0]);
    for d in g.dims() {
        out.extend_from_slice(&d.to_le_bytes());
    }
    for c in g.bounds().to_array() {
        out.extend_from_slice(&c.to_le_bytes());
    }
    out.extend_from_slice(&(payload as u32).to_le_bytes());
    match form {
        Form::Bitmap => {
            let start = out.len();
            for w in &v.bits {
                out.extend_from_slice(&w.to_le_bytes());
            }
            out.truncate(start + payload);
        }
        Form::Boxes => {
            for b in boxes {
                for c in b {
                    out.extend_from_slice(&c.to_le_bytes());
                }
            }
        }
    }
}

/// Little-endian reads that fail instead of panicking.
struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8], LodError> {
        let end = self.at.checked_add(n).filter(|&e| e <= self.bytes.len());
        let end = end.ok_or_else(|| {
            LodError::Corrupt(format!(
                "{what}: needs {n} bytes at offset {}, blob has {}",
                self.at,
                self.bytes.len()
            ))
        })?;
        let s = self.bytes.get(self.at..end).unwrap_or_default();
        self.at = end;
        Ok(s)
    }

    fn array<const N: usize>(&mut self, what: &str) -> Result<[u8; N], LodError> {
        let s = self.take(N, what)?;
        let mut a = [0u8; N];
        a.copy_from_slice(s);
        Ok(a)
    }

    fn u32(&mut self, what: &str) -> Result<u32, LodError> {
        Ok(u32::from_le_bytes(self.array(what)?))
    }
}

/// Decodes one blob at the start of `bytes` on `lattice`; returns the set
/// and the bytes consumed. Every field is checked: the form, the bounds, the
/// dims (they must be those of [`Grid::new`] for the stored bounds and
/// level), the payload length, zero padding bits, and boxes inside the grid
/// and disjoint.
pub fn decode(bytes: &[u8], lattice: &Lattice) -> Result<(Voxels, usize), LodError> {
    let mut r = Reader { bytes, at: 0 };
    let [form, level, r0, r1] = r.array::<4>("header")?;
    let form = match form {
        1 => Form::Bitmap,
        2 => Form::Boxes,
        f => return Err(LodError::Corrupt(format!("form {f} is neither 1 (bitmap) nor 2 (boxes)"))),
    };
    if (r0, r1) != (0, 0) {
        return Err(LodError::Corrupt("reserved header bytes are not zero".into()));
    }
    let dims = [r.u32("dims")?, r.u32("dims")?, r.u32("dims")?];
    let mut b = [0f64; 6];
    for c in &mut b {
        *c = f64::from_le_bytes(r.array("bounds")?);
    }
    let grid = Grid::new(lattice, level, &Aabb::from_array(b))
        .map_err(|e| LodError::Corrupt(format!("bounds {b:?} at level {level}: {e}")))?;
    if grid.dims() != dims {
        return Err(LodError::Corrupt(format!("dims {dims:?}, but the bounds give {:?}", grid.dims())));
    }
    let payload = r.u32("payload length")? as usize;
    let mut v = Voxels::empty(grid);
    match form {
        Form::Bitmap => {
            let want = bitmap_bytes(v.grid.cells());
            if payload != want {
                return Err(LodError::Corrupt(format!("bitmap of {payload} bytes, {want} expected")));
            }
            let data = r.take(payload, "bitmap")?;
            for (i, chunk) in data.chunks(8).enumerate() {
                let mut w = [0u8; 8];
                w[..chunk.len()].copy_from_slice(chunk);
                if let Some(word) = v.bits.get_mut(i) {
                    *word = u64::from_le_bytes(w);
                }
            }
            let cells = v.grid.cells() as usize;
            if !cells.is_multiple_of(64) && v.bits.last().is_some_and(|&w| w >> (cells % 64) != 0) {
                return Err(LodError::Corrupt("bitmap padding bits are not zero".into()));
            }
        }
        Form::Boxes => {
            if !payload.is_multiple_of(BOX_BYTES) {
                return Err(LodError::Corrupt(format!("boxes payload of {payload} bytes")));
            }
            let data = r.take(payload, "boxes")?;
            for (n, chunk) in data.chunks_exact(BOX_BYTES).enumerate() {
                let mut bx = [0u16; 6];
                for (c, pair) in bx.iter_mut().zip(chunk.chunks_exact(2)) {
                    *c = u16::from_le_bytes([pair[0], pair[1]]);
                }
                if !v.fill_box(bx) {
                    return Err(LodError::Corrupt(format!(
                        "box {n} {bx:?}: empty, outside {dims:?} or overlapping"
                    )));
                }
            }
        }
    }
    Ok((v, r.at))
}

/// Appends B(S_n,k): a u32 count, then per object its id (u32) and its blob.
pub fn encode_objects(items: &[(u32, &Voxels)], form: Form, out: &mut Vec<u8>) {
    out.extend_from_slice(&(items.len() as u32).to_le_bytes());
    for (id, v) in items {
        out.extend_from_slice(&id.to_le_bytes());
        encode(v, form, out);
    }
}

/// Decodes what [`encode_objects`] wrote; `bytes` must hold exactly that.
pub fn decode_objects(bytes: &[u8], lattice: &Lattice) -> Result<Vec<(u32, Voxels)>, LodError> {
    let mut r = Reader { bytes, at: 0 };
    let count = r.u32("object count")?;
    let mut out = Vec::new();
    for _ in 0..count {
        let id = r.u32("object id")?;
        let rest = bytes.get(r.at..).unwrap_or_default();
        let (v, used) = decode(rest, lattice)?;
        r.at += used;
        out.push((id, v));
    }
    if r.at != bytes.len() {
        return Err(LodError::Corrupt(format!("{} bytes after the last object", bytes.len() - r.at)));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::Point;

    fn sample() -> (Lattice, Voxels) {
        let l = Lattice { origin: Point::new(0.25, 0.0, 0.0), cell: 0.5 };
        let g = Grid::new(&l, 1, &Aabb::from_array([0.0, 0.0, 0.0, 5.0, 3.0, 1.5])).unwrap();
        let mut v = Voxels::empty(g);
        assert!(v.fill_box([0, 0, 0, 2, 1, 1]));
        assert!(v.fill_box([3, 2, 1, 5, 3, 2]));
        (l, v)
    }

    #[test]
    fn both_forms_round_trip_with_the_predicted_length() {
        let (l, v) = sample();
        for form in [Form::Bitmap, Form::Boxes] {
            let mut out = vec![7u8];
            encode(&v, form, &mut out);
            assert_eq!(out.len() - 1, encoded_len(&v, form));
            assert_eq!(out.len() % 4, 1);
            let (back, used) = decode(&out[1..], &l).unwrap();
            assert_eq!((back, used), (v.clone(), out.len() - 1));
        }
    }

    #[test]
    fn dims_that_disagree_with_the_bounds_are_refused() {
        let (l, v) = sample();
        let mut out = Vec::new();
        encode(&v, Form::Boxes, &mut out);
        out[4] ^= 1;
        assert!(matches!(decode(&out, &l), Err(LodError::Corrupt(_))));
    }

    #[test]
    fn every_truncation_is_refused() {
        let (l, v) = sample();
        let mut out = Vec::new();
        encode_objects(&[(3, &v), (9, &v)], Form::Boxes, &mut out);
        assert_eq!(decode_objects(&out, &l).unwrap(), vec![(3, v.clone()), (9, v)]);
        for n in 0..out.len() {
            assert!(decode_objects(&out[..n], &l).is_err(), "{n}");
        }
    }
}
