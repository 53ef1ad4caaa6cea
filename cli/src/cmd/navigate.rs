//! `mktree navigate`: frustum queries along a camera path through one LRU
//! pool, or the view's cut per step (`--tolerance`); reads and hits per step.

use std::path::Path;

use anyhow::{Context, Result};
use mktree::View;
use mktree::geom::Camera;
use mktree::query::{QueryOptions, ViewOptions, navigate, navigate_view, parse_path};
use serde_json::json;

use crate::output;

/// The cameras of the path file `path` with `lens` (fov, aspect, near, far).
fn cameras(path: &Path, lens: [f64; 4]) -> Result<Vec<Camera>> {
    let text = std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    Ok(parse_path(&text)
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
        .collect())
}

/// The view's cut per step of the path through one pool: pieces, exact
/// objects, the largest projected error, reads and hits.
pub fn run_view(
    file: &Path,
    path: &Path,
    cache_blocks: usize,
    lens: [f64; 4],
    height_px: u32,
    opts: &ViewOptions,
    as_json: bool,
) -> Result<()> {
    let width_px = (f64::from(height_px) * lens[1]).round() as u32;
    let views: Vec<View> = cameras(path, lens)?
        .into_iter()
        .map(|c| View {
            eye: c.eye,
            target: c.target,
            fov_deg: c.fov_deg,
            width_px,
            height_px,
            near_mm: c.near,
            far_mm: c.far,
        })
        .collect();
    let db = crate::input::open_to_read(file)?;
    let r = db.begin_read()?;
    let cuts = navigate_view(&r, &views, opts, cache_blocks)?;
    let total: u64 = cuts.iter().map(|c| c.stats.reads.total()).sum();
    let hits: u64 = cuts.iter().map(|c| c.stats.reads.cache_hits).sum();
    if as_json {
        let steps: Vec<_> = cuts
            .iter()
            .enumerate()
            .map(|(i, c)| {
                let mut v = crate::output::cut_json(c);
                v["step"] = json!(i);
                v
            })
            .collect();
        return output::json(&json!({
            "steps": steps, "cache_blocks": cache_blocks, "block_reads_total": total, "cache_hits_total": hits
        }));
    }
    let rows: Vec<Vec<String>> = cuts
        .iter()
        .enumerate()
        .map(|(i, c)| {
            let r = &c.stats.reads;
            vec![
                i.to_string(),
                c.nodes.len().to_string(),
                c.exact_objects().to_string(),
                format!("{:.2}", c.max_error_px),
                r.node.to_string(),
                r.geometry.to_string(),
                r.total().to_string(),
                r.cache_hits.to_string(),
                format!("{:.2}", c.stats.seconds * 1e3),
            ]
        })
        .collect();
    output::table(&["step", "pieces", "exact", "max_px", "node", "geometry", "reads", "hits", "ms"], &rows);
    println!(
        "{} steps at tau {} px: {total} reads, {hits} hits, pool of {cache_blocks} blocks",
        cuts.len(),
        opts.tolerance_px
    );
    Ok(())
}

/// `lens` is the frustum's fov (degrees), aspect, near and far (mm).
pub fn run(
    file: &Path,
    path: &Path,
    cache_blocks: usize,
    lens: [f64; 4],
    lod: Option<u8>,
    as_json: bool,
) -> Result<()> {
    let cameras = cameras(path, lens)?;
    let db = crate::input::open_to_read(file)?;
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
