//! Clash detection: every pair of scene objects that intersect or come
//! closer than a clearance d, by a traversal of the tree against itself
//! (a bounding-volume test tree, BVTT): from (root, root), a node paired with
//! itself gives its two children paired with themselves and with each other,
//! two distinct nodes whose boxes (grown by d) meet give the larger one's
//! children paired with the other. Leaf pairs test their objects' bounds:
//! B(S_n,1) (object boxes), then B(S_n,k) (voxel sets below M, exact
//! triangles at M). Grown bounds hold every point within d of an object, so
//! k < M gives a superset and k = M the exact pairs.
//!
//! Every block goes through one pool for the whole run, and each leaf's
//! bounds are decoded once and kept, so no block is read twice: the reads
//! are at most the file's blocks (reported beside them).

use std::collections::HashMap;
use std::rc::Rc;
use std::sync::Arc;
use std::time::Instant;

use serde::Serialize;

use super::QueryError;
use super::shape::{Probe, Triangles};
use super::traverse::{TraverseStats, levels};
use crate::db::{Piece, ReadTransaction, record_at};
use crate::geom::{Aabb, Pose};
use crate::scene::{Mesh, ObjectId};
use crate::store::format::node::{ChildRef, LodRef, NodeRecord};
use crate::store::{BlockCache, StorageError};

/// A clash run's settings.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ClashOptions {
    /// The level k (1 ..= M); `None` is M, the exact pairs.
    pub lod: Option<u8>,
    /// d, mm: objects closer than d clash (0: touching or intersecting).
    pub clearance: f64,
}

/// Every clashing pair, with the run's reads.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ClashAnswer {
    /// Sorted pairs (a, b), a < b: exact at M, a superset below.
    pub pairs: Vec<(ObjectId, ObjectId)>,
    pub level: u8,
    /// Blocks in the file, to set the reads against.
    pub file_blocks: u32,
    pub stats: TraverseStats,
}

/// An object's bound at the clash's level k, beyond its box.
enum Fine {
    /// Nothing finer stored for it at k (k = 1, or B(S_n,k) is the node's).
    None,
    /// A voxel set's world boxes, grown by its tolerance.
    Voxels(Vec<Aabb>),
    /// The exact surface (k = M), posed as a probe with clearance d.
    Exact(Box<Triangles>, Box<Mesh>),
}

struct LeafObject {
    id: ObjectId,
    aabb: Aabb,
    fine: Fine,
}

#[derive(Clone)]
struct Held {
    records: Arc<Vec<NodeRecord>>,
    block: u32,
    slot: u16,
}

struct Clash<'a> {
    txn: &'a ReadTransaction,
    k: u8,
    d: f64,
    cache: &'a mut BlockCache,
    leaves: HashMap<(u32, u16), Rc<Vec<LeafObject>>>,
    stats: TraverseStats,
    pairs: Vec<(ObjectId, ObjectId)>,
}

impl Clash<'_> {
    fn test(&mut self, level: u8) {
        if let Some(t) = self.stats.tests_per_level.get_mut(usize::from(level) - 1) {
            *t += 1;
        }
    }

    fn child(&mut self, at: &Held, c: &ChildRef) -> Result<Held, StorageError> {
        let records = if c.block == at.block {
            at.records.clone()
        } else {
            self.txn.read_node_block(c.block, Some(c.checksum), &mut self.stats.reads, Some(self.cache))?
        };
        Ok(Held { records, block: c.block, slot: c.slot })
    }

    /// A leaf's objects with their bounds at levels 1 and k, read once.
    fn leaf(&mut self, at: &Held) -> Result<Rc<Vec<LeafObject>>, QueryError> {
        if let Some(l) = self.leaves.get(&(at.block, at.slot)) {
            return Ok(l.clone());
        }
        self.stats.leaves_visited += 1;
        let rec = record_at(&at.records, at.block, at.slot)?;
        let read = |s: &mut Self, j: u8| -> Result<Option<Piece>, StorageError> {
            match rec.entry(j, true) {
                Some((l, true, e @ (LodRef::InBlock { .. } | LodRef::Run { .. }))) if l <= s.k => {
                    s.txn.read_entry(rec, l, true, e, &mut s.stats.reads, Some(s.cache))
                }
                _ => Ok(None),
            }
        };
        let Some(Piece::ObjectBoxes(boxes)) = read(self, 1)? else {
            let detail = "a leaf stores no object boxes".to_string();
            return Err(StorageError::corrupt_record(at.block, u32::from(at.slot), "lods", detail).into());
        };
        let mut fine: HashMap<ObjectId, Fine> = HashMap::new();
        match if self.k > 1 { read(self, self.k)? } else { None } {
            Some(Piece::ObjectVoxels(v)) => {
                for (id, s) in v {
                    let tol = s.grid().tolerance();
                    fine.insert(id, Fine::Voxels(s.world_boxes().iter().map(|b| b.grown(tol)).collect()));
                }
            }
            Some(Piece::Objects(v)) => {
                for (id, mesh) in v {
                    let probe = Triangles::posed(&mesh, &Pose::default(), self.d)?;
                    fine.insert(id, Fine::Exact(Box::new(probe), Box::new(mesh)));
                }
            }
            _ => {}
        }
        let objects: Vec<LeafObject> = boxes
            .into_iter()
            .map(|(id, aabb)| LeafObject { id, aabb, fine: fine.remove(&id).unwrap_or(Fine::None) })
            .collect();
        let l = Rc::new(objects);
        self.leaves.insert((at.block, at.slot), l.clone());
        Ok(l)
    }

    fn pair<'o>(&mut self, mut a: &'o LeafObject, mut b: &'o LeafObject) {
        // Contact of touching surfaces is decided within parry's tolerance,
        // and not always symmetrically: test a pair one way only, lower id
        // as the probe, as brute force does, whichever leaf the tree met first.
        if b.id < a.id {
            std::mem::swap(&mut a, &mut b);
        }
        self.test(1);
        if !a.aabb.grown(self.d).intersects(&b.aabb) {
            return;
        }
        let hit = match (&a.fine, &b.fine) {
            (Fine::Exact(probe, _), Fine::Exact(_, mesh)) => {
                self.test(self.k);
                probe.meets_mesh(mesh, &mut self.stats.triangles_tested)
            }
            (Fine::Voxels(x), Fine::Voxels(y)) => {
                self.test(self.k);
                x.iter().any(|p| y.iter().any(|q| p.grown(self.d).intersects(q)))
            }
            // One side has no finer bound at k: the boxes' verdict stands.
            _ => true,
        };
        if hit {
            self.pairs.push((a.id.min(b.id), a.id.max(b.id)));
        }
    }

    fn leaves_pair(&mut self, a: &Held, b: Option<&Held>) -> Result<(), QueryError> {
        let x = self.leaf(a)?;
        match b {
            None => {
                for (i, p) in x.iter().enumerate() {
                    for q in &x[i + 1..] {
                        self.pair(p, q);
                    }
                }
            }
            Some(b) => {
                let y = self.leaf(b)?;
                for p in x.iter() {
                    for q in y.iter() {
                        self.pair(p, q);
                    }
                }
            }
        }
        Ok(())
    }
}

