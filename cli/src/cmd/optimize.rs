//! `mktree optimize`: lays a changed tree out anew as a bulk load would.

use std::path::Path;

use anyhow::Result;
use mktree::db::{Database, WriterWait};
use serde_json::json;

use crate::output;

pub fn run(file: &Path, wait: bool, as_json: bool) -> Result<()> {
    let db = Database::open(file).map_err(|e| crate::input::opening(e, file))?;
    let shape = |db: &Database| -> Result<Option<(u32, u32, u32, u32)>> {
        Ok(db.begin_read()?.info().map(|i| (i.nodes, i.leaves, i.depth, i.node_blocks)))
    };
    let before = shape(&db)?;
    let mut w = db.begin_write_with(if wait { WriterWait::Wait } else { WriterWait::Fail })?;
    w.optimize()?;
    w.commit()?;
    let after = shape(&db)?;
    let part = |s: Option<(u32, u32, u32, u32)>| {
        s.map(|(nodes, leaves, depth, node_blocks)| {
            json!({ "nodes": nodes, "leaves": leaves, "depth": depth, "node_blocks": node_blocks })
        })
    };
    if as_json {
        return output::json(&json!({ "before": part(before), "after": part(after) }));
    }
    let line = |s: Option<(u32, u32, u32, u32)>| match s {
        Some((n, l, d, b)) => format!("{n} nodes, {l} leaves, depth {d}, {b} node blocks"),
        None => "no tree".to_string(),
    };
    println!("{}: {} -> {}", file.display(), line(before), line(after));
    Ok(())
}
