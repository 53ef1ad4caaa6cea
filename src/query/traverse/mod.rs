//! The one traversal every query runs (rstar's selection iterator, with the
//! MKtree's multiresolution decisions, paper §1.5), as a lazy iterator.
//!
//! From the root, each child is tested against the query through its box as
//! the parent stores it, so a pruned child's block is never read; a child
//! whose box the query holds answers all its objects without further tests.
//! At a leaf each object is decided by the coarsest bound that can: its box
//! rules it out, or holds it, or has a face the query holds (the box is
//! tight, so that face touches the object); then its finest stored voxel
//! bound up to level k rules it out or holds a surface cell inside the query.
//! Only objects still undecided at k = M have their geometry read.
//!
//! The work is a queue of steps. Without a budget it is a stack (depth
//! first). With a block budget it is a priority queue: the step that settles
//! the most objects per block it reads goes first; a step that would pass
//! the budget is set aside, and what is left is the answer's `maybe`
//! (objects not refined) and `unexplored` (subtrees not read). A best-first
//! query (`rank.rs`: nearest objects, ray hits) orders the queue by a lower
//! bound of the distance (its boxes'), and an object found at its exact
//! distance waits in the queue until nothing nearer can come: hits come in
//! order of distance, ties by id.
//!
//! A query that takes stand-ins (the view, [`Selection::tolerance`]) stops
//! where a node's box, or an object's finest stored bound, is close enough:
//! the visitor is shown the node (`stand_in`) or the object at that level,
//! and nothing below is read. With a budget its queue refines the largest
//! stand-in error first, and what the budget sets aside is shown as stand-ins
//! too, so the stand-ins and objects shown cover all the query meets.
//!
//! [`Select`] runs the queue on demand: each `next` runs steps until an
//! object is decided, so a caller that stops early has read only the blocks
//! its hits needed. `traverse`, and every query built on it, drain the same
//! iterator.

use std::collections::{BinaryHeap, VecDeque};
use std::sync::Arc;
use std::time::Instant;

mod ahead;
mod step;

use super::QueryError;
use super::answer::{Hit, ObjectLevel, Proof, QueryAnswer, QueryOptions, TraverseStats, levels};
use super::rank::Rank;
use super::select::Selection;
use super::visit::{NodeName, Seen, Visitor};
use crate::geom::Aabb;
use crate::lod::Voxels;
use crate::scene::{Key, Mesh, ObjectId};
use crate::store::format::geometry;
use crate::store::format::node::{BoundView, LeafView, NodeView, RecordRef};
use crate::store::format::quant::QuantBox;
use crate::store::{Block, BlockCache, ReadStats, StorageError};
use crate::tree::{NodeRef, ReadTransaction, Reads, view};

enum Step {
    /// A child in another block, not read yet.
    Unread { at: RecordRef, frame: Aabb, inside: bool, estimate: f64, name: NodeName },
    /// A record in hand.
    Node { block: Arc<Block>, offset: u32, frame: Aabb, inside: bool, name: NodeName },
    /// A part whose geometry decides its object: leaf `offset` of `block`,
    /// entry `index` (box `part`, its object's `whole`), which passed bounds
    /// up to `level`, the finest of which is within `eps` mm of it.
    Exact {
        block: Arc<Block>,
        offset: u32,
        index: usize,
        level: u8,
        eps: f64,
        part: Aabb,
        whole: Aabb,
        key: Key,
    },
    /// Best first: an object at its exact distance, yielded when nothing
    /// left in the queue can be nearer.
    Found { object: u32, aabb: Aabb, key: Key, distance: f64 },
    /// Stand-ins with a budget: a record in hand shown by its group bound
    /// b(S_n,`level`), within `eps` mm of its objects, until it is refined.
    Group { block: Arc<Block>, offset: u32, frame: Aabb, name: NodeName, level: u8, eps: f64, voxels: Voxels },
}

/// A step in the queue: the greatest (`priority`, then `tie`) goes first.
struct Queued {
    priority: f64,
    tie: u64,
    step: Step,
}

