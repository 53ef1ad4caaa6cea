//! `mktree tradeoff`: the same random collision queries at every level of
//! every file: block reads, time and precision per level, and the chart.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use mktree::query::{TRADEOFF_SHIFT_MM, TradeoffRow, collision_workload, tradeoff};
use serde_json::json;

use crate::chart::{self, Tradeoff};
use crate::output;

pub fn run(files: &[PathBuf], queries: usize, seed: u64, out: &Path, as_json: bool) -> Result<()> {
    let mut results: Vec<(String, Vec<TradeoffRow>)> = Vec::new();
    for file in files {
        let db = crate::input::open_to_read(file)?;
        let r = db.begin_read()?;
        // The same seed draws the same objects and moves in files of one scene.
        let workload =
            collision_workload(&r, queries, seed).with_context(|| format!("{}", file.display()))?;
        let rows = tradeoff(&r, &workload).with_context(|| format!("{}", file.display()))?;
        results.push((file.display().to_string(), rows));
    }
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let (svg, png) = (out.join("tradeoff.svg"), out.join("tradeoff.png"));
    let series: Vec<Tradeoff> = results
        .iter()
        .map(|(name, rows)| Tradeoff {
            name: name.clone(),
            points: rows.iter().map(|r| (r.mean_reads, r.precision, r.level)).collect(),
        })
        .collect();
    chart::tradeoff(&series, &svg, &png)?;
    if as_json {
        let files: Vec<_> = results.iter().map(|(f, rows)| json!({ "file": f, "levels": rows })).collect();
        return output::json(&json!({
            "queries": queries, "seed": seed, "shift_mm": TRADEOFF_SHIFT_MM, "files": files,
            "chart": { "svg": svg, "png": png },
        }));
    }
    for (file, rows) in &results {
        println!(
            "{file}: {queries} collision queries (objects moved up to {TRADEOFF_SHIFT_MM} mm), seed {seed}"
        );
        let table: Vec<Vec<String>> = rows
            .iter()
            .map(|r| {
                vec![
                    r.level.to_string(),
                    format!("{:.2}", r.mean_reads),
                    format!("{:.2}", r.mean_node_reads),
                    r.stored_bounds.to_string(),
                    format!("{:.2}", r.mean_geometry_reads),
                    format!("{:.3}", r.mean_milliseconds),
                    format!("{:.2}", r.mean_reported),
                    format!("{:.2}", r.mean_exact),
                    format!("{:.3}", r.precision),
                ]
            })
            .collect();
        output::table(
            &["k", "reads", "node", "bounds stored", "geometry", "ms", "reported", "exact", "precision"],
            &table,
        );
    }
    println!("chart: {} and {}", svg.display(), png.display());
    Ok(())
}
