//! Method `refine` (not in the paper): the `vsah` tree, refined top-down
//! with MOA's cuts under a cost model.
//!
//! At each node, seven ways to divide it are scored: the `vsah` cut and
//! the six candidate cuts of MOA2 (§3.1, the best cut of each sorted order
//! within the rate R, as `cut.rs` finds them for MOA and LAA). Each side of
//! each is completed with a `vsah` subtree, never materialised, and scored
//! by the [`CostModel`]'s expected cost of a box query of extent q: the
//! leaves it reaches, plus a third of a block read for every node it
//! reaches (see `cost.rs`). The cut of least score wins (the `vsah` cut on
//! ties, then the first candidate in the six-order), and the pass goes on
//! in its children.
//!
//! Scoring with LAA's structure (§3.2: candidates judged by trial subtrees
//! grown below them) but a different measure: overlap along one axis says
//! nothing of how big the boxes are on the other two, which is what a box
//! query meets.
//!
//! The tree's cost is never above the `vsah` tree's: a node's own cost is
//! the same whichever way it is cut, and at the root the kept
//! option scores at most the `vsah` cut, whose score is the `vsah` tree's
//! cost, and each child in turn starts from its own `vsah` subtree, the one
//! that was scored (up to the rounding of the sums).
//!
//! The seven options are scored in parallel, and every score is a sum in an
//! order fixed by the subtrees' sizes, so the tree is the same on any
//! number of threads. A build costs 15 to 65 times `vsah`'s.
//!
//! Measured and not kept (README, "Build methods and bench-build"): a cost
//! mixing several query sizes, page-aligned cuts as extra options for
//! fuller leaves, and one level of look-ahead below each option.

use rayon::prelude::*;

use super::Split;
use super::cost::CostModel;
use super::cut::{Keys, SixLists, candidates, partition, partition_by};
use super::driver::{Ctx, Splitter};
use super::sah::{Heuristic, Sah};
use super::walk::{Walk, walk};
use crate::geom::Aabb;

/// Below this many objects a node's options are scored on one thread.
const PAR_OPTIONS_MIN: usize = 512;

/// The refining splitter.
pub(crate) struct Refine<'a> {
    ctx: &'a Ctx<'a>,
    keys: &'a Keys<'a>,
    vsah: Sah<'a>,
    model: CostModel,
}

impl<'a> Refine<'a> {
    pub(crate) fn new(ctx: &'a Ctx<'a>, keys: &'a Keys<'a>, model: CostModel) -> Refine<'a> {
        Refine { ctx, keys, vsah: Sah::new(ctx, Heuristic::Volume), model }
    }

    /// The expected cost of the `vsah` subtree of `set`, whose box is `aabb`.
    fn score(&self, set: Vec<u32>, aabb: Aabb) -> f64 {
        walk(&Trial { ctx: self.ctx, vsah: &self.vsah, model: &self.model }, (set, aabb), 0)
    }
}

impl Splitter for Refine<'_> {
    type Set = SixLists;

    fn objects<'s>(&self, set: &'s SixLists) -> &'s [u32] {
        &set[0]
    }

    fn aabb(&self, _ctx: &Ctx<'_>, set: &SixLists) -> Aabb {
        self.keys.aabb(set)
    }

    fn split(&self, set: SixLists, aabb: &Aabb) -> (SixLists, SixLists, Split) {
        let ctx = self.ctx;
        let n = set[0].len();
        let cands = candidates(self.keys, &set, ctx.rate, ctx.tie);
        let vsah = self.vsah.halves(set[0].clone(), aabb);
        // Option 0 is the vsah cut, options 1..=6 the candidates.
        let mut options = vec![(vsah.left.clone(), vsah.right.clone())];
        options.extend(cands.iter().map(|c| {
            let list = &set[c.order];
            (list[..=c.cut_index].to_vec(), list[c.cut_index + 1..].to_vec())
        }));
        let score = |o: usize| {
            let (a, b) = &options[o];
            let [l, r] = if o == 0 { vsah.boxes } else { [ctx.aabb_of(a), ctx.aabb_of(b)] };
            self.score(a.clone(), l) + self.score(b.clone(), r)
        };
        let scores: Vec<f64> = if n >= PAR_OPTIONS_MIN {
            (0..options.len()).into_par_iter().map(score).collect()
        } else {
            (0..options.len()).map(score).collect()
        };
        let best = (1..scores.len()).fold(0, |best, i| if scores[i] < scores[best] { i } else { best });
        match best.checked_sub(1) {
            None => {
                let (left, right) = partition_by(self.keys, &set, &vsah.left);
                (left, right, vsah.split(ctx))
            }
            Some(c) => {
                let (left, right) = partition(self.keys, &set, &cands[c]);
                (left, right, cands[c].split())
            }
        }
    }
}

/// A `vsah` subtree that only adds up its nodes' expected costs.
struct Trial<'a> {
    ctx: &'a Ctx<'a>,
    vsah: &'a Sah<'a>,
    model: &'a CostModel,
}

/// A trial node: its objects and their box.
type TrialSet = (Vec<u32>, Aabb);

impl Walk for Trial<'_> {
    type Set = TrialSet;
    type Out = f64;
    type Mark = ();

    fn len(&self, set: &TrialSet) -> usize {
        set.0.len()
    }

    fn start(&self) -> f64 {
        0.0
    }

    fn visit(&self, (set, aabb): TrialSet, _depth: u32, out: &mut f64) -> Option<(TrialSet, TrialSet, ())> {
        let leaf = self.ctx.leaf.fits(&set);
        *out += self.model.node_cost(&aabb, leaf);
        if leaf {
            return None;
        }
        self.ctx.meter.worked(set.len());
        let h = self.vsah.halves(set, &aabb);
        let [l, r] = h.boxes;
        Some(((h.left, l), (h.right, r), ()))
    }

    fn right_begins(&self, _out: &mut f64, _mark: ()) {}

    fn splice(&self, out: &mut f64, _mark: (), left: f64, right: f64) {
        *out += left + right;
    }
}