impl PartialEq for Queued {
    fn eq(&self, o: &Queued) -> bool {
        self.cmp(o) == std::cmp::Ordering::Equal
    }
}
impl Eq for Queued {}
impl PartialOrd for Queued {
    fn partial_cmp(&self, o: &Queued) -> Option<std::cmp::Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for Queued {
    fn cmp(&self, o: &Queued) -> std::cmp::Ordering {
        self.priority.total_cmp(&o.priority).then(self.tie.cmp(&o.tie))
    }
}

/// The finest bound of `target` at a level <= k among `bounds`.
fn finest<'a>(bounds: impl Iterator<Item = BoundView<'a>>, target: u16, k: u8) -> Option<BoundView<'a>> {
    bounds.filter(|b| b.target == target && b.level <= k).max_by_key(|b| b.level)
}

/// The box of the object of entries `parts` of `leaf`: the union of the
/// parts' stored boxes (one that does not decode is reported where it is
/// tested).
fn object_box(leaf: &LeafView, parts: (usize, usize), frame: &Aabb) -> Aabb {
    (parts.0..parts.1)
        .filter_map(|i| QuantBox::decode(frame, leaf.object(i)?.qbox))
        .fold(Aabb::EMPTY, |b, q| b.union(&q.outer))
}

/// An object decided, in the order the traversal decided it (best first:
/// in order of distance).
pub(crate) struct Decision {
    pub hit: Hit,
    pub accepted: bool,
    /// Best first: the exact distance.
    pub distance: Option<f64>,
}

/// What a budgeted traversal left when it ended.
#[derive(Default)]
struct Rest {
    maybe: Vec<ObjectId>,
    unexplored_nodes: u64,
    level_reached: u8,
}

/// The one traversal as an iterator over the objects a query accepts
/// (`ReadTransaction::select`). Blocks are read as `next` needs them and
/// counted where they are read; [`stats`](Self::stats) tells what the
/// objects so far cost. Hits come depth first (a budget: the most objects
/// per block first), not sorted by id.
pub struct Select<'a, S> {
    txn: &'a ReadTransaction,
    sel: S,
    /// Best first: the distance the queue is ordered by.
    rank: Option<Rank>,
    visitor: Option<&'a mut dyn Visitor>,
    k: u8,
    m: u8,
    budget: Option<u64>,
    /// The finest bound level tested.
    bound_level: u8,
    reads: Reads<'a>,
    /// Reads before the traversal began (a caller's reads may be handed in).
    before: ReadStats,
    heap: BinaryHeap<Queued>,
    /// Steps that would pass the budget.
    deferred: Vec<Queued>,
    seq: u64,
    visits: u64,
    visit_limit: u64,
    /// Objects decided so far (a part still queued of one is not read).
    done: rustc_hash::FxHashSet<u32>,
    /// Objects whose parts are queued for their geometry: parts left.
    parts: rustc_hash::FxHashMap<u32, u32>,
    /// Best first: objects found at a distance, not yet yielded.
    found: rustc_hash::FxHashSet<u32>,
    /// Decided, not yet yielded.
    out: VecDeque<Decision>,
    stats: TraverseStats,
    started: Instant,
    /// Set when the queue is spent (or an error ended it).
    rest: Option<Rest>,
    /// Stand-ins: how the file's group bounds are gridded (their errors
    /// are known from a record's box before its bound is read).
    groups: Option<crate::lod::GroupRule>,
    /// Set while a group bound is refined: its children's records are read
    /// next, with the budget its cost reserved for them. A child the budget
    /// left unread would be shown by its box, coarser than the bound it
    /// replaced, and a larger budget could show a larger error.
    refining: bool,
    /// Over a network, without a budget, a ranking or stand-ins: a step
    /// that must go to the device takes the waiting steps' blocks with it
    /// (every waiting step of such a traversal is run), in one round trip.
    ahead: bool,
    /// Blocks fetched ahead, not to be asked for again.
    fetched_ahead: rustc_hash::FxHashSet<u32>,
}

