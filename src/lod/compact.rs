//! Voxel bounds as stored inline in node records (format-spec/lod.md,
//! "Inline voxel blobs"). The grid is not stored: it is the grid of whole
//! lattice cells over the box the record already holds for the bounded
//! object (or child), at the lattice level the blob's first byte names. So a
//! bound is two bytes and its cells, as a bitmap or as boxes, whichever is
//! smaller.

use zerocopy::{FromBytes, IntoBytes};

use super::{Grid, Lattice, LodError, Voxels};
use crate::geom::Aabb;
use crate::store::format::blob::{BlobHead, FORM_BITMAP, FORM_BOXES8, FORM_BOXES16, HEAD_LEN};

/// The grid of whole cells of lattice level `level` that covers `b`: from
/// the last plane at or below `b.min` to the first at or above `b.max`
/// (at least one cell per axis).
pub fn aligned_grid(lattice: &Lattice, level: u8, b: &Aabb) -> Result<Grid, LodError> {
    if !lattice.is_valid() || b.is_empty() || !b.to_array().iter().all(|c| c.is_finite()) {
        return Err(LodError::BadBounds(b.to_array()));
    }
    let s = lattice.cell_at(level);
    let mut lo = [0f64; 3];
    let mut hi = [0f64; 3];
    for a in 0..3 {
        let guess = ((b.min[a] - lattice.origin[a]) / s).floor();
        let span = (b.max[a] - b.min[a]) / s;
        // Plane indices stay exact below 2^50; a grid is at most 65,535 cells wide.
        if !guess.is_finite()
            || guess.abs() >= (1u64 << 50) as f64
            || span.is_nan()
            || span > f64::from(u16::MAX)
        {
            return Err(LodError::TooLarge { level, dims: [0; 3], cells: u64::MAX });
        }
        // The guess is off by a plane or two at most; where planes do not
        // advance with n (a cell below the coordinates' resolution) the walks
        // are cut short instead of running forever.
        let stalled = || LodError::BadLattice { origin: lattice.origin.into(), cell: lattice.cell };
        let mut n = guess as i64;
        let mut steps = 0;
        while lattice.plane(level, a, n) > b.min[a] {
            n -= 1;
            steps += 1;
            if steps > 4 {
                return Err(stalled());
            }
        }
        while lattice.plane(level, a, n + 1) <= b.min[a] {
            n += 1;
            steps += 1;
            if steps > 8 {
                return Err(stalled());
            }
        }
        let mut m = n + 1;
        while lattice.plane(level, a, m) < b.max[a] {
            m += 1;
            if m - n > i64::from(u16::MAX) + 2 {
                return Err(stalled());
            }
        }
        lo[a] = lattice.plane(level, a, n);
        hi[a] = lattice.plane(level, a, m);
    }
    Grid::new(lattice, level, &Aabb::from_array([lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]]))
}

/// The form `v` encodes to, its payload bytes and, in a box form, the
/// boxes: a bitmap or boxes, the smaller (a tie to the bitmap). The box
/// cover stops once it would be no smaller than the bitmap.
fn form_of(v: &Voxels) -> (u8, usize, Vec<[u16; 6]>) {
    let small = v.grid().dims().iter().all(|&d| d <= 255);
    let per_box = if small { 6 } else { 12 };
    let bitmap_bytes = (v.grid().cells() as usize).div_ceil(8);
    // Boxes win only with fewer than bitmap_bytes / per_box of them.
    match v.boxes_within(bitmap_bytes.div_ceil(per_box).saturating_sub(1)) {
        Some(boxes) => (if small { FORM_BOXES8 } else { FORM_BOXES16 }, boxes.len() * per_box, boxes),
        None => (FORM_BITMAP, bitmap_bytes, Vec::new()),
    }
}

/// Bytes `v` encodes to.
pub fn encoded_len(v: &Voxels) -> usize {
    HEAD_LEN + form_of(v).1
}

/// Encodes `v`, a set on the [`aligned_grid`] over the box its reader holds.
pub fn encode(v: &Voxels) -> Vec<u8> {
    let (form, payload, boxes) = form_of(v);
    let mut out = Vec::with_capacity(HEAD_LEN + payload);
    out.extend_from_slice(BlobHead { level: v.grid().level(), form }.as_bytes());
    match form {
        FORM_BITMAP => {
            let mut bits = vec![0u8; payload];
            for i in v.set_cells() {
                bits[i / 8] |= 1 << (i % 8);
            }
            out.extend_from_slice(&bits);
        }
        _ => {
            for b in &boxes {
                for &c in b {
                    // Corners lie in 0 ..= dims: u8 when every axis has at most 255 cells.
                    if form == FORM_BOXES8 {
                        out.push(c as u8)
                    } else {
                        out.extend_from_slice(&c.to_le_bytes())
                    }
                }
            }
        }
    }
    out
}

