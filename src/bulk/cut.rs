//! The cut step shared by MOA, LAA and LAA's trial subtrees:
//! `ComputeMinOverlap` (MOA2, §3.1) on the six orders of MOA1, the choice
//! among them (`Select_minimum`) and the division of a node's lists.
//!
//! A node keeps its objects as six lists, one per order (x-min, x-max,
//! y-min, y-max, z-min, z-max: MOA1's loop order), each sorted by that
//! coordinate with ties broken by object id. The lists are sorted once for
//! the whole scene and divided stably at every cut, so a node never sorts.
//!
//! **Cut range.** A node of N objects at positions 0..N in an order is cut
//! after position `cut_index` (Icut): the first part is 0..=Icut. With
//! k = ⌊R·N⌋ the paper's range is Icut ∈ [k, N-1-k] (`firstTreat =
//! first + R*N`, `lastTreat = last - R*N`, truncated to integers), so the
//! first part has at least k+1 objects and the second at least k. We clamp
//! it to [0, N-2] so that both parts are non-empty, and when R = 0.5 with N
//! even leaves it empty we use the single middle cut Icut = N/2 - 1.
//! ⌊R·N⌋ is taken with a relative tolerance of 1e-12 so that a decimal rate
//! such as 0.29 × 100 gives 29, not 28.
//!
//! **Overlap.** The value of a cut is MOA2's `max(upper coordinate over
//! the first part) - min(lower coordinate over the second part)` along the
//! order's axis: negative for a gap. All cuts of an order are evaluated in
//! one pass with a running prefix maximum and a table of suffix minima,
//! O(N) where the paper's `SearchMax`/`SearchMin` rescans are O(N²).

use std::ops::RangeInclusive;
use std::sync::atomic::{AtomicBool, Ordering::Relaxed};

use rayon::prelude::*;

use super::walk::PAR_MIN;
use super::{Order, Split, TieBreak};
use crate::geom::{Aabb, Axis, Point};

/// A node's objects in the six orders; `lists[o]` is sorted by order `o`.
pub(crate) type SixLists = [Vec<u32>; 6];

/// The axis and coordinate of order `o` (0..6): x-min, x-max, y-min, ...
fn order_of(o: usize) -> (Axis, Order) {
    let axis = Axis::ALL[o / 2];
    (axis, if o.is_multiple_of(2) { Order::Min } else { Order::Max })
}

/// The six sort keys of every object, read off its box: the lower and
/// upper coordinates on axis a are orders 2a and 2a + 1. The boxes are
/// borrowed, not copied into per-order arrays: a list is scanned in its
/// own order, so each read misses the cache either way, and a box's two
/// coordinates on an axis share a line (and a 10^7-object build saves
/// 480 MB). `side[j]` says which part of the cut being made object j falls in.
pub(crate) struct Keys<'a> {
    boxes: &'a [Aabb],
    /// Written and read only by the task dividing the node that holds j:
    /// tasks running at the same time hold disjoint objects.
    side: Vec<AtomicBool>,
    /// Input id of each object: the tie-break.
    ids: &'a [u32],
}

impl<'a> Keys<'a> {
    /// The keys of `boxes` (finite, checked by the caller); object j has
    /// input id `ids[j]`, which breaks ties.
    pub(crate) fn new(boxes: &'a [Aabb], ids: &'a [u32]) -> Keys<'a> {
        Keys { boxes, ids, side: boxes.iter().map(|_| AtomicBool::new(false)).collect() }
    }

    /// Object j's coordinate for order o.
    #[inline]
    fn coord(&self, o: usize, j: u32) -> f64 {
        let b = &self.boxes[j as usize];
        if o.is_multiple_of(2) { b.min[o / 2] } else { b.max[o / 2] }
    }

    /// The whole scene's six lists: objects 0..n sorted in each order.
    pub(crate) fn sorted_lists(&self) -> SixLists {
        // One order at a time, each sorted on every thread: the packed keys
        // (16 bytes an object) of only one order are held at once.
        six(false, |o| {
            // One integer per object, ordered as (key, input id) and
            // carrying the object: read in order once, compared without
            // floating point.
            let mut packed: Vec<u128> = (self.ids.iter().zip(0u32..))
                .map(|(&id, j)| {
                    u128::from(ordered_bits(self.coord(o, j))) << 64 | u128::from(id) << 32 | u128::from(j)
                })
                .collect();
            packed.par_sort_unstable();
            packed.into_iter().map(|p| p as u32).collect()
        })
    }

    /// R(S_n) of a node, read off its lists: the least lower coordinate on
    /// an axis heads its min order, the greatest upper one ends its max order.
    pub(crate) fn aabb(&self, lists: &SixLists) -> Aabb {
        let corner = |o: usize, pick: fn(&[u32]) -> Option<&u32>| {
            pick(&lists[o]).map_or(f64::NAN, |&j| self.coord(o, j))
        };
        Aabb::new(
            Point::new(corner(0, <[u32]>::first), corner(2, <[u32]>::first), corner(4, <[u32]>::first)),
            Point::new(corner(1, <[u32]>::last), corner(3, <[u32]>::last), corner(5, <[u32]>::last)),
        )
    }
}

