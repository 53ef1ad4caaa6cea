//! Boxes stored as 16-bit fractions of an enclosing box (format-spec/node.md,
//! "Quantized boxes"): a child's box in its parent's, an object's in its
//! leaf's. Half the bytes of f32 corners, and exact in both directions: the
//! stored box contains the true one, and each true face lies in a known
//! one-step slab, so a box can witness contact as well as rule it out.

use crate::geom::{Aabb, Point};

/// Steps across the enclosing box on each axis.
pub const STEPS: u16 = u16::MAX;

/// Coordinate `q` (0 ..= STEPS) of axis `[lo, hi]`. Monotone in `q`, with
/// `0` exactly `lo` and `STEPS` exactly `hi`, computed the same way by the
/// writer and every reader, so the brackets below hold bit for bit.
pub fn dequantize(lo: f64, hi: f64, q: u16) -> f64 {
    match q {
        0 => lo,
        STEPS => hi,
        _ => lo + (hi - lo) * (f64::from(q) / f64::from(STEPS)),
    }
}

/// The largest q with `dequantize(q) <= v` (0 when v is below the axis).
fn floor_q(lo: f64, hi: f64, v: f64) -> u16 {
    // A flat axis: every step is `lo` (the search below would walk them all).
    if hi == lo {
        return if v >= lo { STEPS } else { 0 };
    }
    let guess = if hi > lo { ((v - lo) / (hi - lo) * f64::from(STEPS)).floor() } else { 0.0 };
    let mut q = guess.clamp(0.0, f64::from(STEPS)) as u16;
    while q > 0 && dequantize(lo, hi, q) > v {
        q -= 1;
    }
    while q < STEPS && dequantize(lo, hi, q + 1) <= v {
        q += 1;
    }
    q
}

/// The smallest q with `dequantize(q) >= v` (STEPS when v is above the axis).
fn ceil_q(lo: f64, hi: f64, v: f64) -> u16 {
    let q = floor_q(lo, hi, v);
    if dequantize(lo, hi, q) >= v { q } else { q.saturating_add(1) }
}

/// `b` rounded outward to steps of `frame`: `[x0, y0, z0, x1, y1, z1]`.
/// `b` must lie in `frame` (the writer checks containment after the fact).
pub fn quantize(frame: &Aabb, b: &Aabb) -> [u16; 6] {
    let mut q = [0u16; 6];
    for a in 0..3 {
        let (lo, hi) = (frame.min[a], frame.max[a]);
        q[a + 3] = ceil_q(lo, hi, b.max[a]);
        // Where steps tie (a flat frame), the largest step at or below the
        // lower face may pass the upper one: the upper one holds the face too.
        q[a] = floor_q(lo, hi, b.min[a]).min(q[a + 3]);
    }
    q
}

/// A box decoded from steps of its frame, with what it proves.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QuantBox {
    /// Contains the true box.
    pub outer: Aabb,
    frame: Aabb,
    q: [u16; 6],
}

impl QuantBox {
    /// Decodes `q` in `frame`; `None` when a lower step exceeds the upper one.
    pub fn decode(frame: &Aabb, q: [u16; 6]) -> Option<QuantBox> {
        if (0..3).any(|a| q[a] > q[a + 3]) {
            return None;
        }
        let d = |a: usize, s: u16| dequantize(frame.min[a], frame.max[a], s);
        let outer = Aabb::new(
            Point::new(d(0, q[0]), d(1, q[1]), d(2, q[2])),
            Point::new(d(0, q[3]), d(1, q[4]), d(2, q[5])),
        );
        Some(QuantBox { outer, frame: *frame, q })
    }

    /// The slab `[lo, hi]` on `axis` that holds the true lower face's coordinate.
    pub fn lower_face(&self, axis: usize) -> (f64, f64) {
        let q = self.q;
        (self.outer.min[axis], self.step(axis, q[axis].saturating_add(1).min(q[axis + 3])))
    }

