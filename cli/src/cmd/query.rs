//! `mktree query`: a box, sphere or frustum query at level k through the
//! file, with its block reads; also the JSON and text every single-shape
//! query prints (collide uses them).

use std::path::Path;

use anyhow::{Result, bail};
use mktree::geom::{Aabb, Camera, Frustum, Point, Sphere};
use mktree::query::{QueryAnswer, QueryOptions, Region, query_region};
use serde_json::{Value, json};

use crate::output;

/// The region the flags name (clap lets exactly one through).
pub fn shape(aabb: Option<[f64; 6]>, sphere: Option<[f64; 4]>, frustum: Option<[f64; 10]>) -> Result<Region> {
    Ok(match (aabb, sphere, frustum) {
        (Some(b), _, _) => Region::Box(Aabb::from_array(b)),
        (_, Some(s), _) => Region::Sphere(Sphere::new(Point::new(s[0], s[1], s[2]), s[3])?),
        (_, _, Some(f)) => Region::Frustum(Box::new(Frustum::from_camera(&Camera {
            eye: Point::new(f[0], f[1], f[2]),
            target: Point::new(f[3], f[4], f[5]),
            fov_deg: f[6],
            aspect: f[7],
            near: f[8],
            far: f[9],
        })?)),
        _ => bail!("one of --box, --sphere, --frustum is needed"),
    })
}

pub fn run(file: &Path, region: &Region, opts: &QueryOptions, as_json: bool) -> Result<()> {
    let db = crate::cmd::open_to_read(file)?;
    let r = db.begin_read()?;
    print(&query_region(&r, region, opts, None)?, as_json)
}

/// An answer's JSON: the CLI contract's keys, then the traversal's statistics.
pub fn answer_json(a: &QueryAnswer) -> Value {
    let s = &a.stats;
    json!({
        "objects": a.objects,
        "keys": a.keys,
        "maybe": a.maybe,
        "unexplored_nodes": a.unexplored_nodes,
        "level": a.level,
        "level_reached": a.level_reached,
        "block_reads": {
            "node": s.reads.node, "geometry": s.reads.geometry, "total": s.reads.total()
        },
        "cache_hits": s.reads.cache_hits,
        "nodes_visited": s.nodes_visited,
        "leaves_visited": s.leaves_visited,
        "confirmed_per_level": s.confirmed,
        "rejected_per_level": s.rejected,
        "subtrees_pruned": s.pruned,
        "geometry_tests": s.geometry_tests,
        "triangles_tested": s.triangles_tested,
        "decided": a.decided,
        "seconds": s.seconds,
    })
}

/// Prints an answer as JSON or two lines of text.
pub fn print(a: &QueryAnswer, as_json: bool) -> Result<()> {
    if as_json {
        return output::json(&answer_json(a));
    }
    let s = &a.stats;
    println!(
        "{} objects at level {}: {:?}",
        a.objects.len(),
        a.level,
        a.objects.iter().map(|o| o.0).collect::<Vec<_>>()
    );
    if a.level_reached < a.level || !a.maybe.is_empty() || a.unexplored_nodes > 0 {
        println!(
            "budget reached: level {} reached, {} maybe {:?}, {} subtrees unexplored",
            a.level_reached,
            a.maybe.len(),
            a.maybe.iter().map(|o| o.0).collect::<Vec<_>>(),
            a.unexplored_nodes
        );
    }
    println!(
        "block reads: {} node + {} geometry = {}; {} nodes, {} leaves; {:.3} ms",
        s.reads.node,
        s.reads.geometry,
        s.reads.total(),
        s.nodes_visited,
        s.leaves_visited,
        s.seconds * 1e3
    );
    println!(
        "decided per level k = 1 ..: confirmed {:?}, rejected {:?}; {} subtrees pruned; geometry read for {}",
        s.confirmed, s.rejected, s.pruned, s.geometry_tests
    );
    Ok(())
}