impl<'a, S: Selection> Select<'a, S> {
    /// The traversal of `sel` from record `start` (`None`: an empty tree)
    /// at `opts`' level and budget, reading through `reads`; best first by
    /// `rank` when given.
    pub(crate) fn new(
        txn: &'a ReadTransaction,
        start: Option<NodeRef>,
        sel: S,
        opts: &QueryOptions,
        reads: Reads<'a>,
        rank: Option<Rank>,
    ) -> Result<Select<'a, S>, QueryError> {
        let (k, _) = levels(txn, opts.lod)?;
        if start.is_some() {
            txn.info().ok_or(QueryError::NoTree)?;
        }
        Ok(Select::at_level(txn, start, sel, k, opts, reads, rank)?)
    }

    /// [`new`](Self::new) at level `k`, which the caller has checked is
    /// one of the file's (1..=M), from a `start` of the file's tree: what
    /// is left to fail is the file.
    fn at_level(
        txn: &'a ReadTransaction,
        start: Option<NodeRef>,
        sel: S,
        k: u8,
        opts: &QueryOptions,
        reads: Reads<'a>,
        rank: Option<Rank>,
    ) -> Result<Select<'a, S>, StorageError> {
        let m = txn.pager().lod_levels();
        let nodes = match start {
            Some(_) => txn.info().map_or(0, |i| i.nodes),
            None => 0,
        };
        let levels = usize::from(m);
        let before = reads.stats;
        let mut s = Select {
            txn,
            sel,
            rank,
            visitor: None,
            k,
            m,
            budget: opts.budget,
            bound_level: k.min(m - 1).min(opts.bounds_up_to.unwrap_or(u8::MAX)),
            reads,
            before,
            heap: BinaryHeap::new(),
            deferred: Vec::new(),
            seq: 0,
            visits: 0,
            visit_limit: u64::from(nodes),
            done: Default::default(),
            parts: Default::default(),
            found: Default::default(),
            out: VecDeque::new(),
            stats: TraverseStats {
                confirmed: vec![0; levels],
                rejected: vec![0; levels],
                ..TraverseStats::default()
            },
            started: Instant::now(),
            rest: None,
            groups: None,
            refining: false,
            ahead: false,
            fetched_ahead: Default::default(),
        };
        s.ahead =
            txn.fetches_ahead() && s.rank.is_none() && s.budget.is_none() && s.sel.tolerance().is_none();
        if s.sel.tolerance().is_some() {
            s.groups = txn.group_rule();
        }
        // A budgeted query's costs count the blocks it holds: it holds all
        // it reads (at most its budget).
        s.reads.keep_all(opts.budget.is_some());
        match start {
            None => s.rest = Some(Rest { level_reached: k, ..Rest::default() }),
            Some(start) if s.sel.may_meet_box(&start.aabb) => {
                let inside = s.sel.holds_box(&start.aabb);
                let at = RecordRef { block: start.block, checksum: start.checksum, offset: start.offset };
                let estimate = f64::from(txn.info().map_or(0, |i| i.objects));
                // The tree's root is node 0; a walk from another node learns its id on reading it.
                let root = txn.root().is_some_and(|r| (r.block, r.offset) == (start.block, start.offset));
                let name = NodeName { id: root.then_some(0), parent: None, child: 0 };
                s.push(Step::Unread { at, frame: start.aabb, inside, estimate, name })?;
            }
            Some(_) => s.stats.pruned += 1,
        }
        Ok(s)
    }

    /// Shows `visitor` each record entered and object decided.
    pub(crate) fn visited_by(mut self, visitor: &'a mut dyn Visitor) -> Select<'a, S> {
        self.visitor = Some(visitor);
        self
    }

    /// What the traversal has done so far: the blocks read (the pager's
    /// counts) and the decisions made, per level.
    pub fn stats(&self) -> TraverseStats {
        let mut s = self.stats.clone();
        s.reads = self.reads.stats - self.before;
        if self.rest.is_none() {
            s.seconds = self.started.elapsed().as_secs_f64();
        }
        s
    }

    /// Budgeted, once the iterator has ended: objects seen but not refined
    /// to the level asked for (sorted).
    pub fn maybe(&self) -> &[ObjectId] {
        self.rest.as_ref().map_or(&[], |r| &r.maybe)
    }

    /// Budgeted, once the iterator has ended: subtrees left unread.
    pub fn unexplored_nodes(&self) -> u64 {
        self.rest.as_ref().map_or(0, |r| r.unexplored_nodes)
    }

    /// Once the iterator has ended: the coarsest level an undecided
    /// candidate stopped at (the level asked for when the budget sufficed).
    pub fn level_reached(&self) -> Option<u8> {
        self.rest.as_ref().map(|r| r.level_reached)
    }

    /// The next object accepted.
    pub(crate) fn next_accepted(&mut self) -> Option<Result<Decision, StorageError>> {
        loop {
            match self.next_decision()? {
                Ok(d) if !d.accepted => {}
                d => return Some(d),
            }
        }
    }

    /// The next object decided, accepted or not.
    pub(crate) fn next_decision(&mut self) -> Option<Result<Decision, StorageError>> {
        loop {
            if let Some(d) = self.out.pop_front() {
                return Some(Ok(d));
            }
            if self.rest.is_some() {
                return None;
            }
            if let Err(e) = self.advance() {
                self.heap.clear();
                self.deferred.clear();
                // Nothing set aside is left to show: the error ends the walk.
                if let Err(f) = self.finish() {
                    return Some(Err(f));
                }
                return Some(Err(e));
            }
        }
    }

    /// Drains the iterator into a sorted answer.
    pub(crate) fn answer(&mut self) -> Result<QueryAnswer, StorageError> {
        let (mut accepted, mut decided) = (Vec::new(), Vec::new());
        while let Some(d) = self.next_decision() {
            let d = d?;
            let Hit { object, key, level, proof, .. } = d.hit;
            if d.accepted {
                accepted.push((object, key));
            }
            decided.push(ObjectLevel { object, level, accepted: d.accepted, proof });
        }
        accepted.sort_unstable_by_key(|a| a.0);
        let (objects, keys) = accepted.into_iter().unzip();
        decided.sort_unstable_by_key(|d| d.object);
        let stats = self.stats();
        let rest = self.rest.take().unwrap_or_default();
        Ok(QueryAnswer {
            objects,
            keys,
            maybe: rest.maybe,
            unexplored_nodes: rest.unexplored_nodes,
            level: self.k,
            level_reached: rest.level_reached,
            decided,
            stats,
        })
    }

    fn over_budget(&self, cost: u64) -> bool {
        let spent = self.reads.stats.total() - self.before.total();
        self.budget.is_some_and(|b| spent + cost > b)
    }

    /// Runs one step of the queue, or ends the traversal.
    fn advance(&mut self) -> Result<(), StorageError> {
        let Some(q) = self.heap.pop() else {
            // Blocks read since a step was set aside may have made it affordable.
            let waiting = self.deferred.len();
            let mut still = Vec::new();
            for q in std::mem::take(&mut self.deferred) {
                if self.over_budget(self.charge(&q.step)?) {
                    still.push(q);
                } else {
                    self.heap.push(q);
                }
            }
            self.deferred = still;
            if self.deferred.len() == waiting {
                self.finish()?;
            }
            return Ok(());
        };
        if self.settled(&q.step)? {
            return Ok(());
        }
        if self.budget.is_some() && self.over_budget(self.charge(&q.step)?) {
            self.deferred.push(q);
            return Ok(());
        }
        if self.ahead {
            self.fetch_ahead(&q);
        }
        self.step(q.step)
    }

    /// Ends the traversal: what a budget set aside is the rest, and a query
    /// that takes stand-ins is shown it as stand-ins.
    fn finish(&mut self) -> Result<(), StorageError> {
        let mut rest = Rest { level_reached: self.k, ..Rest::default() };
        for q in std::mem::take(&mut self.deferred) {
            match q.step {
                Step::Unread { frame, name, .. } | Step::Node { frame, name, .. } => {
                    rest.unexplored_nodes += 1;
                    rest.level_reached = 1;
                    if self.sel.tolerance().is_some()
                        && let Some(visitor) = self.visitor.as_deref_mut()
                    {
                        visitor.stand_in(&name, &frame)?;
                    }
                }
                Step::Exact { block, offset, index, level, part, .. } => {
                    let NodeView::Leaf(leaf) = view(&block, offset)? else { continue };
                    let Some(o) = leaf.object(index) else { continue };
                    if !self.done.contains(&o.object_id) {
                        rest.maybe.push(ObjectId(o.object_id));
                        rest.level_reached = rest.level_reached.min(level);
                    }
                    // A part left unread is shown at its bound (another
                    // part of its object may have been read).
                    if self.sel.tolerance().is_some() {
                        let v = match finest(leaf.bounds(), index as u16, level) {
                            Some(b) => Some(self.voxels(block.id(), &b, &part)?),
                            None => None,
                        };
                        let leaf_id = view(&block, offset)?.node_id();
                        let seen = (leaf_id, o.object_id, part);
                        self.seen(
                            seen,
                            (level, true, Proof::Candidate),
                            v.as_ref().map(|v| (level, v)),
                            None,
                        )?;
                    }
                }
                Step::Found { .. } => {}
                Step::Group { frame, name, level, eps, voxels, .. } => {
                    rest.unexplored_nodes += 1;
                    rest.level_reached = rest.level_reached.min(level);
                    if let Some(visitor) = self.visitor.as_deref_mut() {
                        visitor.group(&name, &frame, level, &voxels, eps)?;
                    }
                }
            }
        }
        rest.maybe.sort_unstable();
        rest.maybe.dedup();
        self.stats.seconds = self.started.elapsed().as_secs_f64();
        self.rest = Some(rest);
        Ok(())
    }

    /// A query that takes stand-ins settles a node whose box is close
    /// enough: the visitor is shown it, and it is not read.
    fn settled(&mut self, step: &Step) -> Result<bool, StorageError> {
        let (Step::Unread { frame, name, .. } | Step::Node { frame, name, .. }) = step else {
            return Ok(false);
        };
        if !self.settles(frame, frame.extent().norm()) {
            return self.settled_by_group(step);
        }
        if let Some(visitor) = self.visitor.as_deref_mut() {
            visitor.stand_in(name, frame)?;
        }
        Ok(true)
    }

    /// The group levels of a record in hand, coarse to fine, each with its
    /// error in mm (from the record's box: no read), and the reads of its
    /// group block (0 when held, or when the record stores none).
    fn group_levels(
        &self,
        block: &Block,
        offset: u32,
        frame: &Aabb,
    ) -> Result<(Vec<(u8, f64)>, u64), StorageError> {
        let Some(rule) = &self.groups else { return Ok((Vec::new(), 0)) };
        let record = view(block, offset)?;
        let frame = record.frame(*frame);
        let levels: Vec<(u8, f64)> =
            record.group_levels().filter_map(|k| Some((k, rule.eps(k, &frame)?))).collect();
        let cost = match crate::store::format::node::group_ref(block.bytes()) {
            Some((g, _)) if !levels.is_empty() => u64::from(!self.reads.holds(g)),
            _ => 0,
        };
        Ok((levels, cost))
    }

    /// A query that takes stand-ins settles a record in hand by its
    /// coarsest group bound b(S_n,k) whose error is within the tolerance,
    /// reading its group block (when the budget allows) and nothing below.
    fn settled_by_group(&mut self, step: &Step) -> Result<bool, StorageError> {
        let Step::Node { block, offset, frame, name, .. } = step else { return Ok(false) };
        let (levels, cost) = self.group_levels(block, *offset, frame)?;
        let Some(&(k, eps)) = levels.iter().find(|(_, eps)| self.settles(frame, *eps)) else {
            return Ok(false);
        };
        if self.over_budget(cost) {
            return Ok(false);
        }
        let Some(v) = self.txn.group_bound(block, *offset, frame, k, &mut self.reads)? else {
            return Ok(false);
        };
        let frame = view(block, *offset)?.frame(*frame);
        if let Some(visitor) = self.visitor.as_deref_mut() {
            visitor.group(name, &frame, k, &v, eps)?;
        }
        Ok(true)
    }

    /// Whether what `b` holds, shown by a stand-in within `eps` mm of it,
    /// is close enough for the query (never, for a query without stand-ins).
    fn settles(&self, b: &Aabb, eps: f64) -> bool {
        self.sel.tolerance().is_some_and(|t| self.sel.stand_in_error(b, eps) <= t)
    }

    fn cost(&self, step: &Step) -> Result<u64, StorageError> {
        Ok(match step {
            Step::Unread { at, .. } => u64::from(!self.reads.holds(at.block)),
            Step::Node { .. } | Step::Found { .. } => 0,
            // Refining a group bound costs what `refinement` finds.
            Step::Group { block, offset, frame, eps, .. } => {
                let (blocks, geometry) =
                    self.refinement(block, *offset, frame, self.sel.stand_in_error(frame, *eps))?;
                blocks + geometry
            }
            Step::Exact { block, offset, index, .. } => {
                let NodeView::Leaf(leaf) = view(block, *offset)? else { return Ok(0) };
                let Some(o) = leaf.object(*index) else { return Ok(0) };
                if self.done.contains(&o.object_id) && self.sel.tolerance().is_none() {
                    return Ok(0);
                }
                let (first, _) = leaf.geometry();
                geometry::blocks_of(o.span.0, o.span.1, self.txn.pager().block_size())
                    .filter(|b| !self.reads.holds(first.saturating_add(*b as u32)))
                    .count() as u64
            }
        })
    }

    /// What refining record `offset` of `block` (its box `frame`, shown
    /// with error `shown`) reads before nothing that replaces it shows a
    /// larger error: (node blocks, geometry blocks). It is free when its
    /// children, shown without a read, are no coarser. Else it reads the
    /// child blocks not held of its children that may meet the query; a
    /// child in this block that would show coarser (its finer group bound
    /// did not fit the group block) costs its own refinement in turn, so a
    /// budget near its end keeps the record whole rather than show a
    /// coarser child it cannot refine. A leaf's objects, in hand, cost the
    /// geometry blocks that make them exact when their own stand-ins are
    /// coarser. The look-ahead visits each record of the block at most once
    /// in a tree; it stops after as many visits as the block has records,
    /// since in a hostile file in-block children need not form a tree.
    fn refinement(
        &self,
        block: &Block,
        offset: u32,
        frame: &Aabb,
        shown: f64,
    ) -> Result<(u64, u64), StorageError> {
        self.refinement_within(block, offset, frame, shown, &mut block.records.len())
    }

    fn refinement_within(
        &self,
        block: &Block,
        offset: u32,
        frame: &Aabb,
        shown: f64,
        visits_left: &mut usize,
    ) -> Result<(u64, u64), StorageError> {
        let n = match view(block, offset)? {
            NodeView::Internal(n) => n,
            NodeView::Leaf(leaf) => {
                if self.objects_error(block.id(), &leaf, frame)? <= shown {
                    return Ok((0, 0));
                }
                let (first, sums) = leaf.geometry();
                let unread = (0..sums.len() as u32).filter(|i| !self.reads.holds(first.saturating_add(*i)));
                return Ok((0, unread.count() as u64));
            }
        };
        let mut blocks: Vec<u32> = Vec::new();
        let mut coarser = false;
        let mut in_block = (0, 0);
        for i in 0..2 {
            let Some(qb) = n.child_box(i, frame) else { continue };
            if !self.sel.may_meet_box(&qb.outer) {
                continue;
            }
            let box_error = self.sel.stand_in_error(&qb.outer, qb.outer.extent().norm());
            let at = n.child_ref(i);
            if at.block != 0 {
                coarser |= box_error > shown;
                if !self.reads.holds(at.block) && !blocks.contains(&at.block) {
                    blocks.push(at.block);
                }
                continue;
            }
            let (levels, cost) = self.group_levels(block, at.offset, &qb.outer)?;
            let error = match levels.last() {
                Some(&(_, eps)) if cost == 0 => box_error.min(self.sel.stand_in_error(&qb.outer, eps)),
                _ => box_error,
            };
            if error > shown {
                coarser = true;
                if let Some(left) = visits_left.checked_sub(1) {
                    *visits_left = left;
                    let (b, g) = self.refinement_within(block, at.offset, &qb.outer, shown, visits_left)?;
                    in_block = (in_block.0 + b, in_block.1 + g);
                }
            }
        }
        if !coarser {
            return Ok((0, 0));
        }
        Ok((blocks.len() as u64 + in_block.0, in_block.1))
    }

    /// What a step must find left of the budget: its cost, and for
    /// refining a group bound one more read per node block it reads: after
    /// a child block's records, the traversal reads its group block (at
    /// most one each, counted unread), which shows the children by their
    /// own bounds. A child the budget left without its bound would be shown
    /// by its box, coarser than the bound it replaced.
    fn charge(&self, step: &Step) -> Result<u64, StorageError> {
        match step {
            Step::Group { block, offset, frame, eps, .. } if self.groups.is_some() => {
                let (blocks, geometry) =
                    self.refinement(block, *offset, frame, self.sel.stand_in_error(frame, *eps))?;
                Ok(2 * blocks + geometry)
            }
            _ => self.cost(step),
        }
    }

    /// The largest error, in the query's unit, of a leaf's objects that
    /// may meet the query shown by their own stand-ins (the finest stored
    /// bound below M, else the box), with the record in hand.
    fn objects_error(&self, block: u32, leaf: &LeafView, frame: &Aabb) -> Result<f64, StorageError> {
        let mut worst = 0.0f64;
        for i in 0..leaf.len() {
            let Some(o) = leaf.object(i) else { continue };
            let Some(qb) = QuantBox::decode(frame, o.qbox) else { continue };
            if !self.sel.may_meet_box(&qb.outer) {
                continue;
            }
            let eps = match finest(leaf.bounds(), i as u16, self.bound_level) {
                Some(b) => self.voxels(block, &b, &qb.outer)?.grid().max_cell_diagonal(),
                None => qb.outer.extent().norm(),
            };
            worst = worst.max(self.sel.stand_in_error(&qb.outer, eps));
        }
        Ok(worst)
    }

    fn push(&mut self, step: Step) -> Result<(), StorageError> {
        self.seq += 1;
        let (priority, tie) = match (&self.rank, self.budget) {
            // Nearest first; at one distance, what may still hold a nearer
            // or equal object before a found one, and found ones by id.
            (Some(rank), _) => {
                let (key, tie) = match &step {
                    Step::Unread { frame, .. } | Step::Node { frame, .. } => {
                        (rank.box_distance(frame), (1 << 32) + self.seq)
                    }
                    Step::Exact { part, .. } => (rank.box_distance(part), (1 << 32) + self.seq),
                    Step::Found { object, distance, .. } => (Some(*distance), u64::from(u32::MAX - object)),
                    Step::Group { frame, .. } => (rank.box_distance(frame), (1 << 32) + self.seq),
                };
                // + 0.0: a distance of -0.0 orders as 0.
                (-(key.unwrap_or(f64::INFINITY) + 0.0), tie)
            }
            // Depth first: the newest step first.
            (None, None) => (self.seq as f64, self.seq),
            // Stand-ins: the most error removed per block read first (the
            // error shown now over the reads that refine it); records in
            // hand cost nothing.
            (None, Some(_)) if self.sel.tolerance().is_some() => {
                let error = match &step {
                    Step::Unread { .. } if self.refining => f64::INFINITY,
                    Step::Unread { frame, .. } => self.sel.stand_in_error(frame, frame.extent().norm()),
                    Step::Exact { part, eps, .. } => self.sel.stand_in_error(part, *eps),
                    Step::Group { frame, eps, .. } => self.sel.stand_in_error(frame, *eps),
                    Step::Node { .. } | Step::Found { .. } => f64::INFINITY,
                };
                let cost = self.cost(&step)? as f64;
                (error / cost.max(1.0), self.seq)
            }
            (None, Some(_)) => {
                let gain = match &step {
                    Step::Unread { estimate, .. } => *estimate,
                    Step::Node { .. } | Step::Found { .. } | Step::Group { .. } => f64::INFINITY,
                    Step::Exact { .. } => 1.0,
                };
                let cost = self.cost(&step)? as f64;
                (if cost == 0.0 { f64::INFINITY } else { gain / cost }, self.seq)
            }
        };
        self.heap.push(Queued { priority, tie, step });
        Ok(())
    }

    /// Shows the visitor an entry (an object, or a part of one) as decided.
    fn seen(
        &mut self,
        entry: (u32, u32, Aabb),
        decision: (u8, bool, Proof),
        bound: Option<(u8, &Voxels)>,
        mesh: Option<&Mesh>,
    ) -> Result<(), StorageError> {
        let Some(visitor) = self.visitor.as_deref_mut() else { return Ok(()) };
        let (leaf, object, aabb) = entry;
        let (level, accepted, proof) = decision;
        let decision = ObjectLevel { object: ObjectId(object), level, accepted, proof };
        visitor.object(&Seen { leaf, aabb, bound, mesh, decision })
    }

    /// Records an object's decision (once per object, whatever its parts).
    fn decide(&mut self, object: (u32, Aabb, Key), decision: (u8, bool, Proof), distance: Option<f64>) {
        let ((id, aabb, key), (level, accepted, proof)) = (object, decision);
        let i = usize::from(level) - 1;
        match proof {
            Proof::Candidate => {}
            _ if accepted => self.stats.confirmed[i] += 1,
            _ => self.stats.rejected[i] += 1,
        }
        self.done.insert(id);
        let hit = Hit { object: ObjectId(id), key, aabb, level, proof };
        self.out.push_back(Decision { hit, accepted, distance });
    }
}

