//! Reference method `hilbert` (not in the paper): a binary packed Hilbert
//! tree. All objects are sorted once by the 3D Hilbert code of their box
//! centres, quantised to 21 bits per axis over the scene's box (ties by
//! id); each node is then the halves of its run (the left half gets
//! ⌈N/2⌉). The same order numbers the objects of every build (see
//! `driver.rs`), so for this method the run is simply 0..N.
//!
//! The split record has `order` = `Center` and, since the curve has no cut
//! axis, the axis along which the two halves' boxes overlap least.

use rayon::prelude::*;

use super::Split;
use super::median::left_half;
use super::splitter::{Ctx, Splitter};
use crate::geom::Aabb;

/// Bits per axis of the Hilbert code: 3 × 21 = 63 bits.
const BITS: u32 = 21;

/// Indices 0..N of `boxes` sorted by the Hilbert code of their centres
/// (ties by index): the order the `hilbert` method builds on, and a
/// clustering order for loading the same objects elsewhere (the SQLite peer
/// inserts its rows in it).
pub fn curve_order(boxes: &[Aabb]) -> Vec<u32> {
    let scene = boxes.iter().fold(Aabb::EMPTY, |s, b| s.union(b));
    let extent = scene.extent();
    let cells = f64::from((1u32 << BITS) - 1);
    let codes: Vec<u64> = boxes
        .par_iter()
        .map(|b| {
            let c = b.center();
            hilbert_index(std::array::from_fn(|i| {
                // `as` saturates: a centre on the scene's upper face maps to the last cell.
                if extent[i] > 0.0 { ((c[i] - scene.min[i]) / extent[i] * cells) as u32 } else { 0 }
            }))
        })
        .collect();
    let mut order: Vec<u32> = (0..boxes.len() as u32).collect();
    order.par_sort_unstable_by_key(|&j| (codes[j as usize], j));
    order
}

/// The index along the Hilbert curve of the cell `x` (each coordinate
/// below 2^BITS): Skilling's transpose ("Programming the Hilbert curve",
/// AIP Conf. Proc. 707, 2004), its bits interleaved.
fn hilbert_index(mut x: [u32; 3]) -> u64 {
    let top = 1u32 << (BITS - 1);
    // Inverse undo of the excess work.
    let mut q = top;
    while q > 1 {
        let p = q - 1;
        for i in 0..3 {
            if x[i] & q != 0 {
                x[0] ^= p;
            } else {
                let t = (x[0] ^ x[i]) & p;
                x[0] ^= t;
                x[i] ^= t;
            }
        }
        q >>= 1;
    }
    // Gray encode.
    x[1] ^= x[0];
    x[2] ^= x[1];
    let mut t = 0;
    q = top;
    while q > 1 {
        if x[2] & q != 0 {
            t ^= q - 1;
        }
        q >>= 1;
    }
    for v in &mut x {
        *v ^= t;
    }
    (0..BITS).rev().fold(0u64, |h, bit| x.iter().fold(h, |h, v| (h << 1) | u64::from((v >> bit) & 1)))
}

/// The Hilbert splitter: halves of a run already in curve order.
pub(crate) struct Hilbert<'a> {
    ctx: &'a Ctx<'a>,
}

impl<'a> Hilbert<'a> {
    pub(crate) fn new(ctx: &'a Ctx<'a>) -> Hilbert<'a> {
        Hilbert { ctx }
    }
}

impl Splitter for Hilbert<'_> {
    type Set = Vec<u32>;

    fn objects<'s>(&self, set: &'s Vec<u32>) -> &'s [u32] {
        set
    }

    fn split(&self, mut set: Vec<u32>, _aabb: &Aabb) -> (Vec<u32>, Vec<u32>, Split) {
        let right = set.split_off(left_half(set.len()));
        let split = self.ctx.split_between(&set, &right, None);
        (set, right, split)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The cells of a 2^bits grid in curve order: with BITS = 21 bits, the
    /// cells whose coordinates are multiples of 2^(21 - bits) form the
    /// same curve at a coarser scale.
    fn curve(bits: u32) -> Vec<[u32; 3]> {
        let side = 1u32 << bits;
        let shift = BITS - bits;
        let mut cells: Vec<[u32; 3]> =
            (0..side.pow(3)).map(|c| [c % side, (c / side) % side, c / (side * side)]).collect();
        cells.sort_by_key(|&c| hilbert_index(c.map(|v| v << shift)));
        cells
    }

    #[test]
    fn consecutive_cells_on_the_curve_are_neighbours() {
        for bits in 1..=3 {
            let cells = curve(bits);
            for w in cells.windows(2) {
                let d: u32 = (0..3).map(|i| w[0][i].abs_diff(w[1][i])).sum();
                assert_eq!(d, 1, "{:?} -> {:?} at {bits} bits", w[0], w[1]);
            }
        }
    }

    #[test]
    fn codes_are_distinct_and_start_at_the_origin() {
        let mut codes: Vec<u64> = (0..512u32)
            .map(|c| hilbert_index([c % 8, (c / 8) % 8, c / 64].map(|v| v << (BITS - 3))))
            .collect();
        assert_eq!(hilbert_index([0, 0, 0]), 0);
        codes.sort_unstable();
        codes.dedup();
        assert_eq!(codes.len(), 512);
    }

    #[test]
    fn boxes_of_one_octant_are_consecutive() {
        // The curve fills each octant of the scene before the next one.
        let b = |x: f64| Aabb::from_array([x, x, x, x + 1.0, x + 1.0, x + 1.0]);
        let order = curve_order(&[b(0.0), b(90.0), b(2.0), b(95.0), b(4.0), b(99.0)]);
        let near: Vec<bool> = order.iter().map(|&i| i % 2 == 0).collect();
        assert!(
            near == [true, true, true, false, false, false]
                || near == [false, false, false, true, true, true]
        );
        assert!(curve_order(&[]).is_empty());
    }
}
