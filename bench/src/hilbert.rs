//! The order in which the SQLite peer inserts objects: by the 3D Hilbert
//! index of their box centres, so objects near in space get near rowids
//! and share table pages (the clustering an embedder would give SQLite).
//!
//! The index is Skilling's transform ("Programming the Hilbert curve", AIP
//! Conf. Proc. 707, 2004): the cell's coordinates become the transposed
//! index, whose bits, interleaved, are the position along the curve.

use mktree::geom::Aabb;

/// Bits per axis: 3 x 21 = 63 bits of index.
const BITS: u32 = 21;

/// Indices 0..N of `boxes` sorted by the Hilbert index of their centres,
/// quantised to 2^21 cells per axis of the boxes' union; ties by index.
pub(crate) fn hilbert_order(boxes: &[Aabb]) -> Vec<u32> {
    let all = boxes.iter().fold(Aabb::EMPTY, |s, b| s.union(b));
    let extent = all.extent();
    let last = f64::from((1u32 << BITS) - 1);
    let mut keyed: Vec<(u64, u32)> = boxes
        .iter()
        .zip(0u32..)
        .map(|(b, i)| {
            let c = b.center();
            let cell = std::array::from_fn(|a| {
                // `as` saturates, so a centre on the upper face is the last cell.
                if extent[a] > 0.0 { ((c[a] - all.min[a]) / extent[a] * last) as u32 } else { 0 }
            });
            (hilbert_index(cell, BITS), i)
        })
        .collect();
    keyed.sort_unstable();
    keyed.into_iter().map(|(_, i)| i).collect()
}

/// The position along the Hilbert curve of `cell` (each coordinate below
/// 2^bits, bits <= 21).
fn hilbert_index(mut x: [u32; 3], bits: u32) -> u64 {
    // Undo the excess rotations and reflections, from the top bit down.
    let mut q = 1u32 << (bits - 1);
    while q > 1 {
        let low = q - 1;
        for i in 0..3 {
            if x[i] & q != 0 {
                x[0] ^= low;
            } else {
                let swap = (x[0] ^ x[i]) & low;
                x[0] ^= swap;
                x[i] ^= swap;
            }
        }
        q >>= 1;
    }
    // Gray-encode the transposed index.
    x[1] ^= x[0];
    x[2] ^= x[1];
    let mut flip = 0;
    let mut q = 1u32 << (bits - 1);
    while q > 1 {
        if x[2] & q != 0 {
            flip ^= q - 1;
        }
        q >>= 1;
    }
    x = x.map(|v| v ^ flip);
    // Interleave: bit b of x[0], x[1], x[2], from the top bit down.
    (0..bits).rev().fold(0, |h, b| x.iter().fold(h, |h, v| (h << 1) | u64::from((v >> b) & 1)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_curve_visits_every_cell_once_stepping_to_a_face_neighbour() {
        let bits = 3;
        let side = 1u32 << bits;
        let mut at = vec![None; (side * side * side) as usize];
        for x in 0..side {
            for y in 0..side {
                for z in 0..side {
                    let h = hilbert_index([x, y, z], bits) as usize;
                    assert!(at[h].is_none(), "index {h} given twice");
                    at[h] = Some([x, y, z]);
                }
            }
        }
        let cells: Vec<[u32; 3]> = at.into_iter().map(|c| c.expect("every index is a cell")).collect();
        for w in cells.windows(2) {
            let step: u32 = (0..3).map(|i| w[0][i].abs_diff(w[1][i])).sum();
            assert_eq!(step, 1, "{:?} -> {:?}", w[0], w[1]);
        }
    }

    #[test]
    fn boxes_of_one_octant_are_consecutive() {
        // The curve fills each octant of the scene before the next one.
        let b = |x: f64| Aabb::from_array([x, x, x, x + 1.0, x + 1.0, x + 1.0]);
        let order = hilbert_order(&[b(0.0), b(90.0), b(2.0), b(95.0), b(4.0), b(99.0)]);
        let near: Vec<bool> = order.iter().map(|&i| i % 2 == 0).collect();
        assert!(
            near == [true, true, true, false, false, false]
                || near == [false, false, false, true, true, true]
        );
        assert!(hilbert_order(&[]).is_empty());
    }
}
