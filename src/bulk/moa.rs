//! Minimum Overlap Algorithm, MOA1 (`wDivideList`) with MOA2
//! (`ComputeMinOverlap`), §3.1: each node is cut where the overlap of its
//! two parts is least over the six sorted orders. The cut itself lives in
//! `cut.rs`, shared with LAA.

use super::Split;
use super::cut::{Keys, SixLists, moa_cut, partition};
use super::splitter::{Ctx, Splitter};
use crate::geom::Aabb;

/// MOA's splitter: the greedy minimum-overlap cut.
pub(crate) struct Moa<'a> {
    ctx: &'a Ctx<'a>,
    keys: &'a Keys<'a>,
}

impl<'a> Moa<'a> {
    pub(crate) fn new(ctx: &'a Ctx<'a>, keys: &'a Keys<'a>) -> Moa<'a> {
        Moa { ctx, keys }
    }
}

impl Splitter for Moa<'_> {
    type Set = SixLists;

    fn objects<'s>(&self, set: &'s SixLists) -> &'s [u32] {
        &set[0]
    }

    fn aabb(&self, _ctx: &Ctx<'_>, set: &SixLists) -> Aabb {
        self.keys.aabb(set)
    }

    fn split(&self, set: SixLists, _aabb: &Aabb) -> (SixLists, SixLists, Split) {
        let cut = moa_cut(self.keys, &set, self.ctx.rate, self.ctx.tie);
        let (left, right) = partition(self.keys, &set, &cut);
        (left, right, cut.split())
    }
}