/// Every pair of objects of `txn`'s tree within `opts.clearance`, at level k.
/// Reads go through `cache`, or a pool of the run's own when `None`.
pub fn clash(
    txn: &ReadTransaction,
    opts: &ClashOptions,
    cache: Option<&mut BlockCache>,
) -> Result<ClashAnswer, QueryError> {
    let started = Instant::now();
    if !(opts.clearance.is_finite() && opts.clearance >= 0.0) {
        return Err(QueryError::Clearance(opts.clearance));
    }
    let (k, m) = levels(txn, opts.lod)?;
    let info = txn.info().ok_or(QueryError::NoTree)?;
    let root = txn.root().ok_or(QueryError::NoTree)?;
    let mut own = BlockCache::new(usize::MAX);
    let mut run = Clash {
        txn,
        k,
        d: opts.clearance,
        cache: cache.unwrap_or(&mut own),
        leaves: HashMap::new(),
        stats: TraverseStats { tests_per_level: vec![0; usize::from(m)], ..TraverseStats::default() },
        pairs: Vec::new(),
    };
    let records = txn.read_node_block(root.block, root.checksum, &mut run.stats.reads, Some(run.cache))?;
    let top = Held { records, block: root.block, slot: root.slot };
    // A pair's depth sum only grows; past twice the tree's depth the links loop.
    let limit = 2 * (u64::from(info.depth) + 1);
    let mut stack = vec![(top.clone(), top, 0u64)];
    while let Some((a, b, depth)) = stack.pop() {
        if depth > limit {
            let detail =
                format!("deeper than the {} levels the meta block counts: the links loop", info.depth);
            return Err(
                StorageError::corrupt_record(a.block, u32::from(a.slot), "child_block", detail).into()
            );
        }
        let ra = record_at(&a.records, a.block, a.slot)?.clone();
        let rb = record_at(&b.records, b.block, b.slot)?.clone();
        if (a.block, a.slot) == (b.block, b.slot) {
            run.stats.nodes_visited += 1;
            match &ra.children {
                None => run.leaves_pair(&a, None)?,
                Some((kids, _)) => {
                    let c0 = run.child(&a, &kids[0])?;
                    let c1 = run.child(&a, &kids[1])?;
                    run.test(1);
                    if kids[0].aabb().grown(run.d).intersects(&kids[1].aabb()) {
                        stack.push((c0.clone(), c1.clone(), depth + 2));
                    }
                    stack.push((c1.clone(), c1, depth + 2));
                    stack.push((c0.clone(), c0, depth + 2));
                }
            }
            continue;
        }
        // Descend the internal node, the larger when both are.
        let (split, rs, other, ro) = match (&ra.children, &rb.children) {
            (None, None) => {
                run.leaves_pair(&a, Some(&b))?;
                continue;
            }
            (Some(_), None) => (a, ra, b, rb),
            (None, Some(_)) => (b, rb, a, ra),
            (Some(_), Some(_)) if ra.aabb().volume() >= rb.aabb().volume() => (a, ra, b, rb),
            _ => (b, rb, a, ra),
        };
        if let Some((kids, _)) = &rs.children {
            for c in kids.iter().rev() {
                run.test(1);
                if c.aabb().grown(run.d).intersects(&ro.aabb()) {
                    let held = run.child(&split, c)?;
                    stack.push((held, other.clone(), depth + 1));
                }
            }
        }
    }
    let mut pairs = std::mem::take(&mut run.pairs);
    pairs.sort_unstable();
    pairs.dedup();
    let mut stats = std::mem::take(&mut run.stats);
    stats.seconds = started.elapsed().as_secs_f64();
    Ok(ClashAnswer { pairs, level: k, file_blocks: info.file_blocks, stats })
}
