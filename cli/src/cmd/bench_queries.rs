//! `mktree bench-queries`: the same random box queries against each file,
//! with mean block reads by kind, answers and time per query size.

use std::path::PathBuf;

use anyhow::{Context, Result};
use mktree::geom::Aabb;
use mktree_bench::{WorkloadStats, random_boxes, run_boxes};
use serde::Serialize;

use crate::output;

#[derive(Serialize)]
struct Row {
    file: PathBuf,
    method: String,
    block_size: u32,
    file_bytes: u64,
    share: f64,
    #[serde(flatten)]
    stats: WorkloadStats,
}

pub fn run(files: &[PathBuf], queries: usize, shares: &[f64], seed: u64, as_json: bool) -> Result<()> {
    let mut rows = Vec::new();
    // One workload for all files: the union of their scene boxes.
    let mut dbs = Vec::new();
    let mut scene = Aabb::EMPTY;
    for f in files {
        let db = crate::input::open_to_read(f)?;
        let info = db.begin_read()?.info().with_context(|| format!("{} holds no tree", f.display()))?;
        scene = scene.union(&Aabb::from_array(info.scene_box));
        dbs.push((f, db, info));
    }
    for &share in shares {
        let boxes = random_boxes(&scene, queries, share, seed);
        for (f, db, info) in &dbs {
            let stats = run_boxes(&db.begin_read()?, &boxes)?;
            rows.push(Row {
                file: f.to_path_buf(),
                method: info.params.as_ref().map_or("?".into(), |p| p.method.name().to_string()),
                block_size: info.block_size,
                file_bytes: u64::from(info.file_blocks) * u64::from(info.block_size),
                share,
                stats,
            });
        }
    }
    if as_json {
        return output::json(&serde_json::json!({ "queries": queries, "seed": seed, "rows": rows }));
    }
    println!(
        "{queries} random box queries per size (sides a share of the scene extent), seed {seed}; means per query"
    );
    let table: Vec<Vec<String>> = rows
        .iter()
        .map(|r| {
            vec![
                r.file.display().to_string(),
                r.method.clone(),
                r.block_size.to_string(),
                format!("{:.0}%", r.share * 100.0),
                format!("{:.2}", r.stats.mean_node_reads),
                format!("{:.2}", r.stats.mean_geometry_reads),
                format!("{:.2}", r.stats.mean_total_reads),
                format!("{:.1}", r.stats.mean_objects),
                format!("{:.3}", r.stats.mean_milliseconds),
            ]
        })
        .collect();
    output::table(
        &["file", "method", "block", "box", "node reads", "geometry reads", "total reads", "objects", "ms"],
        &table,
    );
    Ok(())
}
