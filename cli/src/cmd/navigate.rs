//! `mktree navigate`: frustum queries along a camera path through one LRU
//! pool; reads and hits per step.

use std::path::Path;

use anyhow::{Context, Result};
use mktree::geom::Camera;
use mktree::query::{QueryOptions, navigate, parse_path};
use serde_json::json;

use crate::output;

/// `lens` is the frustum's fov (degrees), aspect, near and far (mm).
pub fn run(
    file: &Path,
    path: &Path,
    cache_blocks: usize,
    lens: [f64; 4],
    lod: Option<u8>,
    as_json: bool,
) -> Result<()> {
    let text = std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    let cameras: Vec<Camera> = parse_path(&text)
        .with_context(|| format!("{}", path.display()))?
        .into_iter()
        .map(|(eye, target)| Camera {
            eye,
            target,
            fov_deg: lens[0],
            aspect: lens[1],
            near: lens[2],
            far: lens[3],
        })
        .collect();
    let db = crate::cmd::open_to_read(file)?;
    let r = db.begin_read()?;
    let steps = navigate(&r, &cameras, &QueryOptions { lod, ..Default::default() }, cache_blocks)?;
    let total: u64 = steps.iter().map(|s| s.reads.total()).sum();
    let hits: u64 = steps.iter().map(|s| s.reads.cache_hits).sum();
    if as_json {
        let rows: Vec<_> = steps
            .iter()
            .map(|s| {
                json!({
                    "step": s.step,
                    "objects": s.objects,
                    "block_reads": {
                        "node": s.reads.node, "geometry": s.reads.geometry, "total": s.reads.total()
                    },
                    "cache_hits": s.reads.cache_hits,
                    "seconds": s.seconds,
                })
            })
            .collect();
        return output::json(&json!({
            "steps": rows, "cache_blocks": cache_blocks, "block_reads_total": total, "cache_hits_total": hits
        }));
    }
    let rows: Vec<Vec<String>> = steps
        .iter()
        .map(|s| {
            vec![
                s.step.to_string(),
                s.objects.len().to_string(),
                s.reads.node.to_string(),
                s.reads.geometry.to_string(),
                s.reads.total().to_string(),
                s.reads.cache_hits.to_string(),
                format!("{:.2}", s.seconds * 1e3),
            ]
        })
        .collect();
    output::table(&["step", "objects", "node", "geometry", "reads", "hits", "ms"], &rows);
    println!("{} steps: {total} reads, {hits} hits, pool of {cache_blocks} blocks", steps.len());
    Ok(())
}
