//! `mktree verify`: a file's exact answers against the scene it was built
//! from, for scenes too large to hold in memory (`mktree_bench::verify_tree`).

use std::path::Path;
use std::time::Instant;

use anyhow::{Result, bail};
use mktree::scene::import::ImportOptions;
use serde_json::json;

use crate::input::{folder_of, open_to_read};
use crate::output;

pub fn run(file: &Path, scene: &Path, queries: u32, options: &ImportOptions, as_json: bool) -> Result<()> {
    let started = Instant::now();
    let db = open_to_read(file)?;
    let r = db.begin_read()?;
    let Some(info) = r.info() else { bail!("{} holds no tree", file.display()) };
    // The scene's old vertices wait beside the file, as in a staged build.
    let v = mktree_bench::verify_tree(&r, queries, scene, options, folder_of(file))?;
    if v.scene_objects != info.objects {
        bail!(
            "{} has {} objects and {} has {}: not the scene of this file",
            scene.display(),
            v.scene_objects,
            file.display(),
            info.objects
        );
    }
    let (n, differ, found) = (v.per_kind, &v.differing_queries, v.objects_found);
    let seconds = started.elapsed().as_secs_f64();
    if as_json {
        output::json(&json!({
            "objects": info.objects,
            "box_queries": n,
            "collide_queries": n,
            "objects_found": found,
            "differing_queries": differ,
            "tree_seconds": v.tree_seconds,
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
        bail!("{} of {} queries differ from the exact scan: {differ:?}", differ.len(), v.queries);
    }
    Ok(())
}
