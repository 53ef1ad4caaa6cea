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
//! order fixed by the subtrees alone (a node's cost plus the sum of its
//! halves' scores), so the tree is the same on any number of threads.
//! Options that divide the node alike (the two orders of an axis often
//! pick the same cut, and a cut can match the `vsah` one) are scored once:
//! a score depends only on the two sides' objects. For the same reason no
//! trial regrows a set of [`MEMO_MIN`] objects or more that an earlier
//! trial grew: the [`Memo`] keeps their scores. That covers a node's own
//! `vsah` option, whose halves its parent's trial grew, and beyond it a
//! third of what the trials grew on ship 10^5 and 10^6 (objects in nodes
//! divided, counted) were sets grown before.
//!
//! Measured and not kept (docs/build-methods.md, "Tried and dropped"): a
//! cost mixing several query sizes, page-aligned cuts as extra options for
//! fuller leaves, one level of look-ahead below each option, and scoring a
//! large node's options on a sample of its objects, which misses how full
//! the leaves come out.

use std::collections::HashMap;
use std::sync::atomic::{AtomicU32, AtomicU64, AtomicUsize, Ordering::Relaxed};
use std::sync::{Arc, Mutex, PoisonError};

use rayon::prelude::*;

use super::Split;
use super::cost::CostModel;
use super::cut::{Keys, SixLists, candidates, partition, partition_by, same_objects};
use super::sah::{Heuristic, Sah, Spread};
use super::splitter::{Ctx, Splitter};
use super::walk::PAR_MIN;
use crate::geom::Aabb;
use crate::rng::Rng;

/// Below this many objects a node's options are scored on one thread.
const PAR_OPTIONS_MIN: usize = 512;

/// The [`Memo`] keeps the trial nodes of at least this many objects: a
/// smaller subtree costs about what its key does to look up, and the memo
/// stays small (73,000 sets on ship 10^5).
const MEMO_MIN: usize = 64;

/// Shards of the [`Memo`].
const MEMO_SHARDS: usize = 16;

/// The refining splitter.
pub(crate) struct Refine<'a> {
    ctx: &'a Ctx<'a>,
    keys: &'a Keys<'a>,
    vsah: Sah<'a>,
    model: CostModel,
    memo: Memo,
}

impl<'a> Refine<'a> {
    pub(crate) fn new(ctx: &'a Ctx<'a>, keys: &'a Keys<'a>, model: CostModel) -> Refine<'a> {
        Refine {
            ctx,
            keys,
            vsah: Sah::new(ctx, Heuristic::Volume),
            model,
            memo: Memo::new(ctx.boxes.len(), SWEEP_MIN),
        }
    }
}

/// For each of `options` (two parts of the node of objects `node`), the
/// first earlier option with the same parts, in either order: its score is
/// the same (a sum of two scores is the same either way round). Parts are
/// compared where their [`Memo`] keys match.
fn repeats(keys: &Keys<'_>, memo: &Memo, node: &[u32], options: &[(&[u32], &[u32])]) -> Vec<Option<usize>> {
    let part_keys: Vec<_> = options.iter().map(|(a, b)| (memo.key(a), memo.key(b))).collect();
    (0..options.len())
        .map(|o| {
            let (a, _) = options[o];
            (0..o).find(|&e| {
                let (c, d) = options[e];
                (part_keys[e].0 == part_keys[o].0 && same_objects(keys, node, c, a))
                    || (part_keys[e].1 == part_keys[o].0 && same_objects(keys, node, d, a))
            })
        })
        .collect()
}

/// The set a trial node holds, as the [`Memo`] knows it: its size and two
/// order-free sums of 64-bit digests of its objects. The memo looks a set
/// up by its sums alone: two different sets share them with a chance of
/// about 2^-128 per pair, whatever their sizes, and a shared key could only
/// lend one set the other's score, which makes a worse tree, never a wrong
/// file. Sums, so that a half's key is its parent's less its sibling's.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct SetKey {
    len: usize,
    sums: [u64; 2],
}

impl SetKey {
    /// The key of what is left of `self`'s set when `part`'s is taken out.
    fn less(self, part: SetKey) -> SetKey {
        SetKey {
            len: self.len - part.len,
            sums: [self.sums[0].wrapping_sub(part.sums[0]), self.sums[1].wrapping_sub(part.sums[1])],
        }
    }
}

