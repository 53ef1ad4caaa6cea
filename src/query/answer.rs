//! What a query is asked and what it answers: the level and budget
//! (paper §1.5's k), the hits with the proof that decided each, and the
//! traversal's counts.

use serde::Serialize;

use super::QueryError;
use crate::geom::Aabb;
use crate::scene::{Key, ObjectId};
use crate::store::ReadStats;
use crate::tree::ReadTransaction;

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
    /// The object.
    pub object: ObjectId,
    /// The level of the bound that decided it (or the last it passed).
    pub level: u8,
    /// In the answer (confirmed, or a candidate below M), or rejected.
    pub accepted: bool,
    /// How it was decided.
    pub proof: Proof,
}

/// An object a query accepted, as [`Select`](super::Select) yields it.
#[derive(Debug, Clone, PartialEq)]
pub struct Hit {
    /// The object.
    pub object: ObjectId,
    /// The application's key for it, from its leaf record (no read of its own).
    pub key: Key,
    /// Its box as stored (rounded outward; for an object stored as parts,
    /// the union of the parts' boxes).
    pub aabb: Aabb,
    /// The level of the bound that decided it (a candidate below M: the
    /// finest it passed).
    pub level: u8,
    /// How it was decided.
    pub proof: Proof,
}

/// What a traversal did besides its answer.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct TraverseStats {
    /// Blocks read, by kind, and cache hits.
    pub reads: ReadStats,
    /// Node records entered, leaves included.
    pub nodes_visited: u64,
    /// Leaf records entered.
    pub leaves_visited: u64,
    /// Per level k = 1 .. M (index k - 1): objects confirmed there.
    pub confirmed: Vec<u64>,
    /// Per level k = 1 .. M: objects rejected there.
    pub rejected: Vec<u64>,
    /// Subtrees ruled out by their boxes (their objects are not counted above).
    pub pruned: u64,
    /// Objects whose geometry was read and tested (the level-M decisions).
    pub geometry_tests: u64,
    /// Triangles tested against the query at level M.
    pub triangles_tested: u64,
    /// Wall time of the traversal, seconds.
    pub seconds: f64,
}

/// A query's answer.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct QueryAnswer {
    /// Sorted ids: exact at level M; below M a superset of the exact answer.
    pub objects: Vec<ObjectId>,
    /// The application's key of each of `objects`, in the same order.
    pub keys: Vec<Key>,
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
    /// What the traversal did.
    pub stats: TraverseStats,
}

impl QueryAnswer {
    /// Drops `id` from the answer (a collision query's own object).
    pub(crate) fn without(mut self, id: ObjectId) -> QueryAnswer {
        if let Ok(i) = self.objects.binary_search(&id) {
            self.objects.remove(i);
            self.keys.remove(i);
        }
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
