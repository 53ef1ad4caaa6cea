//! The one traversal every query runs (rstar's selection iterator, with the
//! MKtree's multiresolution decisions, paper §1.5).
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
//! (objects not refined) and `unexplored` (subtrees not read).

use std::collections::BinaryHeap;
use std::sync::Arc;
use std::time::Instant;

use serde::Serialize;

use super::QueryError;
use super::select::Selection;
use crate::db::{NodeRef, ReadTransaction, Reads, view};
use crate::geom::Aabb;
use crate::lod::Voxels;
use crate::scene::ObjectId;
use crate::store::format::geometry;
use crate::store::format::node::{BoundView, NodeView, RecordRef};
use crate::store::format::quant::QuantBox;
use crate::store::{Block, BlockCache, ReadStats, StorageError};

/// Level and block budget of a query.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct QueryOptions {
    /// The level k to answer at (1 ..= M); `None` is M, the exact answer.
    pub lod: Option<u8>,
    /// At most this many block reads; `None` for no limit.
    pub budget: Option<u64>,
    /// Use stored bounds of levels up to this one only (`None`: all up to
    /// k): to measure what each level saves.
    pub bounds_up_to: Option<u8>,
}

/// How an object was decided.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Proof {
    /// Its box (or a subtree's box holding it) misses the query.
    BoxMisses,
    /// A subtree's box holding it lies inside the query.
    InsideNode,
    /// The query holds a face of its tight box.
    Face,
    /// Its voxel bound misses the query.
    VoxelsMiss,
    /// The query holds a surface cell of its voxel bound.
    Cell,
    /// Its exact geometry (level M).
    Exact,
    /// Not decided: a candidate at the query's level k < M (or budget).
    Candidate,
}

/// Where an object seen at a leaf was decided.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct ObjectLevel {
    pub object: ObjectId,
    /// The level of the bound that decided it (or the last it passed).
    pub level: u8,
    /// In the answer (confirmed, or a candidate below M), or rejected.
    pub accepted: bool,
    pub proof: Proof,
}

/// What a traversal did besides its answer.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct TraverseStats {
    pub reads: ReadStats,
    pub nodes_visited: u64,
    pub leaves_visited: u64,
    /// Per level k = 1 .. M (index k - 1): objects confirmed there.
    pub confirmed: Vec<u64>,
    /// Per level k = 1 .. M: objects rejected there.
    pub rejected: Vec<u64>,
    /// Subtrees ruled out by their boxes (their objects are not counted above).
    pub pruned: u64,
    /// Objects whose geometry was read and tested (the level-M decisions).
    pub geometry_tests: u64,
    pub triangles_tested: u64,
    pub seconds: f64,
}

/// A query's answer.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct QueryAnswer {
    /// Sorted ids: exact at level M; below M a superset of the exact answer.
    pub objects: Vec<ObjectId>,
    /// Budgeted: objects seen but not refined to the requested level (sorted).
    pub maybe: Vec<ObjectId>,
    /// Budgeted: subtrees left unread; their objects may meet the query.
    pub unexplored_nodes: u64,
    /// The level asked for.
    pub level: u8,
    /// The coarsest level any undecided candidate stopped at (`level` when
    /// the budget sufficed).
    pub level_reached: u8,
    /// Objects seen at leaves, with the level and proof of their decision (sorted).
    pub decided: Vec<ObjectLevel>,
    pub stats: TraverseStats,
}

impl QueryAnswer {
    /// Drops `id` from the answer (a collision query's own object).
    pub(crate) fn without(mut self, id: ObjectId) -> QueryAnswer {
        self.objects.retain(|&o| o != id);
        self.maybe.retain(|&o| o != id);
        self.decided.retain(|o| o.object != id);
        self
    }
}

/// The level k of a query on `txn`, checked, with M.
pub(crate) fn levels(txn: &ReadTransaction, lod: Option<u8>) -> Result<(u8, u8), QueryError> {
    let m = txn.pager().lod_levels();
    let k = lod.unwrap_or(m);
    if k == 0 || k > m {
        return Err(QueryError::Level { k, m });
    }
    Ok((k, m))
}