impl Splitter for Refine<'_> {
    type Set = Scoped;

    fn objects<'s>(&self, set: &'s Scoped) -> &'s [u32] {
        &set.lists[0]
    }

    fn aabb(&self, _ctx: &Ctx<'_>, set: &Scoped) -> Aabb {
        self.keys.aabb(&set.lists)
    }

    fn split(&self, set: Scoped, aabb: &Aabb) -> (Scoped, Scoped, Split) {
        let ctx = self.ctx;
        let scope = self.memo.scope(set.scope);
        let (node, set) = (scope.node, set.lists);
        let n = set[0].len();
        let cands = candidates(self.keys, &set, ctx.rate, ctx.tie);
        let vsah = self.vsah.halves(set[0].clone(), aabb);
        // Option 0 is the vsah cut, options 1..=6 the candidates.
        let mut options: Vec<(&[u32], &[u32])> = vec![(&vsah.left, &vsah.right)];
        options.extend(cands.iter().map(|c| set[c.order].split_at(c.cut_index + 1)));
        let repeats = repeats(self.keys, &self.memo, &set[0], &options);
        // Each option's score; none for a repeat.
        let score = |o: usize| -> f64 {
            if repeats[o].is_some() {
                return f64::NAN;
            }
            let (a, b) = options[o];
            let ([l, r], [sl, sr]) = if o == 0 {
                (vsah.boxes, vsah.spreads)
            } else {
                ([ctx.aabb_of(a), ctx.aabb_of(b)], [Spread::of(ctx.boxes, a), Spread::of(ctx.boxes, b)])
            };
            self.score(a, l, sl, node) + self.score(b, r, sr, node)
        };
        let mut scores: Vec<f64> = if n >= PAR_OPTIONS_MIN {
            (0..options.len()).into_par_iter().map(score).collect()
        } else {
            (0..options.len()).map(score).collect()
        };
        for o in 0..scores.len() {
            if let Some(e) = repeats[o] {
                scores[o] = scores[e];
            }
        }
        // A repeat ties the option it repeats, and so never wins.
        let best = (1..scores.len()).fold(0, |best, i| if scores[i] < scores[best] { i } else { best });
        let ((left, right), split) = match best.checked_sub(1) {
            None => (partition_by(self.keys, &set, &vsah.left), vsah.split(ctx)),
            Some(c) => (partition(self.keys, &set, &cands[c]), cands[c].split()),
        };
        let scoped = |lists| Scoped { lists, scope: Some(Arc::clone(&scope)) };
        (scoped(left), scoped(right), split)
    }
}

/// The scores of the trial nodes of at least [`MEMO_MIN`] objects, by set
/// (a score depends on the set alone), each with the number of the node
/// whose trials grew it. Split in shards so that threads seldom wait on
/// each other.
///
/// A trial set lies within the node that grew it, so once that node's
/// subtree is built no later trial can meet the set again. Each time the
/// memo has doubled since it last did, it drops the entries of such nodes:
/// it holds about the entries of the nodes on the paths being built, not
/// of every node, which at 10^7 objects is hundreds of megabytes less. A
/// dropped entry is one no trial would have looked up, so the tree is the
/// same.
struct Memo {
    shards: Vec<Mutex<HashMap<[u64; 2], Entry>>>,
    /// The nodes whose subtree is built, a bit each by node number.
    built: Arc<Built>,
    /// The next node's number.
    next_node: AtomicU32,
    /// Entries inserted since the last sweep plus those it kept: about the
    /// entries held (inserts while a sweep runs may be missed).
    held: AtomicUsize,
    /// The least `held` at which a sweep starts.
    sweep_min: usize,
    /// The `held` at which the next sweep starts.
    sweep_at: AtomicUsize,
    /// Taken by the thread that sweeps; others go on meanwhile.
    sweeping: Mutex<()>,
}

/// A memo entry: a trial set's score and the node whose trials grew it.
#[derive(Debug, Clone, Copy)]
struct Entry {
    score: f64,
    node: u32,
}

/// The memo sweeps no sooner than at this many entries.
const SWEEP_MIN: usize = 1 << 16;

