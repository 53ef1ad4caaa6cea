//! A file's exact answers against the scene it was built from (`mktree
//! verify`), for scenes too large to hold in memory: box queries around,
//! and collision queries with moved copies of, objects spread evenly over
//! the ids are answered by the tree, then by one streaming pass over the
//! scene that tests every object exactly (`ScanOracle`).

use std::path::Path;
use std::time::Instant;

use mktree::db::ReadTransaction;
use mktree::geom::{Aabb, Pose, Vector};
use mktree::query::{
    CollideOptions, QueryOptions, Region, ScanOracle, Selection, Triangles, collide, object_meshes,
    query_region,
};
use mktree::scene::ObjectId;
use mktree::scene::import::{ImportOptions, load_each};

use crate::BenchError;

/// What the tree answered against the scan.
#[derive(Debug, Clone, PartialEq)]
pub struct Verification {
    /// Box queries, and as many collision queries.
    pub per_kind: u32,
    /// Objects the scan of the scene met.
    pub scene_objects: u32,
    /// Objects the exact answers hold, over all queries.
    pub objects_found: usize,
    /// The queries whose answer differs from the scan's (boxes first, then
    /// collisions).
    pub differing_queries: Vec<usize>,
    /// All queries run.
    pub queries: usize,
    /// Seconds the tree took to answer.
    pub tree_seconds: f64,
}

/// Verifies the tree of `r` with `queries` queries of each kind against
/// the scene at `scene`, whose old vertices wait in `spill_dir` as in a
/// staged build. The tree must hold objects, and `queries` be positive.
pub fn verify_tree(
    r: &ReadTransaction,
    queries: u32,
    scene: &Path,
    options: &ImportOptions,
    spill_dir: &Path,
) -> Result<Verification, BenchError> {
    let started = Instant::now();
    let objects = r.info().map_or(0, |i| i.objects);
    if objects == 0 || queries == 0 {
        return Err(BenchError::Invalid(format!("nothing to verify: {objects} objects, {queries} queries")));
    }
    let n = queries.min(objects);
    // Every (objects / n)-th object, from the middle of the first stride.
    let ids: Vec<ObjectId> = (0..n)
        .map(|i| ObjectId(((u64::from(i) * 2 + 1) * u64::from(objects) / (2 * u64::from(n))) as u32))
        .collect();
    let meshes = object_meshes(r, &ids)?;
    // A box around each object grown by half its size; a copy of each moved
    // by a third of its size along x and y, so it touches its neighbours.
    let regions: Vec<Region> = meshes
        .iter()
        .map(|m| {
            let b = m.aabb();
            let grow = b.extent() * 0.5;
            Region::Box(Aabb::new(b.min - grow, b.max + grow))
        })
        .collect();
    let poses: Vec<Pose> = meshes
        .iter()
        .map(|m| {
            let e = m.aabb().extent();
            Pose { translation: Vector::new(e.x / 3.0, e.y / 3.0, 0.0), ..Pose::default() }
        })
        .collect();
    let probes: Vec<Triangles> = meshes
        .iter()
        .zip(&poses)
        .map(|(m, p)| Triangles::posed(m, p, 0.0))
        .collect::<Result<_, _>>()
        .map_err(|e| BenchError::Invalid(e.to_string()))?;
    let mut tree_answers: Vec<Vec<ObjectId>> = Vec::new();
    let opts = QueryOptions::default();
    for region in &regions {
        tree_answers.push(query_region(r, region, &opts, None)?.objects);
    }
    let collide_opts = CollideOptions { query: opts, clearance: 0.0, exclude: None };
    for (m, p) in meshes.iter().zip(&poses) {
        tree_answers.push(collide(r, m, p, &collide_opts, None)?.objects);
    }
    let tree_seconds = started.elapsed().as_secs_f64();
    let all: Vec<&dyn Selection> = regions
        .iter()
        .map(|x| x as &dyn Selection)
        .chain(probes.iter().map(|x| x as &dyn Selection))
        .collect();
    let mut oracle = ScanOracle::new(&all);
    load_each(scene, options, Some(spill_dir), &mut |object| oracle.offer(&object.mesh))
        .map_err(mktree::Error::from)?;
    let scene_objects = oracle.objects();
    let exact = oracle.answers();
    Ok(Verification {
        per_kind: n,
        scene_objects,
        objects_found: exact.iter().map(Vec::len).sum(),
        differing_queries: (0..all.len()).filter(|&i| tree_answers[i] != exact[i]).collect(),
        queries: all.len(),
        tree_seconds,
    })
}
