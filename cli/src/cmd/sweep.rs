//! `mktree sweep`: the grid of Tables 39-44, MOA and LAA over R x MemPage,
//! with the look level LAA reached and the build time of each cell.

use std::io::IsTerminal;
use std::path::Path;
use std::sync::atomic::{AtomicU32, Ordering};
use std::time::Instant;

use anyhow::Result;
use mktree::bulk::{BuildParams, LeafRule, LookAhead, Method, Report, build};
use mktree::scene::import::ImportOptions;
use serde::Serialize;

use crate::output;

#[derive(Serialize)]
struct Cell {
    method: &'static str,
    look_ahead: String,
    look_level_reached: u32,
    rate: f64,
    mem_page: u32,
    ov_accumulated: f64,
    grey_nodes: usize,
    ov_average: f64,
    depth: u32,
    leaves: usize,
    build_seconds: f64,
}

pub fn run(
    scene_path: &Path,
    options: &ImportOptions,
    pages: Option<Vec<u32>>,
    rates: &[f64],
    look_ahead: LookAhead,
    as_json: bool,
) -> Result<()> {
    let scene = crate::input::read_scene(scene_path, options)?;
    let pages =
        pages.unwrap_or_else(|| if scene.len() < 1000 { vec![10, 20, 30] } else { vec![100, 200, 500] });
    let boxes = scene.object_boxes();
    // Which cell is running, for a person watching; never in redirected output.
    let tty = std::io::stderr().is_terminal();
    let mut cells = Vec::new();
    for method in [Method::Moa, Method::Laa] {
        for &rate in rates {
            for &page in &pages {
                let params = BuildParams {
                    method,
                    rate,
                    leaf: LeafRule::Objects(page),
                    look_ahead,
                    ..BuildParams::paper()
                };
                let reached = AtomicU32::new(0);
                if tty {
                    eprint!("\r{} R={rate} MemPage={page} ...          ", method.name());
                }
                let started = Instant::now();
                let tree = build(&boxes, None, &params, &|p| {
                    reached.fetch_max(p.look_level_reached, Ordering::Relaxed);
                })?;
                let build_seconds = started.elapsed().as_secs_f64();
                let r = Report::of(&tree);
                cells.push(Cell {
                    method: method.name(),
                    look_ahead: if method == Method::Laa { look_ahead.to_string() } else { "-".into() },
                    look_level_reached: reached.load(Ordering::Relaxed),
                    rate,
                    mem_page: page,
                    ov_accumulated: r.ov_accumulated,
                    grey_nodes: r.grey_nodes,
                    ov_average: r.ov_average,
                    depth: r.depth,
                    leaves: r.leaves,
                    build_seconds,
                });
            }
        }
    }
    if tty {
        eprint!("\r{:60}\r", "");
    }
    if as_json {
        return output::json(
            &serde_json::json!({ "scene": scene_path, "objects": scene.len(), "cells": cells }),
        );
    }
    for method in ["moa", "laa"] {
        println!("{} {} accumulated overlap", scene_path.display(), method.to_uppercase());
        let rows: Vec<Vec<String>> = cells
            .iter()
            .filter(|c| c.method == method)
            .map(|c| {
                vec![
                    if method == "laa" {
                        format!("{} ({})", c.look_ahead, c.look_level_reached)
                    } else {
                        "-".into()
                    },
                    c.rate.to_string(),
                    c.mem_page.to_string(),
                    format!("{:.6}", c.ov_accumulated),
                    c.grey_nodes.to_string(),
                    format!("{:.6}", c.ov_average),
                    c.depth.to_string(),
                    format!("{:.3}", c.build_seconds),
                ]
            })
            .collect();
        output::table(
            &[
                "look level (reached)",
                "R",
                "MemPage",
                "ovAccumulated",
                "N_g",
                "ovAverage",
                "depth",
                "build s",
            ],
            &rows,
        );
        println!();
    }
    Ok(())
}