impl Memo {
    /// A memo for a build of `objects` objects, which divides at most
    /// `objects - 1` nodes, that sweeps no sooner than at `sweep_min`
    /// entries.
    fn new(objects: usize, sweep_min: usize) -> Memo {
        Memo {
            shards: (0..MEMO_SHARDS).map(|_| Mutex::new(HashMap::new())).collect(),
            built: Arc::new(Built((0..objects.div_ceil(64)).map(|_| AtomicU64::new(0)).collect())),
            next_node: AtomicU32::new(0),
            held: AtomicUsize::new(0),
            sweep_min,
            sweep_at: AtomicUsize::new(sweep_min),
            sweeping: Mutex::new(()),
        }
    }

    /// The key of `objects`: the sums of each object's SplitMix64 output
    /// (its digest) and of SplitMix64's output for the digest as seed, so
    /// the two sums are independent. Digests are computed, not kept: a
    /// table of them would be 8 bytes an object.
    fn key(&self, objects: &[u32]) -> SetKey {
        let sums = objects.iter().fold([0u64; 2], |[a, b], &j| {
            let d = Rng::new(u64::from(j)).next_u64();
            [a.wrapping_add(d), b.wrapping_add(Rng::new(d).next_u64())]
        });
        SetKey { len: objects.len(), sums }
    }

    /// The scope of a node about to be divided, inside `parent`'s.
    fn scope(&self, parent: Option<Arc<Scope>>) -> Arc<Scope> {
        Arc::new(Scope { node: self.next_node.fetch_add(1, Relaxed), built: Arc::clone(&self.built), parent })
    }

    fn shard(&self, key: &SetKey) -> &Mutex<HashMap<[u64; 2], Entry>> {
        &self.shards[(key.sums[0] % MEMO_SHARDS as u64) as usize]
    }

    fn get(&self, key: &SetKey) -> Option<f64> {
        // A poisoned shard only means a thread panicked while inserting a
        // plain number: the map is still whole.
        self.shard(key).lock().unwrap_or_else(PoisonError::into_inner).get(&key.sums).map(|e| e.score)
    }

    /// Keeps `score` for `key`'s set, grown by node `node`'s trials.
    fn insert(&self, key: SetKey, score: f64, node: u32) {
        self.shard(&key)
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .insert(key.sums, Entry { score, node });
        if self.held.fetch_add(1, Relaxed) + 1 >= self.sweep_at.load(Relaxed) {
            self.sweep();
        }
    }

    /// Drops the entries of nodes whose subtree is built, a shard at a
    /// time, and sweeps next when the memo has doubled.
    fn sweep(&self) {
        let Ok(_sweeping) = self.sweeping.try_lock() else { return };
        let kept: usize = self
            .shards
            .iter()
            .map(|shard| {
                let mut map = shard.lock().unwrap_or_else(PoisonError::into_inner);
                map.retain(|_, e| !self.built.has(e.node));
                map.len()
            })
            .sum();
        self.held.store(kept, Relaxed);
        self.sweep_at.store((2 * kept).max(self.sweep_min), Relaxed);
    }
}

/// One bit per node, set once its subtree is built.
struct Built(Vec<AtomicU64>);

impl Built {
    fn set(&self, node: u32) {
        if let Some(word) = self.0.get(node as usize / 64) {
            word.fetch_or(1 << (node % 64), Relaxed);
        }
    }

    fn has(&self, node: u32) -> bool {
        self.0.get(node as usize / 64).is_some_and(|w| w.load(Relaxed) & (1 << (node % 64)) != 0)
    }
}

/// A node being divided, held by its children's sets and scopes: when the
/// last of them goes, its subtree is built and the memo may drop the
/// entries its trials grew.
struct Scope {
    node: u32,
    built: Arc<Built>,
    parent: Option<Arc<Scope>>,
}

impl Drop for Scope {
    fn drop(&mut self) {
        self.built.set(self.node);
        // Ancestors whose subtrees end here too are let go in a loop, not
        // by nested drops: a tree can be as deep as it has objects.
        let mut parent = self.parent.take();
        while let Some(scope) = parent {
            parent = Arc::into_inner(scope).and_then(|mut s| s.parent.take());
        }
    }
}

/// A node's objects in the six orders, and the scope of the node that
/// divided them off (none at the root).
pub(crate) struct Scoped {
    lists: SixLists,
    scope: Option<Arc<Scope>>,
}

impl Scoped {
    /// The root's set.
    pub(crate) fn root(lists: SixLists) -> Scoped {
        Scoped { lists, scope: None }
    }
}

