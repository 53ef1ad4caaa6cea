//! Methods `sah` and `vsah` (not in the paper): the binned surface-area
//! heuristic, the standard BVH builder, and the same with the boxes'
//! volume in place of their area. The centroids of a node's objects are
//! put into 32 bins along each axis; of the 31 planes between bins on each
//! axis, the one of least cost
//! `C_trav + (M(left) n_left + M(right) n_right) / M(node)` wins (C_trav =
//! 1, first axis and plane on ties), M the measure. When all centroids
//! coincide there is nothing to bin, and the node gets a median cut.
//!
//! `sah` measures surface area: a flat node box has area from its other
//! two sides; a box flat on two axes (a line) has none, and its length is
//! the measure instead. `vsah` measures volume, taken over the axes on
//! which the node's box has extent (a flat node measures its children's
//! area in its plane, a line their length): a box query of small extent
//! meets a box with a probability about proportional to its volume, which
//! is what a disk-resident tree pays for, where a ray meets it in
//! proportion to its area.

use super::Split;
use super::driver::{Ctx, Splitter};
use super::median::Median;
use crate::geom::{Aabb, Axis};

/// Bins per axis.
const BINS: usize = 32;
/// Cost of visiting a node, relative to testing one object.
const TRAVERSAL_COST: f64 = 1.0;

/// What the heuristic measures of a box.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Heuristic {
    /// Surface area: `sah`.
    Area,
    /// Volume: `vsah`.
    Volume,
}

/// The measure of a node's boxes, fixed by the node's own box.
#[derive(Debug, Clone, Copy)]
enum Measure {
    Area,
    /// SAH on a node with no area.
    Length,
    /// The product of the extents on the axes marked true.
    Volume([bool; 3]),
}

impl Measure {
    fn of_node(heuristic: Heuristic, node: &Aabb) -> Measure {
        match heuristic {
            Heuristic::Area if node.surface_area() == 0.0 => Measure::Length,
            Heuristic::Area => Measure::Area,
            Heuristic::Volume => {
                let e = node.extent();
                Measure::Volume([e.x > 0.0, e.y > 0.0, e.z > 0.0])
            }
        }
    }

    fn of(self, b: &Aabb) -> f64 {
        match self {
            Measure::Area => b.surface_area(),
            Measure::Length => b.extent().sum(),
            Measure::Volume(axes) => {
                let e = b.extent();
                (0..3).filter(|&i| axes[i]).map(|i| e[i]).product()
            }
        }
    }
}

/// The SAH splitter, of either heuristic.
pub(crate) struct Sah<'a> {
    ctx: &'a Ctx<'a>,
    heuristic: Heuristic,
    median: Median<'a>,
}

impl<'a> Sah<'a> {
    pub(crate) fn new(ctx: &'a Ctx<'a>, heuristic: Heuristic) -> Sah<'a> {
        Sah { ctx, heuristic, median: Median::new(ctx) }
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
    fn best_plane(&self, boxes: &[Aabb], set: &[u32], parent: f64, measure: Measure) -> Option<(f64, usize)> {
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
            right[plane] = (acc.0 > 0).then(|| acc.0 as f64 * measure.of(&acc.1));
        }
        let mut acc = (0usize, Aabb::EMPTY);
        let mut best: Option<(f64, usize)> = None;
        for (plane, right) in right.iter().enumerate() {
            acc = (acc.0 + bins[plane].0, acc.1.union(&bins[plane].1));
            let Some(right) = right.filter(|_| acc.0 > 0) else { continue };
            let cost = TRAVERSAL_COST + (acc.0 as f64 * measure.of(&acc.1) + right) / parent;
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

impl Splitter for Sah<'_> {
    type Set = Vec<u32>;

    fn objects<'s>(&self, set: &'s Vec<u32>) -> &'s [u32] {
        set
    }

    fn split(&self, set: Vec<u32>, aabb: &Aabb) -> (Vec<u32>, Vec<u32>, Split) {
        let boxes = self.ctx.boxes;
        let measure = Measure::of_node(self.heuristic, aabb);
        // Not zero: some centroids differ whenever a plane is tried below.
        let parent = measure.of(aabb);
        let mut best: Option<(f64, Binning, usize)> = None;
        for axis in Axis::ALL.map(Axis::index) {
            let Some(binning) = Binning::new(boxes, &set, axis) else { continue };
            if let Some((cost, plane)) = binning.best_plane(boxes, &set, parent, measure)
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
