//! The one traversal every single-shape query runs (region, collide,
//! navigate, tradeoff; clash runs the tree against itself in `clash.rs`).
//!
//! Paper §1.5, the multiresolution query: descend from the root; at each
//! node test the query against b(S_n,1) (the child's box, held by its
//! parent, so a pruned child's block is never read), then against
//! b(S_n,j) for 2 <= j <= k where this node stores it; at a leaf test its
//! objects against B(S_n,j), j = 1 .. k, and at k = M exactly. A miss prunes:
//! every bound contains what it bounds, so nothing below can meet the query.
//! An entry that names another level (tag 4) is tested where it is stored;
//! a spread entry (tag 3) is the children's, met on the way down.
//!
//! The work is a queue of candidates, each one step from its next test. With
//! no budget it is a stack (depth first: a clustered node block is entered
//! once). With a block budget it is a priority queue: the step that settles
//! the most undecided objects per block it would read goes first; a step
//! that would pass the budget is set aside, and what is left when nothing
//! fits is the answer's `maybe` (objects known, not refined) and
//! `unexplored` (subtrees not yet read).

use std::collections::{BinaryHeap, HashSet};
use std::sync::Arc;
use std::time::Instant;

use serde::Serialize;

use super::QueryError;
use super::shape::Probe;
use crate::db::{Piece, ReadTransaction, TraversalGuard, entry_blocks, record_at};
use crate::scene::ObjectId;
use crate::store::format::node::{LodRef, NodeRecord};
use crate::store::{BlockCache, ReadStats, StorageError};

/// Level and block budget of a query.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct QueryOptions {
    /// The level k to answer at (1 ..= M); `None` is M, the exact answer.
    pub lod: Option<u8>,
    /// At most this many block reads; `None` for no limit.
    pub budget: Option<u64>,
}

/// What a traversal did besides its answer.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct TraverseStats {
    pub reads: ReadStats,
    pub nodes_visited: u64,
    pub leaves_visited: u64,
    /// Tests of a bound (a node's or an object's) at level k = 1 .. M, index
    /// k - 1; at M, the objects tested exactly.
    pub tests_per_level: Vec<u64>,
    pub triangles_tested: u64,
    pub seconds: f64,
}

/// Where an object seen at a leaf was decided.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct ObjectLevel {
    pub object: ObjectId,
    /// The level of the last bound it was tested against.
    pub level: u8,
    /// In the answer (confirmed at M, a candidate below), or rejected.
    pub accepted: bool,
}

/// A single-shape query's answer.
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
    /// Objects seen at leaves, with the level they were decided at (sorted).
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

/// A node record in hand: its decoded block and slot.
#[derive(Clone)]
struct Held {
    records: Arc<Vec<NodeRecord>>,
    block: u32,
    slot: u16,
}

impl Held {
    fn rec(&self) -> Result<&NodeRecord, StorageError> {
        record_at(&self.records, self.block, self.slot)
    }
}

enum State {
    /// A child whose box met the query; its block not read yet.
    Unread { block: u32, slot: u16, checksum: Option<u32>, estimate: f64, root: bool },
    /// A node whose group bounds passed up to `level`.
    Node { at: Held, level: u8 },
    /// A leaf's objects: `alive` passed B(S_n,·) up to `olevel` (None: not read yet).
    Leaf { at: Held, level: u8, olevel: u8, alive: Option<Vec<ObjectId>> },
}

struct Cand {
    priority: f64,
    seq: u64,
    state: State,
}

