//! Look Ahead Algorithm, §3.2: LAA1 (`wDivideList`), LAA2 (`LookAhead`) and
//! LAA3 (`wDivideListTrial`).
//!
//! At a node at level l, each of the six candidate cuts (the best cut of
//! each order, as MOA2 finds them) is scored by its own clamped overlap
//! plus the clamped overlaps of every internal node of greedy (MOA) trial
//! subtrees grown on both of its sides, and the candidate of least score
//! wins. Trial nodes are split while they do not fit a page and lie at
//! most `look_ahead_level` levels below the candidate's children (the
//! children being level 1, i.e. tree level l + 1): `Levels(0)` scores the
//! candidates by their own overlap and so rebuilds MOA node by node,
//! `Max` runs the trials down to the leaves. Trials are never
//! materialised: only their accumulated overlap is kept.
//!
//! A tie on the score is broken as MOA breaks ties between the candidates'
//! own cuts (first in the six-order for the paper's first-found rule);
//! this is what makes `Levels(0)` equal to MOA under every tie-break rule.
//!
//! With `look_ahead_level` = Max the tree's total overlap is never more
//! than MOA's (up to float rounding): at every node the greedy cut is one
//! of the candidates, and its score is exactly the greedy subtree's total.

// Paper §3.2: LAA2 as printed differs from this file in three ways.
// (1) It calls `wDivideListTrial(.., actualLevel, lookLevel)` on the
//     children with the parent's level, and LAA3 splits while
//     `actualLevel <= lookLevel`, so LookAheadLevel = 0 still splits the
//     children once: the paper's LookAheadLevel L is our `Levels(L + 1)`,
//     and the paper has no setting that is exactly MOA (it says "similar").
//     We count trial levels from the children so that `Levels(0)` is MOA.
// (2) `FloatSix[i]` starts at `minOv.V[i]` and each side adds `childOver`,
//     which itself starts at `minOv.V[i]`: the candidate's own overlap is
//     counted three times. We count it once.
// (3) `child_ove`, the trial's accumulator, is never declared or returned
//     (a global in the original, presumably), and MOA2 compares raw values
//     while the tables report clamped ones. We accumulate clamped
//     overlaps, the quantity of Tables 39-44.

use super::cut::{Cut, Keys, SixLists, candidates, moa_cut, partition};
use super::splitter::{Ctx, Splitter};
use super::walk::{PAR_MIN, Walk, join_if, walk};
use super::{LookAhead, Split};
use crate::geom::Aabb;

/// LAA's splitter: the candidate with the least look-ahead score.
pub(crate) struct Laa<'a> {
    trial: Trial<'a>,
}

impl<'a> Laa<'a> {
    pub(crate) fn new(ctx: &'a Ctx<'a>, keys: &'a Keys<'a>, look_ahead: LookAhead) -> Laa<'a> {
        Laa { trial: Trial { ctx, keys, look_ahead_level: look_ahead.levels() } }
    }

    /// LAA2 for one candidate: its overlap plus its trial subtrees'.
    fn score(&self, set: &SixLists, cut: &Cut) -> f64 {
        let t = &self.trial;
        if t.look_ahead_level == 0 {
            return cut.overlap();
        }
        let (left, right) = partition(t.keys, set, cut);
        let par = left[0].len().min(right[0].len()) >= PAR_MIN;
        let (a, b) = join_if(par, || walk(t, left, 1), || walk(t, right, 1));
        t.ctx.meter.reached(a.levels.max(b.levels));
        cut.overlap() + a.overlap + b.overlap
    }
}

impl Splitter for Laa<'_> {
    type Set = SixLists;

    fn objects<'s>(&self, set: &'s SixLists) -> &'s [u32] {
        &set[0]
    }

    fn aabb(&self, _ctx: &Ctx<'_>, set: &SixLists) -> Aabb {
        self.trial.keys.aabb(set)
    }

    fn split(&self, set: SixLists, _aabb: &Aabb) -> (SixLists, SixLists, Split) {
        let (ctx, keys) = (self.trial.ctx, self.trial.keys);
        let n = set[0].len();
        let cands = candidates(keys, &set, ctx.rate, ctx.tie);
        // Candidates one at a time: each holds a copy of the node's lists
        // while its trials run, and the trials themselves go parallel.
        let mut best = (cands[0], self.score(&set, &cands[0]));
        for cut in &cands[1..] {
            let score = self.score(&set, cut);
            if score < best.1 || (score == best.1 && cut.beats(&best.0, n, ctx.tie)) {
                best = (*cut, score);
            }
        }
        let (left, right) = partition(keys, &set, &best.0);
        (left, right, best.0.split())
    }
}

/// LAA3, `wDivideListTrial`: a greedy subtree that only adds up overlaps.
struct Trial<'a> {
    ctx: &'a Ctx<'a>,
    keys: &'a Keys<'a>,
    /// The deepest trial level split (children of the candidate = 1).
    look_ahead_level: u32,
}

/// What a trial subtree adds up.
#[derive(Debug, Default)]
struct TrialSum {
    /// Clamped overlaps of its internal nodes.
    overlap: f64,
    /// The deepest level at which it split a node (0: none).
    levels: u32,
}

impl Walk for Trial<'_> {
    type Set = SixLists;
    type Out = TrialSum;
    type Mark = ();

    fn len(&self, set: &SixLists) -> usize {
        set[0].len()
    }

    fn start(&self) -> TrialSum {
        TrialSum::default()
    }

    fn visit(&self, set: SixLists, depth: u32, out: &mut TrialSum) -> Option<(SixLists, SixLists, ())> {
        if depth > self.look_ahead_level || self.ctx.leaf.fits(&set[0]) {
            return None;
        }
        self.ctx.meter.worked(set[0].len());
        let cut = moa_cut(self.keys, &set, self.ctx.rate, self.ctx.tie);
        out.overlap += cut.overlap();
        out.levels = out.levels.max(depth);
        let (left, right) = partition(self.keys, &set, &cut);
        Some((left, right, ()))
    }

    fn right_begins(&self, _out: &mut TrialSum, _mark: ()) {}

    fn splice(&self, out: &mut TrialSum, _mark: (), left: TrialSum, right: TrialSum) {
        out.overlap += left.overlap;
        out.overlap += right.overlap;
        out.levels = out.levels.max(left.levels).max(right.levels);
    }
}