impl<S: Selection> Iterator for Select<'_, S> {
    type Item = Result<Hit, QueryError>;

    fn next(&mut self) -> Option<Self::Item> {
        Some(self.next_accepted()?.map(|d| d.hit).map_err(QueryError::from))
    }
}

impl ReadTransaction {
    /// The objects whose exact geometry (their triangles) meets `query`,
    /// with the reads it took: the one traversal from a cold start.
    pub fn query_box(&self, query: &Aabb) -> Result<QueryAnswer, QueryError> {
        super::query_region(self, &super::Region::Box(*query), &Default::default(), None)
    }

    /// The objects `sel` accepts at `opts`' level and budget, one at a time
    /// as the traversal decides them (depth first; with a budget, the most
    /// objects per block first), reading through `cache` (a pool kept
    /// across queries) when given. Nothing is read before the first `next`;
    /// a caller that stops early reads only what its hits needed, and
    /// [`Select::stats`] counts it.
    pub fn select<'a, S: Selection + ?Sized>(
        &'a self,
        sel: &'a S,
        opts: &QueryOptions,
        cache: Option<&'a BlockCache>,
    ) -> Result<Select<'a, &'a S>, QueryError> {
        sel.check_input()?;
        Select::new(self, self.root(), sel, opts, Reads::new(cache), None)
    }
}