enum Step {
    /// A child in another block, not read yet.
    Unread { at: RecordRef, frame: Aabb, inside: bool, estimate: f64 },
    /// A record in hand.
    Node { block: Arc<Block>, offset: u32, frame: Aabb, inside: bool },
    /// An object whose geometry decides it: leaf `offset` of `block` (whose
    /// box is `frame`), object `index`, which passed bounds up to `level`.
    Exact { block: Arc<Block>, offset: u32, index: usize, level: u8, frame: Aabb },
}

struct Queued {
    priority: f64,
    seq: u64,
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
        self.priority.total_cmp(&o.priority).then(self.seq.cmp(&o.seq))
    }
}

/// An object as the traversal met it: its box as stored, the bound that
/// decided it (or the finest it passed), its mesh when its geometry was
/// read, and the decision.
pub struct Seen<'a> {
    pub aabb: Aabb,
    pub bound: Option<(u8, &'a Voxels)>,
    pub mesh: Option<&'a crate::scene::Mesh>,
    pub decision: ObjectLevel,
}

/// Sees what a traversal meets: each record it enters (with the box its
/// parent holds for it) and each object it decides. Walks that need more
/// than an answer (`check`, fetching a level, clash) are visitors.
pub(crate) trait Visitor {
    /// Record `offset` of `block`, whose box is `frame`.
    fn node(&mut self, _block: &Arc<Block>, _offset: u32, _frame: &Aabb) -> Result<(), StorageError> {
        Ok(())
    }
    /// An object decided.
    fn object(&mut self, _seen: &Seen) -> Result<(), StorageError> {
        Ok(())
    }
}

/// Sees nothing (plain queries).
impl Visitor for () {}

/// The finest bound of `target` at a level <= k among `bounds`.
fn finest<'a>(bounds: impl Iterator<Item = BoundView<'a>>, target: u16, k: u8) -> Option<BoundView<'a>> {
    bounds.filter(|b| b.target == target && b.level <= k).max_by_key(|b| b.level)
}

struct Run<'t, 'c, 'v, S: ?Sized> {
    txn: &'t ReadTransaction,
    sel: &'t S,
    visitor: &'v mut dyn Visitor,
    k: u8,
    m: u8,
    budget: Option<u64>,
    /// The finest bound level tested.
    bound_level: u8,
    reads: &'v mut Reads<'c>,
    heap: BinaryHeap<Queued>,
    seq: u64,
    visits: u64,
    visit_limit: u64,
    /// Objects decided so far (a part still queued of one is not read).
    done: rustc_hash::FxHashSet<u32>,
    /// Objects whose parts are queued for their geometry: parts left.
    parts: rustc_hash::FxHashMap<u32, u32>,
    stats: TraverseStats,
    objects: Vec<ObjectId>,
    decided: Vec<ObjectLevel>,
}

