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
use super::median::Median;
use super::splitter::{Ctx, Splitter};
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

    /// The bin of centroid coordinate `c` (the last bin takes the upper end).
    fn bin_at(&self, c: f64) -> usize {
        // The ratio is in [0, BINS] (`c` is in the spread the binning is
        // of); `as u32` saturates below at 0, and takes fewer instructions
        // than a clamp of a signed cast.
        (((c - self.low) * self.scale) as u32).min(BINS as u32 - 1) as usize
    }
}

/// The least and greatest centroid coordinates of a set of boxes, per axis:
/// where [`Sah::plane`] places its bins.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Spread {
    /// Padded to four numbers, as a [`Bin`]'s corners are, for the same
    /// reason: packed minima and maxima (the fourth is 0 once one is added).
    low: [f64; 4],
    high: [f64; 4],
}

impl Spread {
    const EMPTY: Spread = Spread { low: [f64::INFINITY; 4], high: [f64::NEG_INFINITY; 4] };

    /// The spread of the boxes of objects `set`.
    pub(crate) fn of(boxes: &[Aabb], set: &[u32]) -> Spread {
        let mut s = Spread::EMPTY;
        for &j in set {
            s.add(&centroids(&boxes[j as usize]));
        }
        s
    }

    fn add(&mut self, c: &[f64; 3]) {
        let c = [c[0], c[1], c[2], 0.0];
        widen(&mut self.low, &mut self.high, &c, &c);
    }
}

/// `low` lowered to `lo` and `high` raised to `hi` on each coordinate where
/// they are strictly beyond: [`Aabb::union`]'s rule, on padded corners
/// (two packed minima and two packed maxima). A comparison rather than
/// `f64::min`, which pays for NaN (meshes hold none): this runs per object
/// per level of every trial subtree.
#[allow(clippy::needless_range_loop)] // zipped iterators compiled to 10% more instructions (callgrind)
fn widen(low: &mut [f64; 4], high: &mut [f64; 4], lo: &[f64; 4], hi: &[f64; 4]) {
    for k in 0..4 {
        low[k] = if lo[k] < low[k] { lo[k] } else { low[k] };
        high[k] = if hi[k] > high[k] { hi[k] } else { high[k] };
    }
}

/// A bin: how many objects' centroids fall in it, and their boxes' union.
/// The corners are kept padded to four numbers (the fourth always 0), so
/// that adding a box is two packed minima and two packed maxima; a box's
/// corners as points straddle the pairs, and their union took a third
/// more instructions (the loop that fills bins runs for every object at
/// every level of every trial subtree).
#[derive(Debug, Clone, Copy)]
struct Bin {
    count: usize,
    low: [f64; 4],
    high: [f64; 4],
}

impl Bin {
    const EMPTY: Bin = Bin { count: 0, low: [f64::INFINITY; 4], high: [f64::NEG_INFINITY; 4] };

    /// Adds an object of box `b`: its union is [`Aabb::union`]'s, bit for
    /// bit (`b`'s coordinate only where it is strictly beyond).
    fn add(&mut self, b: &Aabb) {
        // At most a set's length: no overflow to check.
        self.count = self.count.wrapping_add(1);
        widen(
            &mut self.low,
            &mut self.high,
            &[b.min.x, b.min.y, b.min.z, 0.0],
            &[b.max.x, b.max.y, b.max.z, 0.0],
        );
    }

    /// The union of the boxes added.
    fn aabb(&self) -> Aabb {
        let [x0, y0, z0, _] = self.low;
        let [x1, y1, z1, _] = self.high;
        Aabb::from_array([x0, y0, z0, x1, y1, z1])
    }
}

/// The bins of one axis.
type Bins = [Bin; BINS];

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
/// skipped), with the plane and its sides' boxes. A plane after an empty
/// bin divides as the plane before it does, at the same cost, and loses
/// the tie: only planes after a filled bin are measured (a small node
/// fills few of the bins).
fn best_plane(bins: &Bins, parent: f64, measure: Measure) -> Option<(f64, usize, [Aabb; 2], usize)> {
    // n A of the right side of each plane, swept from the right.
    let mut right = [(None, Aabb::EMPTY); BINS - 1];
    let mut acc = (0usize, Aabb::EMPTY);
    let mut area = None;
    for plane in (0..BINS - 1).rev() {
        let bin = &bins[plane + 1];
        if bin.count > 0 {
            acc = (acc.0 + bin.count, acc.1.union(&bin.aabb()));
            area = Some(acc.0 as f64 * measure.of(&acc.1));
        }
        right[plane] = (area, acc.1);
    }
    let mut acc = (0usize, Aabb::EMPTY);
    let mut best: Option<(f64, usize, [Aabb; 2], usize)> = None;
    for (plane, (right, right_box)) in right.iter().enumerate() {
        let bin = &bins[plane];
        if bin.count == 0 {
            continue;
        }
        acc = (acc.0 + bin.count, acc.1.union(&bin.aabb()));
        let Some(right) = *right else { continue };
        let cost = TRAVERSAL_COST + (acc.0 as f64 * measure.of(&acc.1) + right) / parent;
        if best.is_none_or(|b| cost < b.0) {
            best = Some((cost, plane, [acc.1, *right_box], acc.0));
        }
    }
    best
}

