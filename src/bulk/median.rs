//! Reference method `median` (not in the paper): each node is cut in halves
//! at the median box centre along the longest axis of its box, like
//! boost's packing. The objects go left when their centre comes first
//! (ties by input id); the left half gets ⌈N/2⌉.

use std::cmp::Ordering;

use super::Split;
use super::splitter::{Ctx, Splitter};
use crate::geom::Aabb;

/// The median splitter.
pub(crate) struct Median<'a> {
    ctx: &'a Ctx<'a>,
}

impl<'a> Median<'a> {
    pub(crate) fn new(ctx: &'a Ctx<'a>) -> Median<'a> {
        Median { ctx }
    }
}

impl Splitter for Median<'_> {
    type Set = Vec<u32>;

    fn objects<'s>(&self, set: &'s Vec<u32>) -> &'s [u32] {
        set
    }

    fn split(&self, mut set: Vec<u32>, aabb: &Aabb) -> (Vec<u32>, Vec<u32>, Split) {
        let axis = aabb.longest_axis();
        let i = axis.index();
        // Twice the centre: the same order, one operation fewer.
        let centre2 = |j: u32| {
            let b = &self.ctx.boxes[j as usize];
            b.min[i] + b.max[i]
        };
        let id = |j: &u32| self.ctx.ids[*j as usize];
        let cmp =
            |a: &u32, b: &u32| -> Ordering { centre2(*a).total_cmp(&centre2(*b)).then(id(a).cmp(&id(b))) };
        let k = left_half(set.len());
        set.select_nth_unstable_by(k, cmp);
        let right = set.split_off(k);
        let split = self.ctx.split_between(&set, &right, Some(axis));
        (set, right, split)
    }
}

/// The size of the left half of a run of `n` >= 2 objects: ⌈n/2⌉.
pub(crate) fn left_half(n: usize) -> usize {
    n - n / 2
}
