//! `mktree bench-peers`: mktree against SQLite's R*Tree with geometry blobs
//! (and rstar as a reference line) on the same scenes and queries, through
//! `mktree_bench::bench_scene`. A markdown table, or JSON; with `--out`,
//! bench-peers.json and a chart of the read ratios (SVG and PNG).

use std::io::IsTerminal;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, anyhow};
use mktree_bench::{PeerOptions, PeerRow, bench_scene, parse_query_file};
use plotters::coord::Shift;
use plotters::prelude::*;
use serde::Serialize;

use crate::args::BenchPeersArgs;
use crate::chart::{RatioPanel, failed, ratio_panel, svg_and_png};
use crate::output;

/// The whole run, as JSON.
#[derive(Serialize)]
pub(crate) struct Bench {
    /// Queries per generated set (none with a query file).
    pub queries: Option<usize>,
    pub seed: u64,
    pub block_size: u32,
    pub query_file: Option<PathBuf>,
    pub rows: Vec<PeerRow>,
}

/// Runs the benchmark on every scene and prints (and with --out, writes) the result.
pub fn run(o: &BenchPeersArgs) -> Result<()> {
    let query_sets = match &o.query_file {
        Some(f) => {
            let text = std::fs::read_to_string(f).with_context(|| format!("reading {}", f.display()))?;
            Some(parse_query_file(&text).with_context(|| f.display().to_string())?)
        }
        None => None,
    };
    let options = PeerOptions {
        queries: o.queries,
        seed: o.seed,
        block_size: o.block_size,
        lod_levels: o.lods,
        query_sets,
        files_dir: o.out.clone(),
    };
    let tty = std::io::stderr().is_terminal();
    let progress = |step: &str| {
        if tty {
            eprint!("\r{step:70.70}");
        }
    };
    // A group of rows per scene argument (a scene may be named twice).
    let mut groups = Vec::new();
    for arg in &o.scenes {
        let scene = crate::input::scene_or_preset(arg, &o.import.options())?;
        let result = bench_scene(arg, &scene, &options, &progress);
        if tty {
            eprint!("\r{:70}\r", "");
        }
        groups.push(result?);
    }
    let bench = Bench {
        queries: o.query_file.is_none().then_some(o.queries),
        seed: o.seed,
        block_size: o.block_size,
        query_file: o.query_file.clone(),
        rows: groups.concat(),
    };
    if let Some(dir) = &o.out {
        let json = dir.join("bench-peers.json");
        std::fs::write(&json, serde_json::to_string_pretty(&bench)?)
            .with_context(|| format!("writing {}", json.display()))?;
        chart(&groups, &dir.join("bench-peers.svg"), &dir.join("bench-peers.png"))?;
    }
    if o.json {
        return output::json(&bench);
    }
    print_tables(&bench, &groups);
    Ok(())
}

fn print_tables(b: &Bench, groups: &[Vec<PeerRow>]) {
    let queries =
        b.queries.map_or_else(|| "queries from the query file".into(), |n| format!("{n} queries per set"));
    println!(
        "{queries}, seed {}, {}-byte blocks and pages; means per query, each from a cold cache; \
         ratios mktree / SQLite; warm: every block cached\n",
        b.seed, b.block_size
    );
    let f2 = |x: f64| format!("{x:.2}");
    let ratio = |x: Option<f64>| x.map_or_else(|| "-".into(), |r| format!("{r:.3}"));
    let kib = |x: f64| format!("{:.0}", x / 1024.0);
    let rows: Vec<Vec<String>> = b
        .rows
        .iter()
        .map(|r| {
            vec![
                r.scene.clone(),
                r.set.clone(),
                format!(
                    "{:.1} / {:.1} / {:.1}",
                    r.exact_answers, r.mktree_filter_answers, r.sqlite_filter_answers
                ),
                f2(r.mktree_exact_reads),
                f2(r.mktree_exact_lower_bound),
                f2(r.sqlite_exact_reads),
                ratio(r.exact_reads_ratio),
                f2(r.mktree_filter_reads),
                f2(r.mktree_filter_lower_bound),
                f2(r.sqlite_filter_reads),
                ratio(r.filter_reads_ratio),
                format!("{} / {}", kib(r.mktree_exact_bytes), kib(r.sqlite_exact_bytes)),
                format!("{:.1} / {:.1}", r.rstar_nodes_tested, r.rstar_leaves_tested),
                format!("{:.3} / {:.3}", r.mktree_warm_ms, r.sqlite_warm_ms),
                ratio(r.warm_time_ratio),
            ]
        })
        .collect();
    markdown(
        &[
            "scene",
            "set",
            "answers exact / filter mktree / SQLite",
            "mktree exact reads",
            "lower bound",
            "SQLite exact reads",
            "ratio",
            "mktree filter reads",
            "lower bound",
            "SQLite filter reads",
            "ratio",
            "exact KiB mktree / SQLite",
            "rstar nodes / leaves tested",
            "warm ms mktree / SQLite",
            "ratio",
        ],
        &rows,
    );
    println!();
    let files: Vec<Vec<String>> = groups
        .iter()
        .filter_map(|g| g.first())
        .map(|r| {
            vec![
                r.scene.clone(),
                r.objects.to_string(),
                r.mktree_file_bytes.to_string(),
                r.sqlite_file_bytes.to_string(),
                ratio(r.file_bytes_ratio),
                format!("{:.2}", r.mktree_build_seconds),
                format!("{:.2}", r.sqlite_load_seconds),
            ]
        })
        .collect();
    markdown(
        &[
            "scene",
            "objects",
            "mktree file bytes",
            "SQLite file bytes",
            "ratio",
            "mktree build s",
            "SQLite load s",
        ],
        &files,
    );
}

