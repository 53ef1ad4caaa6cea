//! Reference method `sah` (not in the paper): the binned surface-area
//! heuristic, the standard BVH builder. The centroids of a node's objects
//! are put into 32 bins along each axis; of the 31 planes between bins on
//! each axis, the one of least cost
//! `C_trav + (A(left) n_left + A(right) n_right) / A(node)` wins (C_trav =
//! 1, first axis and plane on ties). When all centroids coincide there is
//! nothing to bin, and the node gets a median cut.
//!
//! A flat node box has area from its other two sides; a box flat on two
//! axes (a line) has none, and its length is the measure instead.

use super::Split;
use super::driver::{Ctx, Splitter};
use super::median::Median;
use crate::geom::{Aabb, Axis};

/// Bins per axis.
const BINS: usize = 32;
/// Cost of visiting a node, relative to testing one object.
const TRAVERSAL_COST: f64 = 1.0;

/// The SAH splitter.
pub(crate) struct Sah<'a> {
    ctx: &'a Ctx<'a>,
    median: Median<'a>,
}

impl<'a> Sah<'a> {
    pub(crate) fn new(ctx: &'a Ctx<'a>) -> Sah<'a> {
        Sah { ctx, median: Median::new(ctx) }
    }
}

/// How a node's centroids fall into bins along one axis.
struct Binning {
    axis: usize,
    low: f64,
    scale: f64,
}

impl Binning {
    /// The binning of `set`'s centroids along `axis`; none when they all
    /// have the same coordinate there.
    fn new(boxes: &[Aabb], set: &[u32], axis: usize) -> Option<Binning> {
        let (low, high) = set.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &j| {
            let c = centroid(&boxes[j as usize], axis);
            (l.min(c), h.max(c))
        });
        let extent = high - low;
        (extent > 0.0).then(|| Binning { axis, low, scale: BINS as f64 / extent })
    }

    /// The bin of box `b`'s centroid (the last bin takes the upper end).
    fn bin(&self, b: &Aabb) -> usize {
        // `as` saturates, and the ratio is in [0, BINS].
        (((centroid(b, self.axis) - self.low) * self.scale) as usize).min(BINS - 1)
    }

    /// The least cost of a plane, with the plane (planes with an empty side skipped).
    fn best_plane(&self, boxes: &[Aabb], set: &[u32], parent: f64, lines: bool) -> Option<(f64, usize)> {
        let mut bins = [(0usize, Aabb::EMPTY); BINS];
        for &j in set {
            let b = &boxes[j as usize];
            let slot = &mut bins[self.bin(b)];
            *slot = (slot.0 + 1, slot.1.union(b));
        }
        // n A of the right side of each plane, swept from the right.
        let mut right = [None; BINS - 1];
        let mut acc = (0usize, Aabb::EMPTY);
        for plane in (0..BINS - 1).rev() {
            acc = (acc.0 + bins[plane + 1].0, acc.1.union(&bins[plane + 1].1));
            right[plane] = (acc.0 > 0).then(|| acc.0 as f64 * measure(&acc.1, lines));
        }
        let mut acc = (0usize, Aabb::EMPTY);
        let mut best: Option<(f64, usize)> = None;
        for (plane, right) in right.iter().enumerate() {
            acc = (acc.0 + bins[plane].0, acc.1.union(&bins[plane].1));
            let Some(right) = right.filter(|_| acc.0 > 0) else { continue };
            let cost = TRAVERSAL_COST + (acc.0 as f64 * measure(&acc.1, lines) + right) / parent;
            if best.is_none_or(|b| cost < b.0) {
                best = Some((cost, plane));
            }
        }
        best
    }
}

/// The centre of `b` on `axis`.
fn centroid(b: &Aabb, axis: usize) -> f64 {
    0.5 * (b.min[axis] + b.max[axis])
}

/// A box's surface area, or its length when `lines` (see the module doc).
fn measure(b: &Aabb, lines: bool) -> f64 {
    if lines { b.extent().sum() } else { b.surface_area() }
}

impl Splitter for Sah<'_> {
    type Set = Vec<u32>;

    fn objects<'s>(&self, set: &'s Vec<u32>) -> &'s [u32] {
        set
    }

    fn split(&self, set: Vec<u32>, aabb: &Aabb) -> (Vec<u32>, Vec<u32>, Split) {
        let boxes = self.ctx.boxes;
        let lines = aabb.surface_area() == 0.0;
        // Not zero: some centroids differ whenever a plane is tried below.
        let parent = measure(aabb, lines);
        let mut best: Option<(f64, Binning, usize)> = None;
        for axis in Axis::ALL.map(Axis::index) {
            let Some(binning) = Binning::new(boxes, &set, axis) else { continue };
            if let Some((cost, plane)) = binning.best_plane(boxes, &set, parent, lines)
                && best.as_ref().is_none_or(|b| cost < b.0)
            {
                best = Some((cost, binning, plane));
            }
        }
        let Some((_, binning, plane)) = best else {
            return self.median.split(set, aabb);
        };
        let (left, right): (Vec<u32>, Vec<u32>) =
            set.iter().partition(|&&j| binning.bin(&boxes[j as usize]) <= plane);
        let split = self.ctx.split_between(&left, &right, Axis::from_index(binning.axis));
        (left, right, split)
    }
}
