//! `mktree clash`: every pair of objects within a clearance, with the reads
//! set against the file's blocks.

use std::path::Path;

use anyhow::Result;
use mktree::query::{ClashOptions, clash};
use serde_json::json;

use crate::output;

pub fn run(file: &Path, clearance: f64, lod: Option<u8>, as_json: bool) -> Result<()> {
    let db = crate::input::open_to_read(file)?;
    let r = db.begin_read()?;
    let a = clash(&r, &ClashOptions { lod, clearance }, None)?;
    let s = &a.stats;
    if as_json {
        return output::json(&json!({
            "pairs": a.pairs.iter().map(|p| [p.0, p.1]).collect::<Vec<_>>(),
            "level": a.level,
            "clearance": clearance,
            "block_reads": {
                "node": s.reads.node, "geometry": s.reads.geometry, "total": s.reads.total()
            },
            "cache_hits": s.reads.cache_hits,
            "file_blocks": a.file_blocks,
            "nodes_visited": s.nodes_visited,
            "leaves_visited": s.leaves_visited,
            "confirmed_per_level": s.confirmed,
            "rejected_per_level": s.rejected,
            "geometry_tests": s.geometry_tests,
            "triangles_tested": s.triangles_tested,
            "seconds": s.seconds,
        }));
    }
    println!("{} pairs at level {} within {clearance} mm", a.pairs.len(), a.level);
    for (x, y) in &a.pairs {
        println!("{x} {y}");
    }
    println!(
        "block reads: {} node + {} geometry = {} of the file's {} blocks; geometry tests {}; {:.1} ms",
        s.reads.node,
        s.reads.geometry,
        s.reads.total(),
        a.file_blocks,
        s.geometry_tests,
        s.seconds * 1e3
    );
    Ok(())
}
