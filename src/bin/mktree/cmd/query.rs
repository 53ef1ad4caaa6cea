//! `mktree query`: a box query through the file, with its block reads.

use std::path::Path;

use anyhow::{Context, Result};
use mktree::db::Database;
use mktree::geom::Aabb;
use serde_json::json;

use crate::output;

pub fn run(file: &Path, b: &[f64; 6], as_json: bool) -> Result<()> {
    let db = Database::open(file).with_context(|| format!("opening {}", file.display()))?;
    let r = db.begin_read()?;
    let res = r.query_box(&Aabb::from_array(*b))?;
    let s = &res.stats;
    if as_json {
        return output::json(&json!({
            "objects": res.objects,
            "block_reads": { "node": s.reads.node, "geometry": s.reads.geometry, "total": s.reads.total() },
            "cache_hits": s.reads.cache_hits,
            "nodes_visited": s.nodes_visited,
            "leaves_visited": s.leaves_visited,
            "objects_tested": s.objects_tested,
            "triangles_tested": s.triangles_tested,
            "seconds": s.seconds,
        }));
    }
    println!("{} objects: {:?}", res.objects.len(), res.objects.iter().map(|o| o.0).collect::<Vec<_>>());
    println!(
        "block reads: {} node + {} geometry = {}; {} nodes, {} leaves, {} objects tested; {:.3} ms",
        s.reads.node,
        s.reads.geometry,
        s.reads.total(),
        s.nodes_visited,
        s.leaves_visited,
        s.objects_tested,
        s.seconds * 1e3
    );
    Ok(())
}
