//! Voxel bounds as stored inline in node records (format-spec/lod.md,
//! "Inline voxel blobs"): a grid of whole lattice cells, named by its first
//! cell and its size, so a 24-byte head replaces the 48 bytes of f64 bounds,
//! then the cells as a bitmap or as boxes, whichever is smaller.

use zerocopy::byteorder::little_endian::{I32, U16, U32};
use zerocopy::{FromBytes, Immutable, IntoBytes, KnownLayout, Unaligned};

use super::{Grid, Lattice, LodError, MAX_CELLS, Voxels};
use crate::geom::Aabb;

const FORM_BITMAP: u8 = 1;
const FORM_BOXES8: u8 = 2;
const FORM_BOXES16: u8 = 3;

#[derive(Debug, Clone, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
#[repr(C)]
pub(crate) struct BlobHead {
    pub(crate) level: u8,
    pub(crate) form: u8,
    pub(crate) reserved0: [u8; 2],
    pub(crate) first: [I32; 3],
    pub(crate) dims: [U16; 3],
    pub(crate) reserved1: [u8; 2],
}
/// Bytes of a blob's head.
pub const HEAD_LEN: usize = 24;
const _: () = assert!(size_of::<BlobHead>() == HEAD_LEN);

/// The grid of whole cells of lattice level `level` that covers `b`: from
/// the last plane at or below `b.min` to the first at or above `b.max`
/// (at least one cell per axis). Also returns the first plane's index.
pub fn aligned_grid(lattice: &Lattice, level: u8, b: &Aabb) -> Result<(Grid, [i64; 3]), LodError> {
    if !lattice.is_valid() || b.is_empty() || !b.to_array().iter().all(|c| c.is_finite()) {
        return Err(LodError::BadBounds(b.to_array()));
    }
    let s = lattice.cell_at(level);
    let mut first = [0i64; 3];
    let mut lo = [0f64; 3];
    let mut hi = [0f64; 3];
    for a in 0..3 {
        let guess = ((b.min[a] - lattice.origin[a]) / s).floor();
        if !guess.is_finite() || guess.abs() >= f64::from(i32::MAX) {
            return Err(LodError::BadBounds(b.to_array()));
        }
        let mut n = guess as i64;
        while lattice.plane(level, a, n) > b.min[a] {
            n -= 1;
        }
        while lattice.plane(level, a, n + 1) <= b.min[a] {
            n += 1;
        }
        let mut m = n + 1;
        while lattice.plane(level, a, m) < b.max[a] {
            m += 1;
            if m - n > i64::from(u16::MAX) {
                return Err(LodError::TooLarge { level, dims: [0; 3], cells: MAX_CELLS + 1 });
            }
        }
        first[a] = n;
        lo[a] = lattice.plane(level, a, n);
        hi[a] = lattice.plane(level, a, m);
    }
    let grid = Grid::new(lattice, level, &Aabb::from_array([lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]]))?;
    Ok((grid, first))
}

/// The form and payload bytes `v` encodes to: a bitmap or boxes, the smaller.
fn form_of(v: &Voxels, boxes: usize) -> (u8, usize) {
    let small = v.grid().dims().iter().all(|&d| d <= 255);
    let box_bytes = 4 + boxes * if small { 6 } else { 12 };
    let bitmap_bytes = (v.grid().cells() as usize).div_ceil(8);
    if bitmap_bytes <= box_bytes {
        (FORM_BITMAP, bitmap_bytes)
    } else {
        (if small { FORM_BOXES8 } else { FORM_BOXES16 }, box_bytes)
    }
}

/// Bytes `v` encodes to.
pub fn encoded_len(v: &Voxels) -> usize {
    HEAD_LEN + form_of(v, v.boxes().len()).1
}

/// Encodes `v` (on a grid from [`aligned_grid`] whose first planes are `first`).
pub fn encode(v: &Voxels, first: [i64; 3]) -> Vec<u8> {
    let dims = v.grid().dims();
    let cells = v.grid().cells() as usize;
    let boxes = v.boxes();
    let small = dims.iter().all(|&d| d <= 255);
    let (form, _) = form_of(v, boxes.len());
    let bitmap_bytes = cells.div_ceil(8);
    let head = BlobHead {
        level: v.grid().level(),
        form,
        reserved0: [0; 2],
        first: first.map(|f| I32::new(f as i32)),
        dims: dims.map(|d| U16::new(d as u16)),
        reserved1: [0; 2],
    };
    let mut out = head.as_bytes().to_vec();
    match form {
        FORM_BITMAP => {
            let mut bits = vec![0u8; bitmap_bytes];
            for i in v.set_cells() {
                bits[i / 8] |= 1 << (i % 8);
            }
            out.extend_from_slice(&bits);
        }
        _ => {
            out.extend_from_slice(&(boxes.len() as u32).to_le_bytes());
            for b in &boxes {
                for &c in b {
                    // Corners lie in 0 ..= dims: u8 when every axis has at most 255 cells.
                    if small { out.push(c as u8) } else { out.extend_from_slice(&c.to_le_bytes()) }
                }
            }
        }
    }
    out
}