/// A trial node: its objects, their box, their centroids' spread, and its
/// key when it has at least [`MEMO_MIN`] objects.
type TrialSet = (Vec<u32>, Aabb, Spread, Option<SetKey>);

/// A step of a trial: grow a node, or add a divided node's cost to its
/// halves' scores (the last two on the stack of scores).
enum Step {
    Grow(TrialSet),
    Sum { cost: f64, key: Option<SetKey> },
}

impl Refine<'_> {
    /// The expected cost of the `vsah` subtree of `set`, whose box is
    /// `aabb` and centroid spread `spread`: a node's cost plus the sum of
    /// its halves' scores, `cost + (left + right)`, so that a subtree's
    /// score is the same wherever it is grown, and the [`Memo`] can keep it
    /// (as grown by node `node`).
    fn score(&self, set: &[u32], aabb: Aabb, spread: Spread, node: u32) -> f64 {
        let key = (set.len() >= MEMO_MIN).then(|| self.memo.key(set));
        self.trial((set.to_vec(), aabb, spread, key), node)
    }

    /// [`Refine::score`] of a trial node. The steps wait on a heap stack,
    /// since a `vsah` subtree can be as deep as it has objects; halves of
    /// at least [`PAR_MIN`] objects each are scored on rayon.
    fn trial(&self, root: TrialSet, node: u32) -> f64 {
        let (ctx, model) = (self.ctx, &self.model);
        let mut steps = vec![Step::Grow(root)];
        let mut scores: Vec<f64> = Vec::new();
        while let Some(step) = steps.pop() {
            let (set, aabb, spread, key) = match step {
                Step::Grow(node) => node,
                Step::Sum { cost, key } => {
                    let right = scores.pop().unwrap_or(0.0);
                    let left = scores.pop().unwrap_or(0.0);
                    scores.push(self.summed(cost, key, left, right, node));
                    continue;
                }
            };
            let leaf = ctx.leaf.fits(&set);
            let cost = model.node_cost(&aabb, leaf);
            if leaf {
                scores.push(cost);
                continue;
            }
            if let Some(known) = key.as_ref().and_then(|k| self.memo.get(k)) {
                scores.push(known);
                continue;
            }
            ctx.meter.worked(set.len());
            let h = self.vsah.halves_within(set, &aabb, &spread);
            let ([l, r], [sl, sr]) = (h.boxes, h.spreads);
            // The halves' keys: the left's summed, the right's the rest.
            let (kl, kr) = match key {
                Some(key) if h.left.len().max(h.right.len()) >= MEMO_MIN => {
                    let kl = self.memo.key(&h.left);
                    let kr = key.less(kl);
                    ((kl.len >= MEMO_MIN).then_some(kl), (kr.len >= MEMO_MIN).then_some(kr))
                }
                _ => (None, None),
            };
            if h.left.len().min(h.right.len()) >= PAR_MIN {
                let (left, right) = rayon::join(
                    || self.trial((h.left, l, sl, kl), node),
                    || self.trial((h.right, r, sr, kr), node),
                );
                scores.push(self.summed(cost, key, left, right, node));
            } else {
                steps.push(Step::Sum { cost, key });
                steps.push(Step::Grow((h.right, r, sr, kr)));
                steps.push(Step::Grow((h.left, l, sl, kl)));
            }
        }
        scores.pop().unwrap_or(0.0)
    }

    /// A divided node's score from its cost and its halves' scores, kept
    /// in the memo when the node has a key.
    fn summed(&self, cost: f64, key: Option<SetKey>, left: f64, right: f64, node: u32) -> f64 {
        let score = cost + (left + right);
        if let Some(key) = key {
            self.memo.insert(key, score, node);
        }
        score
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bulk::TieBreak;
    use crate::bulk::driver::grow;
    use crate::bulk::hierarchy::Node;
    use crate::bulk::leaf::Leaf;
    use crate::bulk::progress::Meter;

    fn ctx_of<'a>(boxes: &'a [Aabb], ids: &'a [u32]) -> Ctx<'a> {
        Ctx {
            boxes,
            ids,
            leaf: Leaf::Objects(4),
            rate: 0.2,
            tie: TieBreak::FirstFound,
            meter: Meter::new(&|_| {}, boxes.len(), 0.0),
        }
    }

    /// The score of the `vsah` subtree of `set` by plain recursion, with no
    /// memo: a node's cost plus the sum of its halves'. Also returns every
    /// node of at least [`MEMO_MIN`] objects, with its score.
    fn plain(refine: &Refine<'_>, set: Vec<u32>, found: &mut Vec<(Vec<u32>, f64)>) -> f64 {
        let ctx = refine.ctx;
        let aabb = ctx.aabb_of(&set);
        let leaf = ctx.leaf.fits(&set);
        let cost = refine.model.node_cost(&aabb, leaf);
        if leaf {
            return cost;
        }
        let h = refine.vsah.halves(set.clone(), &aabb);
        let score = cost + (plain(refine, h.left, found) + plain(refine, h.right, found));
        if set.len() >= MEMO_MIN {
            found.push((set, score));
        }
        score
    }

    /// A trial of all of `boxes` against [`plain`], bit for bit; then the
    /// memo holds every node [`plain`] met, with the same score, and a
    /// second trial is the same. Returns how many nodes were checked.
    fn check_trial(boxes: &[Aabb]) -> usize {
        let ids: Vec<u32> = (0..boxes.len() as u32).collect();
        let ctx = ctx_of(boxes, &ids);
        let keys = Keys::new(boxes, &ids);
        let refine = Refine::new(&ctx, &keys, CostModel::of_boxes(boxes, crate::bulk::QueryExtent::Auto));
        let mut found = Vec::new();
        let expected = plain(&refine, ids.clone(), &mut found);
        let trial = refine.score(&ids, ctx.aabb_of(&ids), Spread::of(boxes, &ids), 0);
        assert_eq!(trial.to_bits(), expected.to_bits());
        for (set, score) in &found {
            assert_eq!(
                refine.memo.get(&refine.memo.key(set)).map(f64::to_bits),
                Some(score.to_bits()),
                "{} objects",
                set.len()
            );
        }
        let again = refine.score(&ids, ctx.aabb_of(&ids), Spread::of(boxes, &ids), 0);
        assert_eq!(again.to_bits(), expected.to_bits());
        found.len()
    }

    /// `n` small boxes on a grid 40 wide, jittered by a hash of `seed`
    /// and each box's index.
    fn jittered_grid(n: usize, seed: u64) -> Vec<Aabb> {
        (0..n)
            .map(|i| {
                let h = Rng::derive(seed, i as u64).next_u64();
                let (x, y, z) = ((i % 40) as f64, (i / 40 % 40) as f64, (i / 1600) as f64);
                let d = (h % 1000) as f64 / 2000.0;
                Aabb::from_array([x + d, y, z + d, x + d + 0.7, y + 0.3 + d, z + 0.9])
            })
            .collect()
    }

    #[test]
    fn a_trial_scores_a_node_as_its_cost_plus_its_halves_and_the_memo_keeps_them() {
        // Big enough that the trial scores the root's halves, and theirs, on
        // rayon.
        let n = 6 * PAR_MIN;
        let boxes = jittered_grid(n, 0);
        // Every node of at least MEMO_MIN objects: about 2 n / MEMO_MIN.
        let checked = check_trial(&boxes);
        assert!(checked > n / MEMO_MIN, "{checked} nodes checked");
    }

    #[test]
    fn a_trial_as_deep_as_it_has_objects_adds_up() {
        // Boxes ever further apart: each cut peels the farthest four off (a
        // leaf), so the tree is a quarter as deep as it has objects, and a
        // recursive trial would need a frame per level.
        let boxes: Vec<Aabb> = (0..400)
            .map(|i| {
                let x = 3f64.powi(i);
                Aabb::from_array([x, 0.0, 0.0, x + 1.0, 1.0, 1.0])
            })
            .collect();
        let checked = check_trial(&boxes);
        // The nodes of at least MEMO_MIN objects: one per level down to them.
        assert!(checked >= (400 - MEMO_MIN) / 4, "{checked}");
    }

    /// A refine build of `boxes` on one thread, whose memo sweeps from
    /// `sweep_min` entries: its nodes, the object visits it counted, and
    /// the entries a last sweep leaves once the build is done.
    fn refine_build(boxes: &[Aabb], sweep_min: usize) -> (Vec<Node>, u64, usize) {
        let ids: Vec<u32> = (0..boxes.len() as u32).collect();
        let work = AtomicU64::new(0);
        let report = |p: crate::bulk::BuildProgress| work.store(p.work_done, Relaxed);
        let ctx = Ctx { meter: Meter::new(&report, boxes.len(), 0.0), ..ctx_of(boxes, &ids) };
        let keys = Keys::new(boxes, &ids);
        let model = CostModel::of_boxes(boxes, crate::bulk::QueryExtent::Auto);
        let refine = Refine { memo: Memo::new(boxes.len(), sweep_min), ..Refine::new(&ctx, &keys, model) };
        // On one thread, so that which trial grows a set first, and so the
        // visits counted, do not depend on timing.
        let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        let nodes = pool.install(|| grow(&ctx, &refine, Scoped::root(keys.sorted_lists())));
        ctx.meter.finish();
        refine.memo.sweep();
        let left = refine.memo.shards.iter().map(|s| s.lock().unwrap().len()).sum();
        (nodes, work.load(Relaxed), left)
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(12))]

        /// The memo drops only entries that no trial looks up again: a
        /// build that sweeps at every doubling from one entry makes the
        /// same tree with the same visits as one that never sweeps, and
        /// once the build is done every node's subtree is built, so a last
        /// sweep leaves nothing.
        #[test]
        fn sweeping_drops_only_entries_of_built_subtrees(n in 300usize..3000, seed in 0u64..1000) {
            let boxes = jittered_grid(n, seed);
            let (kept, kept_work, _) = refine_build(&boxes, usize::MAX);
            let (swept, swept_work, left) = refine_build(&boxes, 1);
            proptest::prop_assert_eq!(kept, swept);
            proptest::prop_assert_eq!(kept_work, swept_work);
            proptest::prop_assert_eq!(left, 0);
        }
    }

    #[test]
    fn a_node_is_built_when_its_last_child_goes() {
        let memo = Memo::new(8, SWEEP_MIN);
        let root = memo.scope(None);
        let (left, right) = (memo.scope(Some(Arc::clone(&root))), memo.scope(Some(Arc::clone(&root))));
        let (r, l, rr) = (root.node, left.node, right.node);
        drop(root);
        assert!(!memo.built.has(r), "the children still hold the root");
        drop(left);
        assert!(memo.built.has(l) && !memo.built.has(r));
        drop(right);
        assert!(memo.built.has(rr) && memo.built.has(r));
    }

    #[test]
    fn a_chain_of_scopes_as_deep_as_a_tree_can_be_lets_go_in_a_loop() {
        // Nested drops this deep would overflow a test thread's stack.
        let depth = 400_000;
        let memo = Memo::new(depth, SWEEP_MIN);
        let mut scope = memo.scope(None);
        for _ in 1..depth {
            scope = memo.scope(Some(scope));
        }
        drop(scope);
        assert!((0..depth as u32).all(|node| memo.built.has(node)));
    }

    #[test]
    fn a_sweep_keeps_the_entries_of_nodes_being_built() {
        let memo = Memo::new(8, SWEEP_MIN);
        let (building, built) = (memo.scope(None), memo.scope(None));
        let (a, b) = (memo.key(&[1, 2]), memo.key(&[3, 4]));
        memo.insert(a, 1.5, building.node);
        memo.insert(b, 2.5, built.node);
        drop(built);
        memo.sweep();
        assert_eq!((memo.get(&a), memo.get(&b)), (Some(1.5), None));
        assert_eq!(memo.held.load(Relaxed), 1);
    }

    #[test]
    fn the_memo_keys_a_set_in_any_order_tells_sets_apart_and_takes_a_part_out() {
        let memo = Memo::new(8, SWEEP_MIN);
        let key = |objects: &[u32]| memo.key(objects);
        assert_eq!(key(&[3, 1, 2]), key(&[1, 2, 3]));
        assert_ne!(key(&[1, 2, 3]), key(&[1, 2, 4]));
        assert_ne!(key(&[1, 2]), key(&[1, 2, 0]));
        assert_eq!(key(&[7, 1, 4, 2]).less(key(&[4, 7])), key(&[1, 2]));
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
        assert_eq!(
            repeats(&keys, &Memo::new(6, SWEEP_MIN), &node, &options),
            [None, Some(0), None, Some(0), None]
        );
    }
}