impl<S: Selection + ?Sized> Run<'_, '_, '_, S> {
    fn cost(&self, step: &Step) -> Result<u64, StorageError> {
        Ok(match step {
            Step::Unread { at, .. } => u64::from(!self.reads.holds(at.block)),
            Step::Node { .. } => 0,
            Step::Exact { block, offset, index, .. } => {
                let NodeView::Leaf(leaf) = view(block, *offset)? else { return Ok(0) };
                let Some(o) = leaf.object(*index) else { return Ok(0) };
                if self.done.contains(&o.object_id) {
                    return Ok(0);
                }
                let (first, _) = leaf.geometry();
                geometry::blocks_of(o.span.0, o.span.1, self.txn.pager().block_size())
                    .filter(|b| !self.reads.holds(first.saturating_add(*b as u32)))
                    .count() as u64
            }
        })
    }

    fn push(&mut self, step: Step) -> Result<(), StorageError> {
        self.seq += 1;
        let priority = match self.budget {
            // Depth first: the newest step first.
            None => self.seq as f64,
            Some(_) => {
                let gain = match &step {
                    Step::Unread { estimate, .. } => *estimate,
                    Step::Node { .. } => f64::INFINITY,
                    Step::Exact { .. } => 1.0,
                };
                let cost = self.cost(&step)? as f64;
                if cost == 0.0 { f64::INFINITY } else { gain / cost }
            }
        };
        self.heap.push(Queued { priority, seq: self.seq, step });
        Ok(())
    }

    /// Shows the visitor an entry (an object, or a part of one) as decided.
    fn seen(
        &mut self,
        entry: (u32, Aabb),
        decision: (u8, bool, Proof),
        bound: Option<(u8, &Voxels)>,
        mesh: Option<&crate::scene::Mesh>,
    ) -> Result<(), StorageError> {
        let (object, aabb) = entry;
        let (level, accepted, proof) = decision;
        let decision = ObjectLevel { object: ObjectId(object), level, accepted, proof };
        self.visitor.object(&Seen { aabb, bound, mesh, decision })
    }

    /// Records an object's decision (once per object, whatever its parts).
    fn decide(&mut self, object: u32, level: u8, accepted: bool, proof: Proof) {
        let i = usize::from(level) - 1;
        match proof {
            Proof::Candidate => {}
            _ if accepted => self.stats.confirmed[i] += 1,
            _ => self.stats.rejected[i] += 1,
        }
        if accepted {
            self.objects.push(ObjectId(object));
        }
        self.done.insert(object);
        self.decided.push(ObjectLevel { object: ObjectId(object), level, accepted, proof });
    }

    /// The voxel set of bound `b`, whose target's box is `outer`.
    fn voxels(&self, block: u32, b: &BoundView, outer: &Aabb) -> Result<Voxels, StorageError> {
        let lattice = self
            .txn
            .lattice()
            .ok_or_else(|| StorageError::corrupt(block, "bounds", "no lattice in the meta block"))?;
        crate::lod::decode(b.blob, &lattice, outer)
            .map_err(|e| StorageError::corrupt(block, "bounds", e.to_string()))
    }

    fn step(&mut self, step: Step) -> Result<(), StorageError> {
        match step {
            Step::Unread { at, frame, inside, .. } => {
                let block = self.txn.block(
                    at.block,
                    crate::store::format::frame::BlockType::Node,
                    at.checksum,
                    self.reads,
                )?;
                self.push(Step::Node { block, offset: at.offset, frame, inside })
            }
            Step::Node { block, offset, frame, inside } => self.node(block, offset, frame, inside),
            Step::Exact { block, offset, index, frame, .. } => {
                let NodeView::Leaf(leaf) = view(&block, offset)? else { return Ok(()) };
                let Some(o) = leaf.object(index) else { return Ok(()) };
                // Another part of the object already met the query: this one need not be read.
                if self.done.contains(&o.object_id) {
                    return Ok(());
                }
                let (id, mesh) = self.txn.read_object(block.id(), &leaf, index, self.reads)?;
                self.stats.geometry_tests += 1;
                let hit = self.sel.meets_mesh(&mesh, &mut self.stats.triangles_tested);
                let aabb = QuantBox::decode(&frame, o.qbox).map_or(frame, |q| q.outer);
                self.seen((id.0, aabb), (self.m, hit, Proof::Exact), None, Some(&mesh))?;
                let left = self.parts.entry(id.0).or_insert(1);
                *left = left.saturating_sub(1);
                if hit || *left == 0 {
                    self.decide(id.0, self.m, hit, Proof::Exact);
                }
                Ok(())
            }
        }
    }

    fn node(
        &mut self,
        block: Arc<Block>,
        offset: u32,
        frame: Aabb,
        inside: bool,
    ) -> Result<(), StorageError> {
        self.visits += 1;
        if self.visits > self.visit_limit {
            return Err(StorageError::corrupt(
                block.id(),
                "child_block",
                "more nodes than the meta block counts: the links loop",
            ));
        }
        self.stats.nodes_visited += 1;
        self.visitor.node(&block, offset, &frame)?;
        let bad = |d: &str| StorageError::corrupt(block.id(), "record", d.to_string());
        match view(&block, offset)? {
            NodeView::Internal(n) => {
                let estimate = f64::from(n.child_blocks(0).1.max(1));
                for i in (0..2).rev() {
                    let qb = n.child_box(i, &frame).ok_or_else(|| bad("a child box is backwards"))?;
                    let mut child_inside = inside;
                    if !inside {
                        if !self.sel.may_meet_box(&qb.outer) {
                            self.stats.pruned += 1;
                            continue;
                        }
                        child_inside = self.sel.holds_box(&qb.outer);
                    }
                    let at = n.child_ref(i);
                    if at.block == 0 {
                        self.push(Step::Node {
                            block: block.clone(),
                            offset: at.offset,
                            frame: qb.outer,
                            inside: child_inside,
                        })?;
                    } else {
                        self.push(Step::Unread { at, frame: qb.outer, inside: child_inside, estimate })?;
                    }
                }
            }
            NodeView::Leaf(leaf) => {
                self.stats.leaves_visited += 1;
                // An object larger than a geometry block is stored as parts:
                // consecutive entries of one id. One part proves contact for
                // the object; it misses only when every part does.
                let mut j = 0;
                while j < leaf.len() {
                    let id = leaf.object(j).ok_or_else(|| bad("an object is missing"))?.object_id;
                    let mut end = j + 1;
                    while leaf.object(end).is_some_and(|o| o.object_id == id) {
                        end += 1;
                    }
                    self.object(&block, offset, &leaf, (j, end), &frame, inside)?;
                    j = end;
                }
            }
        }
        Ok(())
    }

    /// Decides the object of entries `parts` of `leaf` (record `offset` of
    /// `block`, box `frame`): by its boxes and bounds, or by queuing the
    /// parts whose geometry must be read.
    fn object(
        &mut self,
        block: &Arc<Block>,
        offset: u32,
        leaf: &crate::store::format::node::LeafView,
        parts: (usize, usize),
        frame: &Aabb,
        inside: bool,
    ) -> Result<(), StorageError> {
        let bad = |d: &str| StorageError::corrupt(block.id(), "record", d.to_string());
        let mut pending: Vec<(usize, u8, Aabb, Option<Voxels>)> = Vec::new();
        let (mut rejected_at, mut reject_proof) = (1u8, Proof::BoxMisses);
        let mut id = 0;
        for i in parts.0..parts.1 {
            let o = leaf.object(i).ok_or_else(|| bad("an object is missing"))?;
            id = o.object_id;
            let qb = QuantBox::decode(frame, o.qbox).ok_or_else(|| bad("an object box is backwards"))?;
            let aabb = qb.outer;
            if inside {
                self.seen((id, aabb), (1, true, Proof::InsideNode), None, None)?;
                self.decide(id, 1, true, Proof::InsideNode);
                return Ok(());
            }
            if !self.sel.may_meet_box(&aabb) {
                self.seen((id, aabb), (1, false, Proof::BoxMisses), None, None)?;
                continue;
            }
            if qb.face_slabs().iter().any(|f| self.sel.holds_box(f)) {
                self.seen((id, aabb), (1, true, Proof::Face), None, None)?;
                self.decide(id, 1, true, Proof::Face);
                return Ok(());
            }
            let mut level = 1;
            let mut voxels = None;
            if let Some(b) = finest(leaf.bounds(), i as u16, self.bound_level) {
                let v = self.voxels(block.id(), &b, &aabb)?;
                level = b.level;
                if !self.sel.may_meet_voxels(&v) {
                    self.seen((id, aabb), (level, false, Proof::VoxelsMiss), Some((level, &v)), None)?;
                    (rejected_at, reject_proof) = (rejected_at.max(level), Proof::VoxelsMiss);
                    continue;
                }
                if self.sel.confirms_voxels(&v) {
                    self.seen((id, aabb), (level, true, Proof::Cell), Some((level, &v)), None)?;
                    self.decide(id, level, true, Proof::Cell);
                    return Ok(());
                }
                voxels = Some(v);
            }
            pending.push((i, level, aabb, voxels));
        }
        if pending.is_empty() {
            self.decide(id, rejected_at, false, reject_proof);
        } else if self.k == self.m {
            self.parts.insert(id, pending.len() as u32);
            for (i, level, _, _) in pending {
                self.push(Step::Exact { block: block.clone(), offset, index: i, level, frame: *frame })?;
            }
        } else {
            let level = pending.iter().map(|p| p.1).max().unwrap_or(1);
            for (_, l, aabb, v) in &pending {
                self.seen((id, *aabb), (*l, true, Proof::Candidate), v.as_ref().map(|v| (*l, v)), None)?;
            }
            self.decide(id, level, true, Proof::Candidate);
        }
        Ok(())
    }
}