/// Decodes a blob on `lattice`, checking every rule; the work is bounded by
/// the grid's cells, which the head bounds by [`MAX_CELLS`].
pub fn decode(bytes: &[u8], lattice: &Lattice) -> Result<Voxels, LodError> {
    let bad = |d: &str| LodError::Corrupt(d.to_string());
    let (head, payload) = BlobHead::ref_from_prefix(bytes).map_err(|_| bad("shorter than its head"))?;
    if head.reserved0 != [0; 2] || head.reserved1 != [0; 2] {
        return Err(bad("reserved bytes are not zero"));
    }
    let dims = head.dims.map(|d| u32::from(d.get()));
    if dims.contains(&0) {
        return Err(bad("a grid without cells"));
    }
    let cells: u64 = dims.iter().map(|&d| u64::from(d)).product();
    if cells > MAX_CELLS {
        return Err(bad("more cells than a grid may have"));
    }
    let a = |ax: usize, n: i64| lattice.plane(head.level, ax, n);
    let first = head.first.map(|f| i64::from(f.get()));
    let lo: [f64; 3] = std::array::from_fn(|ax| a(ax, first[ax]));
    let hi: [f64; 3] = std::array::from_fn(|ax| a(ax, first[ax] + i64::from(dims[ax])));
    let grid = Grid::new(lattice, head.level, &Aabb::from_array([lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]]))?;
    if grid.dims() != dims {
        return Err(bad("the head's size is not its grid's"));
    }
    let mut v = Voxels::empty(grid);
    match head.form {
        FORM_BITMAP => {
            let n = (cells as usize).div_ceil(8);
            if payload.len() != n {
                return Err(bad("a bitmap of the wrong size"));
            }
            for (i, &byte) in payload.iter().enumerate() {
                let mut b = byte;
                while b != 0 {
                    let j = i * 8 + b.trailing_zeros() as usize;
                    if j as u64 >= cells {
                        return Err(bad("a bit past the last cell"));
                    }
                    v.set(j);
                    b &= b - 1;
                }
            }
        }
        FORM_BOXES8 | FORM_BOXES16 => {
            let (count, rest) = U32::ref_from_prefix(payload).map_err(|_| bad("no box count"))?;
            let size = if head.form == FORM_BOXES8 { 6 } else { 12 };
            let count = count.get() as usize;
            if count.checked_mul(size) != Some(rest.len()) {
                return Err(bad("box count and bytes disagree"));
            }
            // Boxes must be disjoint: each cell is set at most once, so the
            // work is bounded by the grid's cells, not by what the blob claims.
            for raw in rest.chunks_exact(size) {
                let c: [u16; 6] = std::array::from_fn(|i| {
                    if size == 6 { u16::from(raw[i]) } else { u16::from_le_bytes([raw[2 * i], raw[2 * i + 1]]) }
                });
                if !v.fill_box(c) {
                    return Err(bad("a box outside the grid or over another"));
                }
            }
        }
        f => return Err(LodError::Corrupt(format!("unknown form {f}"))),
    }
    Ok(v)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::Point;

    #[test]
    fn blobs_round_trip_in_both_forms() {
        let lattice = Lattice { origin: Point::new(-3.0, 0.0, 7.0), cell: 0.5 };
        let b = Aabb::from_array([1.1, 2.2, 8.0, 9.9, 4.0, 20.3]);
        let (grid, first) = aligned_grid(&lattice, 1, &b).unwrap();
        assert!(grid.bounds().contains(&b));
        let mut sparse = Voxels::empty(grid.clone());
        sparse.set_cell([0, 0, 0]);
        sparse.set_cell([2, 1, 3]);
        let mut dense = Voxels::empty(grid.clone());
        for i in 0..grid.cells() as usize {
            if i % 3 != 0 {
                dense.set(i);
            }
        }
        for v in [sparse, dense] {
            let bytes = encode(&v, first);
            assert_eq!(decode(&bytes, &lattice).unwrap(), v);
            assert!(decode(&bytes[..bytes.len() - 1], &lattice).is_err());
        }
    }

    #[test]
    fn a_hostile_head_is_an_error() {
        let lattice = Lattice { origin: Point::origin(), cell: 1.0 };
        let mut bytes = vec![0u8; 40];
        bytes[0] = 0;
        bytes[1] = FORM_BOXES16;
        bytes[16..22].copy_from_slice(&[0xff, 0xff, 0xff, 0xff, 0xff, 0xff]);
        assert!(decode(&bytes, &lattice).is_err(), "too many cells");
    }
}
