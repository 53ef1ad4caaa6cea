//! Speed against accuracy: the same collision queries at every level k,
//! with block reads, time, and the precision of the reported set against
//! the exact one (level M). Recall must be 1: a level that misses an object
//! is an error, not a data point.

use serde::Serialize;

use super::QueryError;
use super::collide::object_meshes;
use super::select::Triangles;
use super::{QueryOptions, levels, traverse};
use crate::geom::Pose;
use crate::rng::Rng;
use crate::scene::ObjectId;
use crate::tree::ReadTransaction;

/// How far a workload moves each object on every axis, mm at most.
pub const TRADEOFF_SHIFT_MM: f64 = 100.0;

/// One level's means over the queries.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TradeoffRow {
    /// The level k the queries were answered at.
    pub level: u8,
    /// Mean block reads per query.
    pub mean_reads: f64,
    /// Mean node-block reads per query.
    pub mean_node_reads: f64,
    /// Bounds the file stores at this level (none: the level answers as the one below).
    pub stored_bounds: u64,
    /// Mean geometry-block reads per query.
    pub mean_geometry_reads: f64,
    /// Mean wall time per query, milliseconds.
    pub mean_milliseconds: f64,
    /// Exact answers over reported ones, over all queries (1 when none reported).
    pub precision: f64,
    /// Mean objects reported per query.
    pub mean_reported: f64,
    /// Mean objects in the exact answer per query.
    pub mean_exact: f64,
}

/// `count` collision queries: scene objects drawn uniformly (from `seed`),
/// each moved by a random translation of up to `TRADEOFF_SHIFT_MM` per axis.
pub fn collision_workload(
    txn: &ReadTransaction,
    count: usize,
    seed: u64,
) -> Result<Vec<Triangles>, QueryError> {
    let objects = txn.info().ok_or(QueryError::NoTree)?.objects;
    let mut rng = Rng::new(seed);
    let picks: Vec<(ObjectId, [f64; 3])> = (0..count)
        .map(|_| {
            let id = ObjectId(rng.below(u64::from(objects)) as u32);
            (id, [0; 3].map(|_| rng.range(-TRADEOFF_SHIFT_MM, TRADEOFF_SHIFT_MM)))
        })
        .collect();
    let ids: Vec<ObjectId> = picks.iter().map(|p| p.0).collect();
    let meshes = object_meshes(txn, &ids)?;
    picks
        .iter()
        .zip(&meshes)
        .map(|((_, t), mesh)| Ok(Triangles::posed(mesh, &Pose::from_degrees(*t, [0.0; 3])?, 0.0)?))
        .collect()
}

/// Runs every query at level 1, at every level below M that stores bounds
/// (a level that stores none answers as the one below it), and at M, each
/// from a cold pool.
pub fn tradeoff(txn: &ReadTransaction, queries: &[Triangles]) -> Result<Vec<TradeoffRow>, QueryError> {
    let (m, _) = levels(txn, None)?;
    let at = |k: u8, q: &Triangles| {
        traverse(txn, q, &QueryOptions { lod: Some(k), budget: None, ..Default::default() }, None)
    };
    let exact: Vec<Vec<ObjectId>> =
        queries.iter().map(|q| Ok(at(m, q)?.objects)).collect::<Result<_, QueryError>>()?;
    let n = queries.len().max(1) as f64;
    let stored: Vec<u64> = txn.lod_info().map_or(Vec::new(), |i| i.stored);
    (1..=m)
        .filter(|&k| k == 1 || k == m || stored.get(usize::from(k) - 1).is_some_and(|&s| s > 0))
        .map(|k| {
            let mut row = TradeoffRow {
                level: k,
                mean_reads: 0.0,
                mean_node_reads: 0.0,
                stored_bounds: stored.get(usize::from(k) - 1).copied().unwrap_or(0),
                mean_geometry_reads: 0.0,
                mean_milliseconds: 0.0,
                precision: 1.0,
                mean_reported: 0.0,
                mean_exact: 0.0,
            };
            let (mut reported, mut right) = (0usize, 0usize);
            for (i, (q, truth)) in queries.iter().zip(&exact).enumerate() {
                let a = at(k, q)?;
                if let Some(o) = truth.iter().find(|o| a.objects.binary_search(o).is_err()) {
                    return Err(QueryError::Missed { k, query: i, object: o.0 });
                }
                let r = &a.stats.reads;
                row.mean_reads += r.total() as f64 / n;
                row.mean_node_reads += r.node as f64 / n;
                row.mean_geometry_reads += r.geometry as f64 / n;
                row.mean_milliseconds += a.stats.seconds * 1e3 / n;
                reported += a.objects.len();
                right += truth.len();
            }
            if reported > 0 {
                row.precision = right as f64 / reported as f64;
            }
            row.mean_reported = reported as f64 / n;
            row.mean_exact = right as f64 / n;
            Ok(row)
        })
        .collect()
}

/// What the bounds stored up to one level are worth, measured.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LevelBenefit {
    /// The finest level whose stored bounds are used.
    pub level: u8,
    /// Mean block reads of an exact answer to the read model's queries when
    /// the bounds of levels up to `level` are used (level 1: none).
    pub mean_reads: f64,
}

/// The measured benefit of each level below M: `per_scale` queries of each
/// scale of the file's read model (`QueryMix`, its query extent from the
/// meta block), centred evenly in the scene, answered exactly with the
/// bounds of levels up to k, k = 1 .. M - 1. What level k saves is the
/// drop from k - 1 to k.
pub fn level_benefit(txn: &ReadTransaction, per_scale: usize) -> Result<Vec<LevelBenefit>, QueryError> {
    let (m, _) = levels(txn, None)?;
    let info = txn.info().ok_or(QueryError::NoTree)?;
    let q = txn.lod_info().map_or([0.0; 3], |l| l.query_extent);
    let scene = crate::geom::Aabb::from_array(info.scene_box);
    let queries = crate::bulk::QueryMix::new(&scene, q).sample_centred(&scene, per_scale);
    let n = queries.len().max(1) as f64;
    (1..m.max(2))
        .map(|k| {
            let opts = QueryOptions { bounds_up_to: Some(k), ..Default::default() };
            let mut reads = 0u64;
            for b in &queries {
                reads += traverse(txn, &super::Region::Box(*b), &opts, None)?.stats.reads.total();
            }
            Ok(LevelBenefit { level: k, mean_reads: reads as f64 / n })
        })
        .collect()
}
