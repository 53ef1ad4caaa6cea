//! `mktree render`: a picture of the view's cut (or of one node's level of
//! detail) drawn by the library's rasterizer, written as PNG.

use std::path::Path;

use anyhow::{Context, Result};
use mktree::render::{draw_cut, draw_level};
use mktree::store::ReadStats;
use serde_json::json;

use crate::args::ViewArgs;
use crate::output;

/// What to draw.
pub enum What {
    /// The view's cut at the tolerance.
    Cut,
    /// Node `node`'s level `k`: B(S_n,k) with `objects`, else b(S_n,k).
    Node { node: u32, k: u8, objects: bool },
}

pub fn run(file: &Path, args: &ViewArgs, what: What, out: &Path, as_json: bool) -> Result<()> {
    let db = crate::input::open_to_read(file)?;
    let r = db.begin_read()?;
    let m = db.lod_levels();
    let (img, summary) = match what {
        What::Cut => {
            let scene = r.root().map_or(mktree::Aabb::EMPTY, |n| n.aabb);
            let view = args.view(&scene);
            let cut = r
                .view(&view, &args.view_options(true), None)
                .with_context(|| format!("{}", file.display()))?;
            let img = draw_cut(&view, &cut, m)?;
            let mut s = output::cut_json(&cut);
            // The pieces are in `mktree view`; the picture's summary is enough here.
            s["pieces"] = json!(null);
            (img, s)
        }
        What::Node { node, k, objects } => {
            let (at, _) = r.locate(node)?;
            let view = args.view(&at.aabb);
            let mut reads = ReadStats::default();
            let level = r.fetch_level(node, k, objects, &mut reads)?;
            let img = draw_level(&view, &level, k, m, !objects)?;
            let s = json!({
                "node": node, "level": k, "bound": if objects { "object_bounds" } else { "group_bound" },
                "faces": level.faces(), "bytes": level.bytes,
                "block_reads": { "node": reads.node, "geometry": reads.geometry, "total": reads.total() },
            });
            (img, s)
        }
    };
    output::write_png(&img, out)?;
    let mut s = summary;
    s["output"] = json!(out.display().to_string());
    s["pixels_drawn"] = json!(img.coverage());
    if as_json {
        return output::json(&s);
    }
    println!(
        "{}: {} x {} px, {} drawn; {} block reads",
        out.display(),
        img.width,
        img.height,
        img.coverage(),
        s["block_reads"]["total"]
    );
    Ok(())
}