/// Runs `sel` through `txn`'s tree at `opts`' level and budget, reading
/// through `cache` (a pool shared across queries) when given. Each block is
/// read at most once per query.
pub fn traverse<S: Selection + ?Sized>(
    txn: &ReadTransaction,
    sel: &S,
    opts: &QueryOptions,
    cache: Option<&BlockCache>,
) -> Result<QueryAnswer, QueryError> {
    match txn.root() {
        Some(root) => walk(txn, root, sel, opts, &mut Reads::new(cache), &mut ()),
        // An empty database answers every query with nothing.
        None => {
            let (k, m) = levels(txn, opts.lod)?;
            let per_level = vec![0; usize::from(m)];
            let stats = TraverseStats {
                confirmed: per_level.clone(),
                rejected: per_level,
                ..TraverseStats::default()
            };
            Ok(QueryAnswer {
                objects: Vec::new(),
                maybe: Vec::new(),
                unexplored_nodes: 0,
                level: k,
                level_reached: k,
                decided: Vec::new(),
                stats,
            })
        }
    }
}

/// The traversal from record `start` (its block read through `reads`
/// unless `reads` holds it), showing `visitor` what it meets.
pub(crate) fn walk<S: Selection + ?Sized>(
    txn: &ReadTransaction,
    start: NodeRef,
    sel: &S,
    opts: &QueryOptions,
    reads: &mut Reads,
    visitor: &mut dyn Visitor,
) -> Result<QueryAnswer, QueryError> {
    let started = Instant::now();
    let (k, m) = levels(txn, opts.lod)?;
    let info = txn.info().ok_or(QueryError::NoTree)?;
    let levels = usize::from(m);
    let before = reads.stats;
    let mut run = Run {
        txn,
        sel,
        visitor,
        k,
        m,
        budget: opts.budget,
        bound_level: k.min(m - 1).min(opts.bounds_up_to.unwrap_or(u8::MAX)),
        reads,
        heap: BinaryHeap::new(),
        seq: 0,
        visits: 0,
        visit_limit: u64::from(info.nodes),
        done: Default::default(),
        parts: Default::default(),
        stats: TraverseStats {
            confirmed: vec![0; levels],
            rejected: vec![0; levels],
            ..TraverseStats::default()
        },
        objects: Vec::new(),
        decided: Vec::new(),
    };
    let mut answer_level = k;
    if sel.may_meet_box(&start.aabb) {
        let inside = sel.holds_box(&start.aabb);
        let at = RecordRef { block: start.block, checksum: start.checksum, offset: start.offset };
        run.push(Step::Unread { at, frame: start.aabb, inside, estimate: f64::from(info.objects) })?;
    } else {
        run.stats.pruned += 1;
    }
    let mut deferred: Vec<Queued> = Vec::new();
    let spent = |r: &Reads| r.stats.total() - before.total();
    loop {
        let Some(q) = run.heap.pop() else {
            // Blocks read since a step was set aside may have made it affordable.
            let waiting = deferred.len();
            let mut still = Vec::new();
            for q in deferred.drain(..) {
                let cost = run.cost(&q.step)?;
                if opts.budget.is_some_and(|b| spent(run.reads) + cost > b) {
                    still.push(q);
                } else {
                    run.heap.push(q);
                }
            }
            deferred = still;
            if deferred.len() == waiting {
                break;
            }
            continue;
        };
        let cost = run.cost(&q.step)?;
        if opts.budget.is_some_and(|b| spent(run.reads) + cost > b) {
            deferred.push(q);
            continue;
        }
        run.step(q.step)?;
    }
    let mut stats = std::mem::take(&mut run.stats);
    let mut answer = QueryAnswer {
        objects: std::mem::take(&mut run.objects),
        maybe: Vec::new(),
        unexplored_nodes: 0,
        level: k,
        level_reached: k,
        decided: std::mem::take(&mut run.decided),
        stats: TraverseStats::default(),
    };
    for q in deferred {
        match q.step {
            Step::Unread { .. } | Step::Node { .. } => {
                answer.unexplored_nodes += 1;
                answer_level = 1;
            }
            Step::Exact { block, offset, index, level, .. } => {
                if let Ok(NodeView::Leaf(leaf)) = view(&block, offset)
                    && let Some(o) = leaf.object(index)
                    && !run.done.contains(&o.object_id)
                {
                    answer.maybe.push(ObjectId(o.object_id));
                    answer_level = answer_level.min(level);
                }
            }
        }
    }
    let mut r = reads.stats;
    r.node -= before.node;
    r.geometry -= before.geometry;
    r.other -= before.other;
    r.cache_hits -= before.cache_hits;
    stats.reads = r;
    stats.seconds = started.elapsed().as_secs_f64();
    answer.stats = stats;
    answer.level_reached = answer_level;
    answer.objects.sort_unstable();
    answer.maybe.sort_unstable();
    answer.maybe.dedup();
    answer.decided.sort_unstable_by_key(|d| d.object);
    Ok(answer)
}