/// Bits of a finite `x` whose unsigned order is the order of the values,
/// with -0.0 and 0.0 equal (so that they tie, and the id decides).
fn ordered_bits(x: f64) -> u64 {
    let bits = (x + 0.0).to_bits();
    if bits >> 63 == 1 { !bits } else { bits | 1 << 63 }
}

/// The first part of a cut holds Icut + 1 objects: Icut ranges over
/// [`cut_range`]. Needs `n >= 2`.
pub(crate) fn cut_range(n: usize, rate: f64) -> RangeInclusive<usize> {
    debug_assert!(n >= 2);
    // Paper §3.1: MOA1's `firstTreat..lastTreat` is empty for R = 0.5 and
    // N even, and indexes absolutely (first..last); ours is clamped to
    // leave both parts non-empty, and counts from the node's first object.
    let r_n = rate * n as f64;
    let k = ((r_n + r_n * 1e-12).floor() as usize).min(n / 2);
    let last = (n - 1 - k).min(n - 2);
    k.min(last)..=last
}

/// One candidate cut: order `o` of a node cut after `cut_index`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct Cut {
    pub(crate) order: usize,
    /// Icut: the position of the last object of the first part.
    pub(crate) cut_index: usize,
    /// MOA2's raw overlap; negative for a gap.
    pub(crate) gap: f64,
}

impl Cut {
    /// The overlap the paper reports: `gap` clamped at zero.
    pub(crate) fn overlap(&self) -> f64 {
        if self.gap > 0.0 { self.gap } else { 0.0 }
    }

    /// How far the cut is from the middle of a node of `n` objects.
    fn imbalance(&self, n: usize) -> usize {
        (2 * (self.cut_index + 1)).abs_diff(n)
    }

    /// True when this cut beats `other` (found earlier) under `tie`, in a
    /// node of `n` objects. Strict, so that the first found wins a tie.
    pub(crate) fn beats(&self, other: &Cut, n: usize, tie: TieBreak) -> bool {
        // Paper §3.1: MOA2 as printed compares raw values (`overlap <
        // minOv.overlap`), which prefers wider gaps like `WidestGap`; its
        // tables report overlaps clamped at zero, and `FirstFound` compares
        // those, so that the first cut with no overlap wins.
        match tie {
            TieBreak::FirstFound => self.overlap() < other.overlap(),
            TieBreak::WidestGap => self.gap < other.gap,
            TieBreak::MostBalanced => {
                (self.overlap(), self.imbalance(n)) < (other.overlap(), other.imbalance(n))
            }
        }
    }

    /// The node's split record.
    pub(crate) fn split(&self) -> Split {
        let (axis, order) = order_of(self.order);
        Split { axis, order, overlap: self.overlap(), gap: self.gap }
    }
}