/// Prints a markdown table, its columns padded to line up.
fn markdown(header: &[&str], rows: &[Vec<String>]) {
    let mut width: Vec<usize> = header.iter().map(|h| h.len()).collect();
    for r in rows {
        for (w, c) in width.iter_mut().zip(r) {
            *w = (*w).max(c.len());
        }
    }
    let line = |cells: &[String]| {
        let padded: Vec<String> = cells.iter().zip(&width).map(|(c, w)| format!("{c:w$}")).collect();
        println!("| {} |", padded.join(" | "));
    };
    line(&header.iter().map(|h| h.to_string()).collect::<Vec<_>>());
    line(&width.iter().map(|&w| "-".repeat(w)).collect::<Vec<_>>());
    for r in rows {
        line(r);
    }
}

/// Pixels per scene panel.
const PANEL: (u32, u32) = (900, 360);
/// The reference ratios drawn across each panel.
const LEVELS: [f64; 2] = [0.6, 0.8];

/// The chart: one panel per scene, mktree / SQLite mean reads for exact
/// answers and for the box filter by query set, with lines at 0.6 and 0.8
/// (and parity, 1); as SVG and PNG.
fn chart(groups: &[Vec<PeerRow>], svg: &Path, png: &Path) -> Result<()> {
    let size = (PANEL.0, PANEL.1 * groups.len().max(1) as u32);
    svg_and_png!(size, svg, png, draw(groups))
}

fn draw<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, groups: &[Vec<PeerRow>]) -> Result<()> {
    root.fill(&WHITE).map_err(failed)?;
    let panels = root.split_evenly((groups.len().max(1), 1));
    for (area, rows) in panels.iter().zip(groups) {
        panel(area, rows)?;
    }
    Ok(())
}

/// One scene: a line for exact answers and one for the filter.
fn panel<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, rows: &[PeerRow]) -> Result<()> {
    let scene = rows.first().map_or("", |r| r.scene.as_str());
    let lines = [
        ("exact answers", points(rows, |r| r.exact_reads_ratio)),
        ("box filter", points(rows, |r| r.filter_reads_ratio)),
    ];
    // Headroom above the highest point for the legend.
    let top = lines.iter().flat_map(|l| l.1.iter().map(|p| p.1)).fold(1.1f64, f64::max) * 1.3;
    let sets: Vec<String> = rows.iter().map(|r| r.set.clone()).collect();
    let panel = RatioPanel {
        caption: format!("{scene}: mean reads per query, mktree / SQLite"),
        x_desc: "query set",
        y_desc: "mktree reads / SQLite page reads".into(),
        sets: &sets,
        lines: lines.into(),
        y: 0.0..top,
        rules: [(1.0, BLACK.mix(0.4))].into_iter().chain(LEVELS.map(|l| (l, RED.mix(0.4)))).collect(),
    };
    ratio_panel(area, &panel)
}

/// (set index, ratio) for the sets that have one.
fn points(rows: &[PeerRow], ratio: impl Fn(&PeerRow) -> Option<f64>) -> Vec<(f64, f64)> {
    rows.iter().enumerate().filter_map(|(i, r)| ratio(r).map(|y| (i as f64, y))).collect()
}
