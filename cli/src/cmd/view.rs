//! `mktree view`: the view's cut through the levels of detail for one
//! camera, as JSON (pieces front to back, errors, block reads).

use std::path::Path;

use anyhow::{Context, Result};
use mktree::query::{ViewCut, ViewOptions};
use mktree::{Aabb, Point, View};
use serde_json::{Value, json};

use crate::args::ViewArgs;
use crate::output;

/// The camera of `args` (default: framing `scene`), its far distance
/// defaulting to `scene`'s farthest corner.
pub fn camera(args: &ViewArgs, scene: &Aabb) -> View {
    let Some(c) = args.camera else {
        let v = mktree::render::framing(scene, args.width_px, args.height_px, args.fov_deg);
        let v = View { near_mm: args.near.min(v.near_mm), ..v };
        return match args.far {
            Some(far) => View { far_mm: far, ..v },
            None => v.seeing_all_of(scene),
        };
    };
    let view = View {
        eye: Point::new(c[0], c[1], c[2]),
        target: Point::new(c[3], c[4], c[5]),
        fov_deg: args.fov_deg,
        width_px: args.width_px,
        height_px: args.height_px,
        near_mm: args.near,
        far_mm: args.far.unwrap_or(0.0),
    };
    if args.far.is_some() { view } else { view.seeing_all_of(scene) }
}

/// The options of `args`: its tolerance and budget.
pub fn options(args: &ViewArgs, shapes: bool) -> ViewOptions {
    ViewOptions { tolerance_px: args.tolerance, budget: args.budget, shapes }
}

/// A cut as JSON.
pub fn cut_json(cut: &ViewCut) -> Value {
    let pieces: Vec<Value> = cut
        .nodes
        .iter()
        .map(|n| {
            json!({
                "node": n.node.id, "parent": n.node.parent, "child": n.node.child,
                "level": n.level, "bound": n.bound, "aabb": n.aabb.to_array(),
                "objects": n.objects, "eps_mm": n.eps_mm, "distance_mm": n.distance_mm, "error_px": n.error_px,
            })
        })
        .collect();
    let r = &cut.stats.reads;
    json!({
        "pieces": pieces,
        "piece_count": cut.nodes.len(),
        "exact_objects": cut.exact_objects(),
        "max_error_px": cut.max_error_px,
        "tolerance_px": cut.tolerance_px,
        "budget": cut.budget,
        "block_reads": { "node": r.node, "geometry": r.geometry, "total": r.total() },
        "cache_hits": r.cache_hits,
        "seconds": cut.stats.seconds,
    })
}

pub fn run(file: &Path, args: &ViewArgs) -> Result<()> {
    let db = crate::cmd::open_to_read(file)?;
    let r = db.begin_read()?;
    let scene = r.root().map_or(Aabb::EMPTY, |n| n.aabb);
    let cut = r
        .view(&camera(args, &scene), &options(args, false), None)
        .with_context(|| format!("{}", file.display()))?;
    output::json(&cut_json(&cut))
}