/// Runs `sel` through `txn`'s tree at `opts`' level and budget, reading
/// through `cache` (a pool shared across queries) when given: the whole
/// [`Select`] iterator, sorted into an answer.
pub fn traverse<S: Selection + ?Sized>(
    txn: &ReadTransaction,
    sel: &S,
    opts: &QueryOptions,
    cache: Option<&BlockCache>,
) -> Result<QueryAnswer, QueryError> {
    Ok(txn.select(sel, opts, cache)?.answer()?)
}

/// The traversal from record `start` (its block read through `reads`
/// unless `reads` holds it), showing `visitor` what it meets; `reads` gets
/// back what the walk read and holds.
pub(crate) fn walk<S: Selection + ?Sized>(
    txn: &ReadTransaction,
    start: NodeRef,
    sel: &S,
    opts: &QueryOptions,
    reads: &mut Reads,
    visitor: &mut dyn Visitor,
) -> Result<QueryAnswer, QueryError> {
    // What the level may refuse, refused before `reads` is lent.
    let (k, _) = levels(txn, opts.lod)?;
    txn.info().ok_or(QueryError::NoTree)?;
    Ok(walk_level(txn, start, sel, k, opts, reads, visitor)?)
}

/// [`walk`] at level `k` of the file's 1..=M, which the caller knows it
/// holds (db's own passes over a stored tree): only the file can fail it.
/// A `k` outside the file's levels is taken as the nearest one.
pub(crate) fn walk_level<S: Selection + ?Sized>(
    txn: &ReadTransaction,
    start: NodeRef,
    sel: &S,
    k: u8,
    opts: &QueryOptions,
    reads: &mut Reads,
    visitor: &mut dyn Visitor,
) -> Result<QueryAnswer, StorageError> {
    let k = k.clamp(1, txn.pager().lod_levels().max(1));
    let mut select =
        Select::at_level(txn, Some(start), sel, k, opts, reads.lend(), None)?.visited_by(visitor);
    let answer = select.answer();
    reads.take_back(select.reads);
    answer
}
