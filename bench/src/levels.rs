//! What the levels of detail below M do for exact collision queries: each
//! query (a scene object moved by a random translation, its own original
//! left out) is answered at level M twice from a cold pool, once with the
//! file's stored bounds and once with none below M (`bounds_up_to` 1), and
//! the two answers must be equal. The report has, per query, the block
//! reads of both and what each level decided: the objects ruled out (a box,
//! or a voxel bound, that misses the moved object) and proved (a face, or a
//! surface cell, that it holds), and at M those read and tested exactly.

use mktree::ReadTransaction;
use mktree::geom::Pose;
use mktree::query::{CollideOptions, QueryAnswer, QueryOptions, Triangles, collide, object_meshes};
use mktree::scene::{Mesh, ObjectId};
use serde::Serialize;

use crate::BenchError;
use crate::rng::Rng;

/// One collision query of [`collision_levels`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LevelsQuery {
    /// The scene object moved, and left out of its own answer.
    pub object: u32,
    /// Its translation, mm.
    pub translate: [f64; 3],
    /// Objects it touches or comes within the clearance of (level M).
    pub answer: usize,
    /// Block reads with the stored bounds of every level.
    pub reads: u64,
    /// Of which geometry blocks.
    pub geometry_reads: u64,
    /// Block reads of the same answer using no bound below M.
    pub reads_without_levels: u64,
    /// Of which geometry blocks.
    pub geometry_reads_without_levels: u64,
    /// Per level k = 1 ..= M (index k - 1): objects ruled out there.
    pub ruled_out: Vec<u64>,
    /// Per level k = 1 ..= M: objects proved to collide there.
    pub proved: Vec<u64>,
}

impl LevelsQuery {
    /// Objects decided below M, either way, at levels 2 ..= M - 1.
    pub fn decided_between(&self) -> u64 {
        let m = self.ruled_out.len();
        (1..m.saturating_sub(1)).map(|i| self.ruled_out[i] + self.proved[i]).sum()
    }

    /// Block reads the levels below M saved this query (negative: cost).
    pub fn reads_saved(&self) -> i64 {
        self.reads_without_levels as i64 - self.reads as i64
    }
}

/// Query objects with their translations, mm.
type Picks = Vec<(ObjectId, [f64; 3])>;

/// `count` scene objects drawn uniformly from `seed`, each with a
/// translation of up to `shift_mm` along each axis, and their meshes.
fn picks(
    txn: &ReadTransaction,
    count: usize,
    shift_mm: f64,
    seed: u64,
) -> Result<(Picks, Vec<Mesh>), BenchError> {
    let objects = txn.info().ok_or_else(|| BenchError::Invalid("the file holds no tree".into()))?.objects;
    if objects == 0 {
        return Err(BenchError::Invalid("the file's tree has no objects".into()));
    }
    let mut rng = Rng::new(seed, 0x1e7e15);
    let picks: Picks = (0..count)
        .map(|_| {
            let id = ObjectId(rng.below(u64::from(objects)) as u32);
            (id, [0; 3].map(|_| (2.0 * rng.unit() - 1.0) * shift_mm))
        })
        .collect();
    let ids: Vec<ObjectId> = picks.iter().map(|p| p.0).collect();
    let meshes = object_meshes(txn, &ids)?;
    Ok((picks, meshes))
}

/// The queries of [`collision_levels`] as probes for
/// [`mktree::query::tradeoff`]: each moved mesh grown by `clearance_mm`
/// (its own object's original is then among its answers).
pub fn clearance_workload(
    txn: &ReadTransaction,
    count: usize,
    shift_mm: f64,
    clearance_mm: f64,
    seed: u64,
) -> Result<Vec<Triangles>, BenchError> {
    let (picks, meshes) = picks(txn, count, shift_mm, seed)?;
    picks
        .iter()
        .zip(&meshes)
        .map(|(&(id, translate), mesh)| {
            let pose = Pose::from_degrees(translate, [0.0; 3])
                .map_err(|e| BenchError::Invalid(format!("object {}: {e}", id.0)))?;
            Triangles::posed(mesh, &pose, clearance_mm)
                .map_err(|e| BenchError::Invalid(format!("object {}: {e}", id.0)))
        })
        .collect()
}

/// `count` collision queries on `txn`'s tree, each a scene object drawn
/// uniformly from `seed` and moved by up to `shift_mm` along each axis,
/// asking for the objects within `clearance_mm` of it, answered with and
/// without the levels below M (see the module's note).
pub fn collision_levels(
    txn: &ReadTransaction,
    count: usize,
    shift_mm: f64,
    clearance_mm: f64,
    seed: u64,
) -> Result<Vec<LevelsQuery>, BenchError> {
    let (picks, meshes) = picks(txn, count, shift_mm, seed)?;
    picks
        .iter()
        .zip(&meshes)
        .map(|(&(id, translate), mesh)| {
            let pose = Pose::from_degrees(translate, [0.0; 3])
                .map_err(|e| BenchError::Invalid(format!("object {}: {e}", id.0)))?;
            let answer = |bounds_up_to: Option<u8>| -> Result<QueryAnswer, BenchError> {
                let query = QueryOptions { bounds_up_to, ..QueryOptions::default() };
                let opts = CollideOptions { query, clearance: clearance_mm, exclude: Some(id) };
                Ok(collide(txn, mesh, &pose, &opts, None)?)
            };
            let (with, without) = (answer(None)?, answer(Some(1))?);
            if with.objects != without.objects {
                return Err(BenchError::Invalid(format!(
                    "object {} moved by {translate:?}: {} objects with the levels, {} without",
                    id.0,
                    with.objects.len(),
                    without.objects.len()
                )));
            }
            Ok(LevelsQuery {
                object: id.0,
                translate,
                answer: with.objects.len(),
                reads: with.stats.reads.total(),
                geometry_reads: with.stats.reads.geometry,
                reads_without_levels: without.stats.reads.total(),
                geometry_reads_without_levels: without.stats.reads.geometry,
                ruled_out: per_level(&with, false),
                proved: per_level(&with, true),
            })
        })
        .collect()
}

/// Per level k = 1 ..= M: the objects of `a` (its own object left out)
/// accepted, or rejected, there.
fn per_level(a: &QueryAnswer, accepted: bool) -> Vec<u64> {
    let mut counts = vec![0; usize::from(a.level)];
    for d in a.decided.iter().filter(|d| d.accepted == accepted) {
        if let Some(c) = counts.get_mut(usize::from(d.level).wrapping_sub(1)) {
            *c += 1;
        }
    }
    counts
}
