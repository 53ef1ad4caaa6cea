//! `mktree demo`: the README's first command. Generates tanker2, builds it
//! with MOA and with LAA(max) at R = 0.3 and MemPage = 500 objects in the
//! paper's 48,000-byte blocks, prints both
//! per-level tables side by side, then box queries with their block reads.

use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result};
use mktree::build::{BuildParams, LeafRule, LookAhead, Method, Report};
use mktree::db::{CreateOptions, Database, check};
use mktree::geom::Aabb;
use mktree::query::{QueryOptions, Region, query_region};
use mktree::scene::generate::{GenOptions, Preset, generate_scene};

use crate::output::{self, opt};

pub fn run(dir: Option<&Path>) -> Result<()> {
    match dir {
        Some(d) => {
            std::fs::create_dir_all(d)?;
            demo(d)?;
            println!("\nfiles kept in {}", d.display());
            Ok(())
        }
        None => {
            let tmp = std::env::temp_dir().join(format!("mktree-demo-{}", std::process::id()));
            std::fs::create_dir_all(&tmp)?;
            let result = demo(&tmp);
            let _ = std::fs::remove_dir_all(&tmp);
            result
        }
    }
}

fn demo(dir: &Path) -> Result<()> {
    let started = Instant::now();
    let scene = generate_scene(&GenOptions { preset: Preset::Tanker2, objects: None, seed: 0 })?;
    let e = scene.aabb().extent();
    println!(
        "tanker2: {} objects, {} triangles, {:.0} x {:.0} x {:.0} mm (generated in {:.2} s)\n",
        scene.len(),
        scene.triangle_count(),
        e.x,
        e.y,
        e.z,
        started.elapsed().as_secs_f64()
    );
    let mut dbs = Vec::new();
    let mut reports = Vec::new();
    for (name, method, look_ahead) in
        [("moa", Method::Moa, LookAhead::Levels(0)), ("laa", Method::Laa, LookAhead::Max)]
    {
        let path = dir.join(format!("tanker2-{name}.mkt"));
        let _ = std::fs::remove_file(&path);
        // The paper's page: MemPage = 48000 bytes (500 objects), §3.1.1.
        let db = Database::create(&path, CreateOptions { block_size: 48_000, ..CreateOptions::default() })
            .with_context(|| format!("creating {}", path.display()))?;
        let params = BuildParams {
            method,
            rate: 0.3,
            leaf: LeafRule::Objects(500),
            look_ahead,
            ..BuildParams::default()
        };
        let t = Instant::now();
        let mut w = db.begin_write()?;
        let tree = w.bulk_load(&scene, &params, &|_| {})?;
        w.commit()?;
        let secs = t.elapsed().as_secs_f64();
        let report = Report::of(&tree);
        let info = db.begin_read()?.info().context("no tree")?;
        println!(
            "{}: {} in {:.3} s: {} blocks of {} bytes ({} node, {} geometry); ovAccumulated {:.1}, N_g {}, ovAverage {:.1}; check: {}",
            name.to_uppercase(),
            path.display(),
            secs,
            info.file_blocks,
            info.block_size,
            info.node_blocks,
            info.geometry_blocks,
            report.ov_accumulated,
            report.grey_nodes,
            report.ov_average,
            if check(&db)?.ok() { "ok" } else { "FAULTS" }
        );
        reports.push(report);
        dbs.push(db);
    }
    println!("\nper level, MOA | LAA(max), R = 0.3, MemPage = 500 objects (the paper's Tables 13 and 31)");
    let depth = reports.iter().map(|r| r.levels.len()).max().unwrap_or(0);
    let cell = |r: &Report, l: usize| -> Vec<String> {
        r.levels.get(l).map_or(vec!["".into(); 4], |x| {
            vec![x.leaves.to_string(), opt(x.ov_min), opt(x.ov_min_rel), opt(x.ov_max)]
        })
    };
    let rows: Vec<Vec<String>> = (0..depth)
        .map(|l| [vec![l.to_string()], cell(&reports[0], l), cell(&reports[1], l)].concat())
        .collect();
    output::table(
        &["level", "MOA leaves", "ovMin", "ovMinRel", "ovMax", "LAA leaves", "ovMin", "ovMinRel", "ovMax"],
        &rows,
    );
    println!("\nbox queries (exact triangle-box answers), block reads MOA | LAA:");
    let c = scene.aabb().center();
    let mut rows = Vec::new();
    for frac in [0.01, 0.05, 0.2] {
        for (dx, dy, dz) in [(0.0, 0.0, 0.0), (0.25, -0.2, 0.1), (-0.3, 0.3, -0.25)] {
            let h = e * frac / 2.0;
            let p = c + mktree::geom::Vector::new(dx * e.x, dy * e.y, dz * e.z);
            let q = Aabb::new(p - h, p + h);
            let mut row = vec![format!("{:.0}% at ({:.0}, {:.0}, {:.0})", frac * 100.0, p.x, p.y, p.z)];
            let mut answers = Vec::new();
            for db in &dbs {
                let res = query_region(&db.begin_read()?, &Region::Box(q), &QueryOptions::default(), None)?;
                row.push(format!(
                    "{} ({}+{})",
                    res.stats.reads.total(),
                    res.stats.reads.node,
                    res.stats.reads.geometry
                ));
                answers.push(res.objects);
            }
            anyhow::ensure!(answers[0] == answers[1], "MOA and LAA files disagree on a query");
            row.insert(1, answers[0].len().to_string());
            rows.push(row);
        }
    }
    output::table(
        &["box (share of extent, centre)", "objects", "MOA reads (node+geo)", "LAA reads (node+geo)"],
        &rows,
    );
    Ok(())
}
