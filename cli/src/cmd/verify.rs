//! `mktree verify`: a file's exact answers against the scene it was built
//! from, for scenes too large to hold in memory. Box queries around, and
//! collision queries with moved copies of, objects spread evenly over the
//! ids are answered by the tree, then by one streaming pass over the scene
//! that tests every object exactly ([`ScanOracle`]).

use std::path::Path;
use std::time::Instant;

use anyhow::{Result, bail};
use mktree::geom::{Aabb, Pose, Vector};
use mktree::query::{
    CollideOptions, QueryOptions, Region, ScanOracle, Selection, Triangles, collide, object_meshes,
    query_region,
};
use mktree::scene::ObjectId;
use mktree::scene::import::{ImportOptions, load_each};
use serde_json::json;

use crate::output;

pub fn run(file: &Path, scene: &Path, queries: u32, options: &ImportOptions, as_json: bool) -> Result<()> {
    let started = Instant::now();
    let db = crate::cmd::open_to_read(file)?;
    let r = db.begin_read()?;
    let Some(info) = r.info() else { bail!("{} holds no tree", file.display()) };
    if info.objects == 0 || queries == 0 {
        bail!("nothing to verify: {} objects, {queries} queries", info.objects);
    }
    let n = queries.min(info.objects);
    // Every (objects / n)-th object, from the middle of the first stride.
    let ids: Vec<ObjectId> = (0..n)
        .map(|i| ObjectId(((u64::from(i) * 2 + 1) * u64::from(info.objects) / (2 * u64::from(n))) as u32))
        .collect();
    let meshes = object_meshes(&r, &ids)?;
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
    let probes: Vec<Triangles> =
        meshes.iter().zip(&poses).map(|(m, p)| Triangles::posed(m, p, 0.0)).collect::<Result<_, _>>()?;
    let mut tree_answers: Vec<Vec<ObjectId>> = Vec::new();
    let opts = QueryOptions::default();
    for region in &regions {
        tree_answers.push(query_region(&r, region, &opts, None)?.objects);
    }
    let collide_opts = CollideOptions { query: opts, clearance: 0.0, exclude: None };
    for (m, p) in meshes.iter().zip(&poses) {
        tree_answers.push(collide(&r, m, p, &collide_opts, None)?.objects);
    }
    let tree_seconds = started.elapsed().as_secs_f64();
    let all: Vec<&dyn Selection> = regions
        .iter()
        .map(|x| x as &dyn Selection)
        .chain(probes.iter().map(|x| x as &dyn Selection))
        .collect();
    let mut oracle = ScanOracle::new(&all);
    // The scene's old vertices wait beside the file, as in a staged build.
    load_each(scene, options, Some(crate::cmd::folder_of(file)), &mut |object| oracle.offer(&object.mesh))?;
    if oracle.objects() != info.objects {
        bail!(
            "{} has {} objects and {} has {}: not the scene of this file",
            scene.display(),
            oracle.objects(),
            file.display(),
            info.objects
        );
    }
    let exact = oracle.answers();
    let differ: Vec<usize> = (0..all.len()).filter(|&i| tree_answers[i] != exact[i]).collect();
    let found: usize = exact.iter().map(Vec::len).sum();
    let seconds = started.elapsed().as_secs_f64();
    if as_json {
        output::json(&json!({
            "objects": info.objects,
            "box_queries": n,
            "collide_queries": n,
            "objects_found": found,
            "differing_queries": differ,
            "tree_seconds": tree_seconds,
            "seconds": seconds,
        }))?;
    } else {
        println!(
            "{}: {n} box and {n} collision queries, {found} objects found, {} differ from a scan of {} ({:.1} s)",
            file.display(),
            differ.len(),
            scene.display(),
            seconds
        );
    }
    if !differ.is_empty() {
        bail!("{} of {} queries differ from the exact scan: {differ:?}", differ.len(), all.len());
    }
    Ok(())
}