    /// The slab `[lo, hi]` on `axis` that holds the true upper face's coordinate.
    pub fn upper_face(&self, axis: usize) -> (f64, f64) {
        let q = self.q;
        (self.step(axis, q[axis + 3].saturating_sub(1).max(q[axis])), self.outer.max[axis])
    }

    fn step(&self, axis: usize, s: u16) -> f64 {
        dequantize(self.frame.min[axis], self.frame.max[axis], s)
    }

    /// The six regions that each hold a whole face of the true box: the
    /// outer box squeezed, on one axis, to the slab of that face. A point
    /// set holding one of them holds a point of whatever the box is tight on.
    pub fn face_slabs(&self) -> [Aabb; 6] {
        std::array::from_fn(|i| {
            let (a, (lo, hi)) = if i < 3 { (i, self.lower_face(i)) } else { (i - 3, self.upper_face(i - 3)) };
            let mut s = self.outer;
            s.min[a] = lo;
            s.max[a] = hi;
            s
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn arb_box(lo: f64, hi: f64) -> impl Strategy<Value = Aabb> {
        (lo..hi, lo..hi, lo..hi, lo..hi, lo..hi, lo..hi).prop_map(|(a, b, c, d, e, f)| {
            Aabb::from_array([a.min(d), b.min(e), c.min(f), a.max(d), b.max(e), c.max(f)])
        })
    }

    proptest! {
        /// Outward in one direction, tight in the other: the stored box holds
        /// the true one, and every true face lies in its slab.
        #[test]
        fn a_quantized_box_contains_the_box_and_brackets_its_faces(
            frame in arb_box(-1.0e7, 1.0e7), t in arb_box(0.0, 1.0),
        ) {
            let e = frame.extent();
            let b = Aabb::new(frame.min + e.component_mul(&t.min.coords), frame.min + e.component_mul(&t.max.coords));
            let b = Aabb::new(b.min.sup(&frame.min).inf(&frame.max), b.max.sup(&frame.min).inf(&frame.max));
            let q = QuantBox::decode(&frame, quantize(&frame, &b)).unwrap();
            for a in 0..3 {
                prop_assert!(q.outer.min[a] <= b.min[a] && q.outer.max[a] >= b.max[a]);
                prop_assert!(q.lower_face(a).0 <= b.min[a] && b.min[a] <= q.lower_face(a).1);
                prop_assert!(q.upper_face(a).0 <= b.max[a] && b.max[a] <= q.upper_face(a).1);
            }
            for s in q.face_slabs() {
                prop_assert!(q.outer.contains(&s));
            }
        }

        #[test]
        fn dequantize_is_monotone(lo in -1.0e9f64..1.0e9, w in 0.0f64..1.0e9, q in 0u16..STEPS) {
            prop_assert!(dequantize(lo, lo + w, q) <= dequantize(lo, lo + w, q + 1));
        }
    }

    #[test]
    fn floor_q_on_a_flat_axis_is_the_largest_step_at_or_below() {
        let largest = |lo: f64, v: f64| (0..=STEPS).rev().find(|&q| dequantize(lo, lo, q) <= v).unwrap_or(0);
        for (lo, v) in [(5.0, 5.0), (5.0, 4.0), (5.0, 6.0), (-0.0, 0.0), (0.0, -1e-300)] {
            assert_eq!(floor_q(lo, lo, v), largest(lo, v), "lo {lo}, v {v}");
        }
    }

    #[test]
    fn a_flat_frame_and_the_frame_itself_quantize_exactly() {
        let frame = Aabb::from_array([1.0, 2.0, 3.0, 1.0, 5.0, 9.0]);
        assert_eq!(quantize(&frame, &frame), [STEPS, 0, 0, STEPS, STEPS, STEPS]);
        let q = QuantBox::decode(&frame, quantize(&frame, &frame)).unwrap();
        assert_eq!(q.outer, frame);
        assert!(QuantBox::decode(&frame, [5, 0, 0, 4, 0, 0]).is_none());
    }
}
