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
//! number of threads. Options that divide the node alike (the two orders
//! of an axis often pick the same cut, and a cut can match the `vsah`
//! one) are scored once: a score depends only on the two sides' objects.
//! Nor is the `vsah` option scored at a node that its parent's trial grew:
//! that trial summed it already ([`Known`]).
//!
//! Measured and not kept (docs/build-methods.md, "Tried and dropped"): a
//! cost mixing several query sizes, page-aligned cuts as extra options for
//! fuller leaves, one level of look-ahead below each option, and scoring a
//! large node's options on a sample of its objects, which misses how full
//! the leaves come out.

use rayon::prelude::*;

use super::Split;
use super::cost::CostModel;
use super::cut::{Keys, SixLists, candidates, partition, partition_by, same_objects};
use super::sah::{Heuristic, Sah, Spread};
use super::splitter::{Ctx, Splitter};
use super::walk::{Walk, walk};
use crate::geom::Aabb;
use crate::rng::Rng;

/// Below this many objects a node's options are scored on one thread.
const PAR_OPTIONS_MIN: usize = 512;

/// A trial keeps no [`Known`] of its nodes of fewer objects: their own
/// trials cost little, and each record is an allocation.
const KNOWN_MIN: usize = 64;

/// How many levels below its root a trial keeps [`Known`] of: each node's
/// cost is added to the sum of each open node above it, so this bounds the
/// work per node where a tree is as deep as it has objects.
const KNOWN_DEPTH: usize = 48;

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

    /// The expected cost of the `vsah` subtree of `set`, whose box is
    /// `aabb` and centroid spread `spread`.
    fn score(&self, set: &[u32], aabb: Aabb, spread: Spread) -> Scored {
        walk(&Trial { ctx: self.ctx, vsah: &self.vsah, model: &self.model }, (set.to_vec(), aabb, spread), 0)
            .finish()
    }
}

/// What a trial learnt of a node it grew, for the node's own refinement:
/// the score of its `vsah` option (the sum of its `vsah` halves' trials,
/// as [`Refine::split`] would add them, bit for bit), and the same of those
/// halves. Known for the trial's nodes of at least [`KNOWN_MIN`] objects
/// down to [`KNOWN_DEPTH`] levels below its root.
pub(crate) struct Known {
    vsah_score: f64,
    halves: [Option<Box<Known>>; 2],
}

/// A node being refined: its lists, and what its parent's trial learnt of it.
pub(crate) type Pending = (SixLists, Option<Box<Known>>);

/// For each of `options` (two parts of the node of objects `node`), the
/// first earlier option with the same parts, in either order: its score is
/// the same (a sum of two scores is the same either way round).
fn repeats(keys: &Keys<'_>, node: &[u32], options: &[(&[u32], &[u32])]) -> Vec<Option<usize>> {
    let digests: Vec<_> = options.iter().map(|(a, b)| (digest(a), digest(b))).collect();
    (0..options.len())
        .map(|o| {
            let (a, _) = options[o];
            (0..o).find(|&e| {
                let (c, d) = options[e];
                (digests[e].0 == digests[o].0 && same_objects(keys, node, c, a))
                    || (digests[e].1 == digests[o].0 && same_objects(keys, node, d, a))
            })
        })
        .collect()
}

/// A cheap digest of a set of objects, equal for equal sets in any order.
fn digest(objects: &[u32]) -> (usize, u64) {
    // Each object's first SplitMix64 output, summed: order does not count.
    let mix = |j: u32| Rng::new(u64::from(j)).next_u64();
    (objects.len(), objects.iter().fold(0u64, |h, &j| h.wrapping_add(mix(j))))
}