impl PartialEq for Cand {
    fn eq(&self, o: &Cand) -> bool {
        self.cmp(o) == std::cmp::Ordering::Equal
    }
}
impl Eq for Cand {}
impl PartialOrd for Cand {
    fn partial_cmp(&self, o: &Cand) -> Option<std::cmp::Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for Cand {
    fn cmp(&self, o: &Cand) -> std::cmp::Ordering {
        self.priority.total_cmp(&o.priority).then(self.seq.cmp(&o.seq))
    }
}

/// The next stored entry of `rec` for levels after `after` up to `last`:
/// group bounds (`objects` false) or per-object bounds. An entry that names
/// another level is skipped: that level's own entry is the same blob.
pub(crate) fn next_entry(rec: &NodeRecord, after: u8, last: u8, objects: bool) -> Option<(u8, LodRef)> {
    (after.saturating_add(1)..=last).find_map(|j| match rec.entry(j, objects) {
        Some((l, o, e @ (LodRef::InBlock { .. } | LodRef::Run { .. }))) if l == j && o == objects => {
            Some((j, e))
        }
        _ => None,
    })
}

/// The level k of a query on `txn`, checked, with M.
pub(crate) fn levels(txn: &ReadTransaction, lod: Option<u8>) -> Result<(u8, u8), QueryError> {
    let m = txn.info().ok_or(QueryError::NoTree)?.lod_levels;
    let k = lod.unwrap_or(m);
    if k == 0 || k > m {
        return Err(QueryError::Level { k, m });
    }
    Ok((k, m))
}

/// Per-object results of testing one leaf piece.
pub(crate) fn test_piece<P: Probe + ?Sized>(
    probe: &P,
    piece: &Piece,
    triangles_tested: &mut u64,
) -> Vec<(ObjectId, bool)> {
    match piece {
        Piece::ObjectBoxes(v) => v.iter().map(|(id, b)| (*id, probe.meets_box(b))).collect(),
        Piece::ObjectVoxels(v) => v.iter().map(|(id, s)| (*id, probe.meets_voxels(s))).collect(),
        Piece::Objects(v) => v.iter().map(|(id, m)| (*id, probe.meets_mesh(m, triangles_tested))).collect(),
        Piece::Box { .. } | Piece::Voxels { .. } => Vec::new(),
    }
}

/// True when a group piece (b(S_n,j)) may meet the probe.
fn group_meets<P: Probe + ?Sized>(probe: &P, piece: &Piece, n: &mut u64) -> bool {
    match piece {
        Piece::Box { aabb, .. } => probe.meets_box(aabb),
        Piece::Voxels { voxels, .. } => probe.meets_voxels(voxels),
        other => test_piece(probe, other, n).iter().any(|x| x.1),
    }
}

struct Run<'a, P: ?Sized> {
    txn: &'a ReadTransaction,
    probe: &'a P,
    k: u8,
    m: u8,
    budget: Option<u64>,
    /// With the query's own unbounded pool a block is read at most once,
    /// so a step costs its blocks not yet read; with a caller's pool, which
    /// may evict, it costs all its blocks (an upper bound).
    exact_cost: bool,
    seen: HashSet<u32>,
    heap: BinaryHeap<Cand>,
    seq: u64,
    stats: TraverseStats,
    objects: Vec<ObjectId>,
    decided: Vec<ObjectLevel>,
}