impl Sah<'_> {
    /// The plane of least cost over all three axes (the first axis and
    /// plane on ties); none when all centroids coincide. One pass over the
    /// objects, binning on every axis within `spread`, the set's.
    fn plane(&self, set: &[u32], aabb: &Aabb, spread: &Spread) -> Option<Plane> {
        let boxes = self.ctx.boxes;
        let measure = Measure::of_node(self.heuristic, aabb);
        // Not zero: some centroids differ whenever a plane is tried below.
        let parent = measure.of(aabb);
        let binnings: [Option<Binning>; 3] =
            std::array::from_fn(|a| Binning::new(a, spread.low[a], spread.high[a]));
        let mut bins = [[Bin::EMPTY; BINS]; 3];
        // Indexed by axis rather than zipped with the bins: this loop runs
        // for every object at every level of every trial subtree (a fifth
        // of a build's instructions on ship 30,000).
        for &j in set {
            let b = &boxes[j as usize];
            for (axis, binning) in binnings.iter().enumerate() {
                if let Some(binning) = binning {
                    bins[axis][binning.bin_at(centroid(b, axis))].add(b);
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
        let spread = Spread::of(self.ctx.boxes, &set);
        self.halves_within(set, aabb, &spread)
    }

    /// [`Sah::halves`] of a set whose [`Spread`] is known; the halves come
    /// with theirs, found as they are divided.
    pub(crate) fn halves_within(&self, set: Vec<u32>, aabb: &Aabb, spread: &Spread) -> Halves {
        let boxes = self.ctx.boxes;
        let Some(p) = self.plane(&set, aabb, spread) else {
            let (left, right, split) = self.median.split(set, aabb);
            let boxes = [self.ctx.aabb_of(&left), self.ctx.aabb_of(&right)];
            let spreads = [Spread::of(self.ctx.boxes, &left), Spread::of(self.ctx.boxes, &right)];
            return Halves { left, right, boxes, spreads, plane: None, median: Some(split) };
        };
        let (mut left, mut right) = (Vec::with_capacity(p.left), Vec::with_capacity(set.len() - p.left));
        let mut spreads = [Spread::EMPTY; 2];
        for j in set {
            let c = centroids(&boxes[j as usize]);
            let side = usize::from(p.binning.bin_at(c[p.binning.axis]) > p.plane);
            spreads[side].add(&c);
            if side == 0 { left.push(j) } else { right.push(j) }
        }
        Halves { left, right, boxes: p.boxes, spreads, plane: Axis::from_index(p.binning.axis), median: None }
    }
}

/// A node divided by [`Sah::halves`].
pub(crate) struct Halves {
    pub(crate) left: Vec<u32>,
    pub(crate) right: Vec<u32>,
    pub(crate) boxes: [Aabb; 2],
    /// The sides' centroid spreads.
    pub(crate) spreads: [Spread; 2],
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

/// The centre of `b`.
fn centroids(b: &Aabb) -> [f64; 3] {
    std::array::from_fn(|axis| centroid(b, axis))
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

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Every plane measured, the first of least cost kept: what
    /// [`best_plane`] must choose.
    fn every_plane(bins: &Bins, parent: f64, measure: Measure) -> Option<(f64, usize, [Aabb; 2], usize)> {
        let mut best: Option<(f64, usize, [Aabb; 2], usize)> = None;
        for plane in 0..BINS - 1 {
            let side = |range: std::ops::Range<usize>| {
                bins[range].iter().fold((0, Aabb::EMPTY), |(n, b), c| (n + c.count, b.union(&c.aabb())))
            };
            let ((nl, l), (nr, r)) = (side(0..plane + 1), side(plane + 1..BINS));
            if nl == 0 || nr == 0 {
                continue;
            }
            let cost = TRAVERSAL_COST + (nl as f64 * measure.of(&l) + nr as f64 * measure.of(&r)) / parent;
            if best.is_none_or(|b| cost < b.0) {
                best = Some((cost, plane, [l, r], nl));
            }
        }
        best
    }

    proptest! {
        #[test]
        fn only_planes_after_filled_bins_are_measured_and_the_choice_is_the_same(
            filled in prop::collection::vec((0usize..BINS, 1usize..5, prop::array::uniform6(0.0f64..100.0)), 0..12),
            volume in any::<bool>(),
        ) {
            let mut bins: Bins = [Bin::EMPTY; BINS];
            for (i, n, c) in filled {
                let b = Aabb::from_array([c[0].min(c[3]), c[1].min(c[4]), c[2].min(c[5]), c[0].max(c[3]), c[1].max(c[4]), c[2].max(c[5])]);
                for _ in 0..n {
                    bins[i].add(&b);
                }
            }
            let measure = if volume { Measure::Volume([true; 3]) } else { Measure::Area };
            let fast = best_plane(&bins, 1e6, measure);
            let slow = every_plane(&bins, 1e6, measure);
            prop_assert_eq!(fast.map(|b| (b.0.to_bits(), b.1, b.2, b.3)), slow.map(|b| (b.0.to_bits(), b.1, b.2, b.3)));
        }

        /// A bin's box is the union of the boxes added, bit for bit, signed
        /// zeros and infinities included: the trees depend on it.
        #[test]
        fn a_bins_box_is_the_union_of_its_boxes_bit_for_bit(
            corners in prop::collection::vec(prop::array::uniform6(prop::sample::select(
                vec![-2.5, -1.0, -0.0, 0.0, 0.5, 3.0, f64::INFINITY, f64::NEG_INFINITY])), 0..8),
        ) {
            let mut bin = Bin::EMPTY;
            let mut union = Aabb::EMPTY;
            for c in &corners {
                let b = Aabb::from_array(*c);
                bin.add(&b);
                union = union.union(&b);
            }
            prop_assert_eq!(bin.count, corners.len());
            prop_assert_eq!(bin.aabb().to_array().map(f64::to_bits), union.to_array().map(f64::to_bits));
        }
    }
}