/// Decodes a blob bounding what `outer` bounds, on `lattice`, checking every
/// rule; the work is bounded by the grid's cells (at most `MAX_CELLS`).
pub fn decode(bytes: &[u8], lattice: &Lattice, outer: &Aabb) -> Result<Voxels, LodError> {
    let bad = |d: &str| LodError::Corrupt(d.to_string());
    let (head, payload) = BlobHead::ref_from_prefix(bytes).map_err(|_| bad("shorter than its head"))?;
    let grid = aligned_grid(lattice, head.level, outer)?;
    let dims = grid.dims();
    let cells = grid.cells();
    let mut v = Voxels::empty(grid);
    match head.form {
        FORM_BITMAP => {
            if payload.len() as u64 != cells.div_ceil(8) {
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
            let size = if head.form == FORM_BOXES8 { 6 } else { 12 };
            if payload.len() % size != 0 || (size == 6 && dims.iter().any(|&d| d > 255)) {
                return Err(bad("boxes of the wrong size"));
            }
            // Boxes must be disjoint: each cell is set at most once, so the
            // work is bounded by the grid's cells, not by what the blob claims.
            for raw in payload.chunks_exact(size) {
                let c: [u16; 6] = std::array::from_fn(|i| {
                    if size == 6 {
                        u16::from(raw[i])
                    } else {
                        u16::from_le_bytes([raw[2 * i], raw[2 * i + 1]])
                    }
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
    use crate::store::format::blob::sets_no_cell;

    #[test]
    fn blobs_round_trip_in_both_forms() {
        let lattice = Lattice { origin: Point::new(-3.0, 0.0, 7.0), cell: 0.5 };
        let b = Aabb::from_array([1.1, 2.2, 8.0, 9.9, 4.0, 20.3]);
        let grid = aligned_grid(&lattice, 1, &b).unwrap();
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
            let bytes = encode(&v);
            assert_eq!(bytes.len(), encoded_len(&v));
            assert_eq!(decode(&bytes, &lattice, &b).unwrap(), v);
            assert!(decode(&bytes[..bytes.len() - 1], &lattice, &b).is_err());
        }
    }

    #[test]
    fn an_empty_set_is_seen_in_every_form_without_its_grid() {
        let lattice = Lattice { origin: Point::origin(), cell: 1.0 };
        let b = Aabb::from_array([0.0, 0.0, 0.0, 4.0, 4.0, 4.0]);
        let grid = aligned_grid(&lattice, 0, &b).unwrap();
        let mut one = Voxels::empty(grid.clone());
        one.set_cell([3, 0, 2]);
        assert!(sets_no_cell(&encode(&Voxels::empty(grid))));
        assert!(!sets_no_cell(&encode(&one)));
        let bitmap = [&[0, FORM_BITMAP][..], &[0; 8]].concat();
        for (blob, empty) in
            [(bitmap, true), (vec![0, FORM_BOXES16], true), (vec![0, 9], false), (vec![0], false)]
        {
            assert_eq!(sets_no_cell(&blob), empty, "{blob:?}");
        }
    }

    #[test]
    fn a_grid_too_fine_for_its_box_is_an_error() {
        let lattice = Lattice { origin: Point::origin(), cell: 1e-3 };
        let huge = Aabb::from_array([0.0, 0.0, 0.0, 1e6, 1e6, 1e6]);
        assert!(decode(&[0, FORM_BITMAP], &lattice, &huge).is_err());
    }

    proptest::proptest! {
        /// The cover cut short picks what the whole cover would: a bitmap
        /// unless the boxes take fewer bytes, and then those very boxes.
        #[test]
        fn a_blob_is_the_smaller_form_of_the_whole_cover(
            size in proptest::array::uniform3(1u8..12),
            seeds in proptest::collection::vec(proptest::num::u64::ANY, 0..60),
            blocks in proptest::collection::vec(proptest::array::uniform3(0u8..12), 0..4),
        ) {
            let lattice = Lattice { origin: Point::origin(), cell: 1.0 };
            let b = Aabb::from_array([0.0, 0.0, 0.0, f64::from(size[0]), f64::from(size[1]), f64::from(size[2])]);
            let grid = aligned_grid(&lattice, 0, &b).unwrap();
            let corners: Vec<[u32; 3]> = blocks.iter().map(|c| c.map(u32::from)).collect();
            // Solid parts, where a few boxes beat the bitmap.
            let v = Voxels::scattered_and_solid(grid.clone(), &seeds, &corners);
            let cells = grid.cells();
            let boxes = v.boxes();
            let bitmap = (cells as usize).div_ceil(8);
            let want = if bitmap <= boxes.len() * 6 { (FORM_BITMAP, bitmap) } else { (FORM_BOXES8, boxes.len() * 6) };
            let (form, payload, got) = form_of(&v);
            proptest::prop_assert_eq!((form, payload), want);
            if form == FORM_BOXES8 {
                proptest::prop_assert_eq!(got, boxes);
            }
            proptest::prop_assert_eq!(decode(&encode(&v), &lattice, &b).unwrap(), v);
        }
    }
}