impl<P: Probe + ?Sized> Run<'_, P> {
    fn push(&mut self, state: State) -> Result<(), StorageError> {
        self.seq += 1;
        let priority = match self.budget {
            None => 0.0,
            Some(_) => {
                let gain = match &state {
                    State::Unread { estimate, .. } => *estimate,
                    State::Node { at, .. } => at.rec()?.object_count.into(),
                    State::Leaf { alive: Some(a), .. } => a.len() as f64,
                    State::Leaf { at, .. } => at.rec()?.object_count.into(),
                };
                let cost = self.cost(&self.blocks(&state)?) as f64;
                if cost == 0.0 { f64::INFINITY } else { gain / cost }
            }
        };
        self.heap.push(Cand { priority, seq: self.seq, state });
        Ok(())
    }

    /// The blocks the candidate's next step reads.
    fn blocks(&self, s: &State) -> Result<Vec<u32>, StorageError> {
        Ok(match s {
            State::Unread { block, .. } => vec![*block],
            State::Node { at, level } => next_entry(at.rec()?, *level, self.k.min(self.m - 1), false)
                .map_or(Vec::new(), |e| entry_blocks(&e.1)),
            State::Leaf { at, olevel, .. } => {
                next_entry(at.rec()?, *olevel, self.k, true).map_or(Vec::new(), |e| entry_blocks(&e.1))
            }
        })
    }

    fn cost(&self, blocks: &[u32]) -> u64 {
        blocks.iter().filter(|b| !self.exact_cost || !self.seen.contains(b)).count() as u64
    }

    fn test(&mut self, level: u8) {
        if let Some(t) = self.stats.tests_per_level.get_mut(usize::from(level) - 1) {
            *t += 1;
        }
    }

    fn step(
        &mut self,
        state: State,
        cache: &mut BlockCache,
        guard: &mut TraversalGuard,
    ) -> Result<(), StorageError> {
        let (txn, probe) = (self.txn, self.probe);
        match state {
            State::Unread { block, slot, checksum, root, .. } => {
                let records = txn.read_node_block(block, checksum, &mut self.stats.reads, Some(cache))?;
                let at = Held { records, block, slot };
                if root {
                    // The root has no parent holding its box: test it here.
                    self.test(1);
                    if !probe.meets_box(&at.rec()?.aabb()) {
                        return Ok(());
                    }
                }
                self.enter(at, guard)?;
            }
            State::Node { at, level } => {
                let rec = at.rec()?;
                if let Some((j, e)) = next_entry(rec, level, self.k.min(self.m - 1), false) {
                    let piece = txn.read_entry(rec, j, false, e, &mut self.stats.reads, Some(cache))?;
                    self.test(j);
                    let pass = piece.is_none_or(|p| group_meets(probe, &p, &mut self.stats.triangles_tested));
                    if pass {
                        self.push(State::Node { at, level: j })?;
                    }
                    return Ok(());
                }
                match &rec.children {
                    Some((kids, _)) => {
                        let estimate = f64::from(rec.object_count) / 2.0;
                        for c in kids.iter().rev() {
                            self.test(1);
                            if !probe.meets_box(&c.aabb()) {
                                continue;
                            }
                            if c.block == at.block {
                                let held = Held { records: at.records.clone(), block: c.block, slot: c.slot };
                                self.enter(held, guard)?;
                            } else {
                                self.push(State::Unread {
                                    block: c.block,
                                    slot: c.slot,
                                    checksum: Some(c.checksum),
                                    estimate,
                                    root: false,
                                })?;
                            }
                        }
                    }
                    None => {
                        self.stats.leaves_visited += 1;
                        self.push(State::Leaf { at, level, olevel: 0, alive: None })?;
                    }
                }
            }
            State::Leaf { at, level, olevel, alive } => {
                let rec = at.rec()?;
                let Some((j, e)) = next_entry(rec, olevel, self.k, true) else {
                    let Some(alive) = alive else {
                        let detail = "a leaf stores no per-object bound".to_string();
                        return Err(StorageError::corrupt_record(
                            at.block,
                            u32::from(at.slot),
                            "lods",
                            detail,
                        ));
                    };
                    for &object in &alive {
                        self.decided.push(ObjectLevel { object, level: olevel, accepted: true });
                    }
                    self.objects.extend(alive);
                    return Ok(());
                };
                let piece = txn.read_entry(rec, j, true, e, &mut self.stats.reads, Some(cache))?;
                let tested =
                    piece.map_or(Vec::new(), |p| test_piece(probe, &p, &mut self.stats.triangles_tested));
                let mut next = Vec::new();
                for (object, pass) in tested {
                    if alive.as_ref().is_some_and(|a| !a.contains(&object)) {
                        continue;
                    }
                    self.test(j);
                    if pass {
                        next.push(object);
                    } else {
                        self.decided.push(ObjectLevel { object, level: j, accepted: false });
                    }
                }
                if !next.is_empty() {
                    self.push(State::Leaf { at, level, olevel: j, alive: Some(next) })?;
                }
            }
        }
        Ok(())
    }

    fn enter(&mut self, at: Held, guard: &mut TraversalGuard) -> Result<(), StorageError> {
        guard.visit(crate::db::NodeLocation { block: at.block, slot: at.slot, checksum: None })?;
        self.stats.nodes_visited += 1;
        self.push(State::Node { at, level: 1 })
    }
}