/// `ComputeMinOverlap` (MOA2) on order `o`: the best cut of `list` in the
/// cut range, in one O(N) pass. A list sorted by the lower coordinate
/// starts each second part with its least lower coordinate, and one sorted
/// by the upper coordinate ends each first part with its greatest upper
/// one: only the other extreme needs a running maximum (prefix) or a table
/// of minima (suffix).
fn best_in_order(keys: &Keys<'_>, list: &[u32], o: usize, rate: f64, tie: TieBreak) -> Cut {
    let n = list.len();
    let range = cut_range(n, rate);
    let (first, last) = (*range.start(), *range.end());
    let axis = o / 2;
    let (lower, upper) = (|j: u32| keys.coord(2 * axis, j), |j: u32| keys.coord(2 * axis + 1, j));
    // Paper §3.1: MOA2 rescans each part with `SearchMax`/`SearchMin`,
    // O(N²) per order; the running extremes give the same values in O(N).
    let mut best: Option<Cut> = None;
    let mut consider = |cut_index: usize, gap: f64| {
        let cut = Cut { order: o, cut_index, gap };
        if best.is_none_or(|b| cut.beats(&b, n, tie)) {
            best = Some(cut);
        }
    };
    if o.is_multiple_of(2) {
        let mut high = list[..first].iter().fold(f64::NEG_INFINITY, |m, &j| m.max(upper(j)));
        for k in first..=last {
            high = high.max(upper(list[k]));
            consider(k, high - lower(list[k + 1]));
        }
    } else {
        // low[k - first]: the least lower coordinate over list[k + 1..].
        let mut low = vec![f64::INFINITY; last - first + 1];
        let mut least = list[last + 1..].iter().fold(f64::INFINITY, |m, &j| m.min(lower(j)));
        for k in (first..=last).rev() {
            low[k - first] = least;
            least = least.min(lower(list[k]));
        }
        for (k, low) in (first..=last).zip(low) {
            consider(k, upper(list[k]) - low);
        }
    }
    // The range is never empty (n >= 2), so a cut was considered.
    best.unwrap_or_default()
}

/// The best cut of each of the six orders (the paper's `minOv`).
pub(crate) fn candidates(keys: &Keys<'_>, lists: &SixLists, rate: f64, tie: TieBreak) -> [Cut; 6] {
    six(lists[0].len() >= PAR_MIN, |o| best_in_order(keys, &lists[o], o, rate, tie))
}

/// `Select_minimum(minOv)`: the first of the six candidates that no later
/// one beats.
pub(crate) fn choose(candidates: &[Cut; 6], n: usize, tie: TieBreak) -> Cut {
    candidates.iter().skip(1).fold(candidates[0], |best, c| if c.beats(&best, n, tie) { *c } else { best })
}

/// MOA's greedy cut of a node: the best of the six orders.
pub(crate) fn moa_cut(keys: &Keys<'_>, lists: &SixLists, rate: f64, tie: TieBreak) -> Cut {
    choose(&candidates(keys, lists, rate, tie), lists[0].len(), tie)
}

/// The node's lists divided at `cut`: each list keeps its order, split into
/// the objects of the first part and those of the second.
pub(crate) fn partition(keys: &Keys<'_>, lists: &SixLists, cut: &Cut) -> (SixLists, SixLists) {
    let (o, k) = (cut.order, cut.cut_index);
    for (i, &j) in lists[o].iter().enumerate() {
        keys.side[j as usize].store(i <= k, Relaxed);
    }
    divide_marked(keys, lists, Some((o, k)))
}

/// The node's lists divided into the objects of `first` (some of the
/// node's objects, found by another method) and the rest, each list
/// keeping its order.
pub(crate) fn partition_by(keys: &Keys<'_>, lists: &SixLists, first: &[u32]) -> (SixLists, SixLists) {
    for &j in &lists[0] {
        keys.side[j as usize].store(false, Relaxed);
    }
    for &j in first {
        keys.side[j as usize].store(true, Relaxed);
    }
    divide_marked(keys, lists, None)
}

/// True when `a` and `b`, parts of the node of objects `node`, hold the
/// same objects.
pub(crate) fn same_objects(keys: &Keys<'_>, node: &[u32], a: &[u32], b: &[u32]) -> bool {
    if a.len() != b.len() {
        return false;
    }
    for &j in node {
        keys.side[j as usize].store(false, Relaxed);
    }
    for &j in a {
        keys.side[j as usize].store(true, Relaxed);
    }
    b.iter().all(|&j| keys.side[j as usize].load(Relaxed))
}