impl Splitter for Refine<'_> {
    type Set = Pending;

    fn objects<'s>(&self, set: &'s Pending) -> &'s [u32] {
        &set.0[0]
    }

    fn aabb(&self, _ctx: &Ctx<'_>, set: &Pending) -> Aabb {
        self.keys.aabb(&set.0)
    }

    fn split(&self, (set, known): Pending, aabb: &Aabb) -> (Pending, Pending, Split) {
        let ctx = self.ctx;
        let n = set[0].len();
        let cands = candidates(self.keys, &set, ctx.rate, ctx.tie);
        let vsah = self.vsah.halves(set[0].clone(), aabb);
        // Option 0 is the vsah cut, options 1..=6 the candidates.
        let mut options: Vec<(&[u32], &[u32])> = vec![(&vsah.left, &vsah.right)];
        options.extend(cands.iter().map(|c| set[c.order].split_at(c.cut_index + 1)));
        let repeats = repeats(self.keys, &set[0], &options);
        // Each option's score and its sides' trials; none for a repeat, or
        // for the vsah option when the parent's trial already scored it.
        let score = |o: usize| -> (f64, Option<[Scored; 2]>) {
            if repeats[o].is_some() {
                return (f64::NAN, None);
            }
            if let (0, Some(k)) = (o, &known) {
                return (k.vsah_score, None);
            }
            let (a, b) = options[o];
            let ([l, r], [sl, sr]) = if o == 0 {
                (vsah.boxes, vsah.spreads)
            } else {
                ([ctx.aabb_of(a), ctx.aabb_of(b)], [Spread::of(ctx.boxes, a), Spread::of(ctx.boxes, b)])
            };
            let (a, b) = (self.score(a, l, sl), self.score(b, r, sr));
            (a.total + b.total, Some([a, b]))
        };
        let mut scored: Vec<(f64, Option<[Scored; 2]>)> = if n >= PAR_OPTIONS_MIN {
            (0..options.len()).into_par_iter().map(score).collect()
        } else {
            (0..options.len()).map(score).collect()
        };
        let mut scores: Vec<f64> = scored.iter().map(|s| s.0).collect();
        for o in 0..scores.len() {
            if let Some(e) = repeats[o] {
                scores[o] = scores[e];
            }
        }
        // A repeat ties the option it repeats, and so never wins.
        let best = (1..scores.len()).fold(0, |best, i| if scores[i] < scores[best] { i } else { best });
        let [kl, kr] = match (best, known) {
            (0, Some(k)) => k.halves,
            _ => scored.swap_remove(best).1.map_or([None, None], |sides| sides.map(|s| s.known)),
        };
        match best.checked_sub(1) {
            None => {
                let (left, right) = partition_by(self.keys, &set, &vsah.left);
                ((left, kl), (right, kr), vsah.split(ctx))
            }
            Some(c) => {
                let (left, right) = partition(self.keys, &set, &cands[c]);
                ((left, kl), (right, kr), cands[c].split())
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

/// A trial node: its objects, their box and their centroids' spread.
type TrialSet = (Vec<u32>, Aabb, Spread);

/// A trial scored: the expected cost of its subtree, as a walk adds it,
/// and what it learnt of its root.
struct Scored {
    total: f64,
    known: Option<Box<Known>>,
}

/// A node of a trial whose subtree the walk is in.
struct Open {
    depth: u32,
    /// Its objects.
    len: usize,
    /// Its subtree's cost so far, added in the order a walk from it would
    /// add it (its own walk's total, bit for bit, once finished).
    sum: f64,
    /// Its halves, scored, as they finish.
    halves: [Option<Scored>; 2],
}

impl Open {
    /// The node's subtree scored, its own walk finished.
    fn finish(self) -> Scored {
        let known = match self.halves {
            [Some(l), Some(r)] if self.len >= KNOWN_MIN => {
                Some(Box::new(Known { vsah_score: l.total + r.total, halves: [l.known, r.known] }))
            }
            _ => None,
        };
        Scored { total: self.sum, known }
    }
}

/// A trial walk in progress: the open nodes from its root down to the node
/// visited last, [`KNOWN_DEPTH`] levels at most. Each node's cost is added
/// to the sum of every open node above it, so that each subtree's sum is
/// the total its own walk would give (a walk's order depends on sizes
/// only): what [`Known`] records.
struct TrialOut {
    path: Vec<Open>,
}

impl TrialOut {
    /// Adds `cost` to the sums of the open nodes.
    fn add(&mut self, cost: f64) {
        for open in &mut self.path {
            open.sum += cost;
        }
    }

    /// Closes the open nodes at `depth` or deeper, the root excepted: their
    /// subtrees are walked, and each hands its score to its parent.
    fn close_to(&mut self, depth: u32) {
        while self.path.len() > 1 && self.path.last().is_some_and(|o| o.depth >= depth) {
            let Some(open) = self.path.pop() else { break };
            let scored = open.finish();
            if let Some(parent) = self.path.last_mut() {
                let halves = &mut parent.halves;
                halves[usize::from(halves[0].is_some())] = Some(scored);
            }
        }
    }

    /// The walk's root scored, its walk done.
    fn finish(mut self) -> Scored {
        self.close_to(0);
        self.path.pop().map_or(Scored { total: 0.0, known: None }, Open::finish)
    }
}

impl Walk for Trial<'_> {
    type Set = TrialSet;
    type Out = TrialOut;
    /// The node is open (not deeper than [`KNOWN_DEPTH`] below the root).
    type Mark = bool;

    fn len(&self, set: &TrialSet) -> usize {
        set.0.len()
    }

    fn start(&self) -> TrialOut {
        TrialOut { path: Vec::new() }
    }

    fn visit(
        &self,
        (set, aabb, spread): TrialSet,
        depth: u32,
        out: &mut TrialOut,
    ) -> Option<(TrialSet, TrialSet, bool)> {
        out.close_to(depth);
        // A sum starts at 0 and takes the node's own cost first, as a walk's
        // total does. Deeper nodes are not known, but add to the sums above.
        let open = out.path.len() <= KNOWN_DEPTH;
        if open {
            out.path.push(Open { depth, len: set.len(), sum: 0.0, halves: [None, None] });
        }
        let leaf = self.ctx.leaf.fits(&set);
        out.add(self.model.node_cost(&aabb, leaf));
        if leaf {
            return None;
        }
        self.ctx.meter.worked(set.len());
        let h = self.vsah.halves_within(set, &aabb, &spread);
        let ([l, r], [sl, sr]) = (h.boxes, h.spreads);
        Some(((h.left, l, sl), (h.right, r, sr), open))
    }

    fn right_begins(&self, _out: &mut TrialOut, _open: bool) {}

    fn splice(&self, out: &mut TrialOut, open: bool, left: TrialOut, right: TrialOut) {
        let (left, right) = (left.finish(), right.finish());
        out.add(left.total + right.total);
        // The node just visited, whose halves were walked apart.
        if let Some(node) = out.path.last_mut().filter(|_| open) {
            node.halves = [Some(left), Some(right)];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bulk::TieBreak;
    use crate::bulk::leaf::Leaf;
    use crate::bulk::progress::Meter;
    use crate::bulk::walk::PAR_MIN;

    /// The trial of all of `boxes`, checked: its total against a plain
    /// preorder sum of the `vsah` tree's node costs (when no halves are big
    /// enough to be walked apart), and every [`Known`] it holds, at any
    /// depth, against fresh trials of that node's halves, bit for bit.
    /// Returns how many were checked, and the `vsah` tree's depth.
    fn check_trial(boxes: &[Aabb]) -> (usize, usize) {
        let n = boxes.len();
        let ids: Vec<u32> = (0..n as u32).collect();
        let ctx = Ctx {
            boxes,
            ids: &ids,
            leaf: Leaf::Objects(4),
            rate: 0.2,
            tie: TieBreak::FirstFound,
            meter: Meter::new(&|_| {}, n, 0.0),
        };
        let keys = Keys::new(boxes, &ids);
        let refine = Refine::new(&ctx, &keys, CostModel::of_boxes(boxes, crate::bulk::QueryExtent::Auto));
        let all = ids.clone();
        let trial = refine.score(&all, ctx.aabb_of(&all), Spread::of(boxes, &all));
        // The plain sum, and the depth, by an explicit stack.
        let (mut sum, mut depth) = (0.0, 0);
        let mut stack = vec![(all.clone(), 1)];
        while let Some((set, d)) = stack.pop() {
            let aabb = ctx.aabb_of(&set);
            let leaf = ctx.leaf.fits(&set);
            sum += refine.model.node_cost(&aabb, leaf);
            depth = depth.max(d);
            if !leaf {
                let h = refine.vsah.halves(set, &aabb);
                stack.push((h.right, d + 1));
                stack.push((h.left, d + 1));
            }
        }
        if n < 2 * PAR_MIN {
            assert_eq!(trial.total.to_bits(), sum.to_bits());
        }
        let mut checked = 0;
        let mut pending = vec![(all, trial.known)];
        while let Some((set, known)) = pending.pop() {
            let Some(k) = known else { continue };
            let h = refine.vsah.halves(set.clone(), &ctx.aabb_of(&set));
            let [l, r] = h.boxes;
            let [sl, sr] = h.spreads;
            let fresh = refine.score(&h.left, l, sl).total + refine.score(&h.right, r, sr).total;
            assert_eq!(k.vsah_score.to_bits(), fresh.to_bits(), "a node of {} objects", set.len());
            checked += 1;
            let [kl, kr] = k.halves;
            pending.push((h.left, kl));
            pending.push((h.right, kr));
        }
        (checked, depth)
    }

    #[test]
    fn what_a_trial_learns_of_its_nodes_is_their_vsah_scores_bit_for_bit() {
        // A grid of small boxes jittered by a fixed hash: big enough that the
        // trial walks the root's halves, and theirs, apart, and below
        // that in one sum.
        let n = 6 * PAR_MIN;
        let boxes: Vec<Aabb> = (0..n)
            .map(|i| {
                let h = digest(&[i as u32]).1;
                let (x, y, z) = ((i % 40) as f64, (i / 40 % 40) as f64, (i / 1600) as f64);
                let d = (h % 1000) as f64 / 2000.0;
                Aabb::from_array([x + d, y, z + d, x + d + 0.7, y + 0.3 + d, z + 0.9])
            })
            .collect();
        let (checked, _) = check_trial(&boxes);
        // Every node of at least KNOWN_MIN objects: about 2 n / KNOWN_MIN.
        assert!(checked > n / KNOWN_MIN, "{checked} nodes known");
    }

    #[test]
    fn a_trial_deeper_than_it_keeps_sums_for_still_adds_up_and_knows_its_top() {
        // Boxes ever further apart: each cut peels the farthest few off, so
        // the tree is far deeper than KNOWN_DEPTH.
        let boxes: Vec<Aabb> = (0..400)
            .map(|i| {
                let x = 3f64.powi(i);
                Aabb::from_array([x, 0.0, 0.0, x + 1.0, 1.0, 1.0])
            })
            .collect();
        let (checked, depth) = check_trial(&boxes);
        assert!(depth > 2 * KNOWN_DEPTH, "depth {depth}");
        assert!(checked >= KNOWN_DEPTH - 1, "{checked} nodes known");
    }

    #[test]
    fn an_option_repeats_the_first_with_the_same_parts_in_either_order() {
        let boxes = vec![Aabb::from_array([0.0, 0.0, 0.0, 1.0, 1.0, 1.0]); 6];
        let ids: Vec<u32> = (0..6).collect();
        let keys = Keys::new(&boxes, &ids);
        let node = [0, 1, 2, 3, 4, 5];
        let options: [(&[u32], &[u32]); 5] = [
            (&[0, 1, 2], &[3, 4, 5]),
            (&[2, 0, 1], &[5, 3, 4]), // the same parts, reordered
            (&[0, 1, 3], &[2, 4, 5]), // as many objects, others
            (&[4, 5, 3], &[1, 2, 0]), // option 0 mirrored
            (&[0, 1], &[2, 3, 4, 5]),
        ];
        assert_eq!(repeats(&keys, &node, &options), [None, Some(0), None, Some(0), None]);
    }
}