/// Runs `probe` through `txn`'s tree at `opts`' level and budget, reading
/// through `cache` (a pool kept across queries) or, when `None`, a pool of
/// its own, so each block is read at most once.
pub(crate) fn traverse<P: Probe + ?Sized>(
    txn: &ReadTransaction,
    probe: &P,
    opts: &QueryOptions,
    cache: Option<&mut BlockCache>,
) -> Result<QueryAnswer, QueryError> {
    let started = Instant::now();
    let (k, m) = levels(txn, opts.lod)?;
    let root = txn.root().ok_or(QueryError::NoTree)?;
    let mut own = BlockCache::new(usize::MAX);
    let exact_cost = cache.is_none();
    let cache = cache.unwrap_or(&mut own);
    let mut run = Run {
        txn,
        probe,
        k,
        m,
        budget: opts.budget,
        exact_cost,
        seen: HashSet::new(),
        heap: BinaryHeap::new(),
        seq: 0,
        stats: TraverseStats { tests_per_level: vec![0; usize::from(m)], ..TraverseStats::default() },
        objects: Vec::new(),
        decided: Vec::new(),
    };
    let objects = txn.info().map_or(0.0, |i| f64::from(i.objects));
    let root_state = State::Unread {
        block: root.block,
        slot: root.slot,
        checksum: root.checksum,
        estimate: objects,
        root: true,
    };
    run.push(root_state)?;
    let mut guard = TraversalGuard::new(txn);
    let mut deferred: Vec<Cand> = Vec::new();
    loop {
        let Some(c) = run.heap.pop() else {
            // Blocks read since a step was set aside may have made it affordable.
            let before = deferred.len();
            let mut still = Vec::new();
            for c in deferred.drain(..) {
                let cost = run.cost(&run.blocks(&c.state)?);
                if opts.budget.is_some_and(|b| run.stats.reads.total() + cost > b) {
                    still.push(c);
                } else {
                    run.heap.push(c);
                }
            }
            deferred = still;
            if deferred.len() == before {
                break;
            }
            continue;
        };
        let blocks = run.blocks(&c.state)?;
        if opts.budget.is_some_and(|b| run.stats.reads.total() + run.cost(&blocks) > b) {
            deferred.push(c);
            continue;
        }
        run.step(c.state, cache, &mut guard)?;
        run.seen.extend(blocks);
    }
    let mut answer = QueryAnswer {
        objects: std::mem::take(&mut run.objects),
        maybe: Vec::new(),
        unexplored_nodes: 0,
        level: k,
        level_reached: k,
        decided: std::mem::take(&mut run.decided),
        stats: std::mem::take(&mut run.stats),
    };
    for c in deferred {
        let reached = match c.state {
            State::Unread { .. } => {
                answer.unexplored_nodes += 1;
                1
            }
            State::Node { level, .. } | State::Leaf { level, alive: None, .. } => {
                answer.unexplored_nodes += 1;
                level
            }
            State::Leaf { olevel, alive: Some(alive), .. } => {
                answer.maybe.extend(alive);
                olevel
            }
        };
        answer.level_reached = answer.level_reached.min(reached);
    }
    answer.objects.sort_unstable();
    answer.maybe.sort_unstable();
    answer.decided.sort_unstable_by_key(|d| d.object);
    answer.stats.seconds = started.elapsed().as_secs_f64();
    Ok(answer)
}