/// The lists divided by the marks in `keys.side`; `cut` (order, Icut), when
/// the marks come from one, divides its own list by position.
fn divide_marked(keys: &Keys<'_>, lists: &SixLists, cut: Option<(usize, usize)>) -> (SixLists, SixLists) {
    let parts = six(lists[0].len() >= PAR_MIN, |p| {
        let list = &lists[p];
        match cut {
            Some((o, k)) if p == o => (list[..=k].to_vec(), list[k + 1..].to_vec()),
            _ => list.iter().partition(|&&j| keys.side[j as usize].load(Relaxed)),
        }
    });
    let mut first = SixLists::default();
    let mut second = SixLists::default();
    for (o, (a, b)) in parts.into_iter().enumerate() {
        first[o] = a;
        second[o] = b;
    }
    (first, second)
}

/// `f(0..6)`, on rayon when `par`.
fn six<T: Send + Default>(par: bool, f: impl Fn(usize) -> T + Sync) -> [T; 6] {
    let mut out: [T; 6] = Default::default();
    if par {
        out.par_iter_mut().enumerate().for_each(|(o, slot)| *slot = f(o));
    } else {
        out.iter_mut().enumerate().for_each(|(o, slot)| *slot = f(o));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ordered_bits_keep_the_order_of_values() {
        let v = [f64::MIN, -1e300, -2.5, -1e-310, -0.0, 0.0, 1e-310, 3.0, 1e300, f64::MAX];
        for w in v.windows(2) {
            assert_eq!(ordered_bits(w[0]) < ordered_bits(w[1]), w[0] < w[1], "{w:?}");
            assert_eq!(ordered_bits(w[0]) == ordered_bits(w[1]), w[0] == w[1], "{w:?}");
        }
    }

    #[test]
    fn the_cut_range_keeps_r_n_objects_off_each_end() {
        assert_eq!(cut_range(10, 0.2), 2..=7);
        assert_eq!(cut_range(100, 0.29), 29..=70);
        assert_eq!(cut_range(10, 0.0), 0..=8);
        assert_eq!(cut_range(11, 0.5), 5..=5);
    }

    #[test]
    fn the_cut_range_always_leaves_an_object_on_each_side() {
        assert_eq!(cut_range(2, 0.0), 0..=0);
        assert_eq!(cut_range(2, 0.5), 0..=0);
        assert_eq!(cut_range(3, 0.5), 1..=1);
        // R = 0.5 with N even: the paper's range is empty; the middle cut.
        assert_eq!(cut_range(10, 0.5), 4..=4);
        for n in 2..200 {
            for rate in [0.0, 0.01, 0.2, 0.3, 0.49, 0.5] {
                let r = cut_range(n, rate);
                assert!(!r.is_empty() && *r.end() <= n - 2, "{n} {rate}");
            }
        }
    }

    #[test]
    fn first_found_keeps_the_first_zero_and_widest_gap_the_widest() {
        // x-min order: [0,1] [2,3] [10,11]; cuts after 0 (gap -1) and 1 (gap -7).
        let boxes: Vec<Aabb> =
            [0.0, 2.0, 10.0].iter().map(|&x| Aabb::from_array([x, 0.0, 0.0, x + 1.0, 1.0, 1.0])).collect();
        let keys = Keys::new(&boxes, &[0, 1, 2]);
        let list = [0, 1, 2];
        let first = best_in_order(&keys, &list, 0, 0.0, TieBreak::FirstFound);
        assert_eq!((first.cut_index, first.gap, first.overlap()), (0, -1.0, 0.0));
        let widest = best_in_order(&keys, &list, 0, 0.0, TieBreak::WidestGap);
        assert_eq!((widest.cut_index, widest.gap), (1, -7.0));
    }

    #[test]
    fn most_balanced_prefers_the_middle_among_equal_overlaps() {
        let boxes: Vec<Aabb> = (0..6)
            .map(|i| Aabb::from_array([i as f64 * 2.0, 0.0, 0.0, i as f64 * 2.0 + 1.0, 1.0, 1.0]))
            .collect();
        let keys = Keys::new(&boxes, &[0, 1, 2, 3, 4, 5]);
        let cut = best_in_order(&keys, &[0, 1, 2, 3, 4, 5], 0, 0.0, TieBreak::MostBalanced);
        assert_eq!(cut.cut_index, 2);
    }
}
