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
    /// The binning of centroids from `low` to `high` along `axis`; none
    /// when they all have the same coordinate there.
    fn new(axis: usize, low: f64, high: f64) -> Option<Binning> {
        let extent = high - low;
        (extent > 0.0).then(|| Binning { axis, low, scale: BINS as f64 / extent })
    }

    /// The bin of box `b`'s centroid (the last bin takes the upper end).
    fn bin(&self, b: &Aabb) -> usize {
        // `as` saturates, and the ratio is in [0, BINS].
        (((centroid(b, self.axis) - self.low) * self.scale) as usize).min(BINS - 1)
    }
}

/// Per bin: the objects whose centroid falls in it, and their boxes' union.
type Bins = [(usize, Aabb); BINS];

/// The plane of least cost: the objects of bins `..= plane` go left.
struct Plane {
    binning: Binning,
    plane: usize,
    /// The boxes of the left and right sides.
    boxes: [Aabb; 2],
    /// Objects on the left.
    left: usize,
}

/// The least cost of a plane of `bins` (planes with an empty side
/// skipped), with the plane and its sides' boxes.
fn best_plane(bins: &Bins, parent: f64, measure: Measure) -> Option<(f64, usize, [Aabb; 2], usize)> {
    // n A of the right side of each plane, swept from the right.
    let mut right = [(None, Aabb::EMPTY); BINS - 1];
    let mut acc = (0usize, Aabb::EMPTY);
    for plane in (0..BINS - 1).rev() {
        acc = (acc.0 + bins[plane + 1].0, acc.1.union(&bins[plane + 1].1));
        right[plane] = ((acc.0 > 0).then(|| acc.0 as f64 * measure.of(&acc.1)), acc.1);
    }
    let mut acc = (0usize, Aabb::EMPTY);
    let mut best: Option<(f64, usize, [Aabb; 2], usize)> = None;
    for (plane, (right, right_box)) in right.iter().enumerate() {
        acc = (acc.0 + bins[plane].0, acc.1.union(&bins[plane].1));
        let Some(right) = right.filter(|_| acc.0 > 0) else { continue };
        let cost = TRAVERSAL_COST + (acc.0 as f64 * measure.of(&acc.1) + right) / parent;
        if best.is_none_or(|b| cost < b.0) {
            best = Some((cost, plane, [acc.1, *right_box], acc.0));
        }
    }
    best
}

impl Sah<'_> {
    /// The plane of least cost over all three axes (the first axis and
    /// plane on ties); none when all centroids coincide. Two passes over
    /// the objects: the centroids' range, then every axis's bins.
    fn plane(&self, set: &[u32], aabb: &Aabb) -> Option<Plane> {
        let boxes = self.ctx.boxes;
        let measure = Measure::of_node(self.heuristic, aabb);
        // Not zero: some centroids differ whenever a plane is tried below.
        let parent = measure.of(aabb);
        let (mut low, mut high) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for &j in set {
            let b = &boxes[j as usize];
            for axis in 0..3 {
                let c = centroid(b, axis);
                (low[axis], high[axis]) = (low[axis].min(c), high[axis].max(c));
            }
        }
        let binnings: [Option<Binning>; 3] = std::array::from_fn(|a| Binning::new(a, low[a], high[a]));
        let mut bins = [[(0usize, Aabb::EMPTY); BINS]; 3];
        for &j in set {
            let b = &boxes[j as usize];
            for (binning, bins) in binnings.iter().zip(&mut bins) {
                if let Some(binning) = binning {
                    let slot = &mut bins[binning.bin(b)];
                    *slot = (slot.0 + 1, slot.1.union(b));
                }
            }
        }
        let mut best: Option<(f64, Plane)> = None;
        for (binning, bins) in binnings.into_iter().zip(&bins) {
            let Some(binning) = binning else { continue };
            if let Some((cost, plane, sides, left)) = best_plane(bins, parent, measure)
                && best.as_ref().is_none_or(|b| cost < b.0)
            {
                best = Some((cost, Plane { binning, plane, boxes: sides, left }));
            }
        }
        best.map(|b| b.1)
    }

    /// `set` divided by the heuristic, with both sides' boxes and, for a
    /// plane, its axis (a node whose centroids coincide gets a median cut).
    pub(crate) fn halves(&self, set: Vec<u32>, aabb: &Aabb) -> Halves {
        let Some(p) = self.plane(&set, aabb) else {
            let (left, right, split) = self.median.split(set, aabb);
            let boxes = [self.ctx.aabb_of(&left), self.ctx.aabb_of(&right)];
            return Halves { left, right, boxes, plane: None, median: Some(split) };
        };
        let boxes = self.ctx.boxes;
        let (mut left, mut right) = (Vec::with_capacity(p.left), Vec::with_capacity(set.len() - p.left));
        for j in set {
            if p.binning.bin(&boxes[j as usize]) <= p.plane { left.push(j) } else { right.push(j) }
        }
        Halves { left, right, boxes: p.boxes, plane: Axis::from_index(p.binning.axis), median: None }
    }
}

/// A node divided by [`Sah::halves`].
pub(crate) struct Halves {
    pub(crate) left: Vec<u32>,
    pub(crate) right: Vec<u32>,
    pub(crate) boxes: [Aabb; 2],
    /// The axis of the plane that divided it.
    plane: Option<Axis>,
    /// The median cut's record, when the centroids coincided.
    median: Option<Split>,
}

impl Halves {
    /// The split record of the division.
    pub(crate) fn split(&self, ctx: &Ctx<'_>) -> Split {
        match self.median {
            Some(split) => split,
            None => ctx.split_of(&self.boxes[0], &self.boxes[1], self.plane),
        }
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
        let h = self.halves(set, aabb);
        let split = h.split(self.ctx);
        (h.left, h.right, split)
    }
}
