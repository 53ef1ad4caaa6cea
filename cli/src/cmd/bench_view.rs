//! `mktree bench-view`: the view query's speed against its accuracy along
//! a walk through each file's scene (`mktree_bench::bench_view`): block
//! reads and triangles per frame against τ, the error kept under a block
//! budget, and the exact frustum query's reads as the yardstick. Writes a
//! chart and, per file, a strip of one frame drawn at each τ.

use anyhow::{Context, Result, bail};
use mktree::ViewOptions;
use mktree::geom::{Aabb, Point};
use mktree::render::{Image, draw_cut, framing};
use mktree_bench::{ViewBench, ViewBenchOptions, bench_view, flight, orbit, views};
use serde_json::json;

use crate::args::{BenchViewArgs, Walk};
use crate::output;

pub fn run(args: &BenchViewArgs) -> Result<()> {
    if args.steps == 0 {
        bail!("--steps 0: a walk has at least one frame");
    }
    if let Some(t) = args.taus.iter().find(|t| !(t.is_finite() && **t >= 0.0)) {
        bail!("--taus: {t} is not a tolerance in pixels (finite, >= 0)");
    }
    std::fs::create_dir_all(&args.out).with_context(|| format!("creating {}", args.out.display()))?;
    let opts = ViewBenchOptions {
        taus: args.taus.clone(),
        budgets: args.budgets.clone(),
        cache_blocks: args.cache_blocks,
        height_px: args.height_px,
        ..ViewBenchOptions::default()
    };
    let mut results: Vec<(String, ViewBench)> = Vec::new();
    for file in &args.files {
        let name =
            file.file_stem().map_or_else(|| file.display().to_string(), |s| s.to_string_lossy().into());
        let db = crate::input::open_to_read(file)?;
        let r = db.begin_read()?;
        let scene = r.root().with_context(|| format!("{} holds no tree", file.display()))?.aabb;
        let path = match args.walk {
            Walk::Length => flight(&scene, args.steps),
            Walk::Orbit => orbit(&scene, args.steps),
        };
        let walk = views(&path, &scene, &opts);
        let bench = bench_view(&r, &walk, &opts).with_context(|| format!("{}", file.display()))?;
        let m = r.info().map_or(1, |i| i.lod_levels);
        // The middle section of the scene from above (a walk's frame sees
        // mostly the plate ahead), drawn at each tolerance, side by side.
        let frame = framing(&middle_section(&scene), STRIP_PX.0, STRIP_PX.1, opts.fov_deg);
        let mut strip: Vec<Image> = Vec::new();
        for &tau in &args.taus {
            let cut = r.view(&frame, &ViewOptions { tolerance_px: tau, budget: None, shapes: true }, None)?;
            strip.push(draw_cut(&frame, &cut, m)?);
        }
        let strip_path = args.out.join(format!("frames-{name}.png"));
        output::write_png(&side_by_side(&strip), &strip_path)?;
        results.push((name, bench));
    }
    let json_path = args.out.join("bench-view.json");
    let report: Vec<_> = results.iter().map(|(name, b)| json!({ "file": name, "bench": b })).collect();
    std::fs::write(&json_path, serde_json::to_string_pretty(&report)?)
        .with_context(|| format!("writing {}", json_path.display()))?;
    crate::chart::bench_view(&results, &args.out.join("bench-view.svg"), &args.out.join("bench-view.png"))?;
    if args.json {
        return output::json(&report);
    }
    for (name, b) in &results {
        println!(
            "{name}: {} frames, exact frustum query {:.1} reads per frame",
            b.frames, b.exact_frustum_reads
        );
        let rows: Vec<Vec<String>> = b
            .taus
            .iter()
            .map(|t| {
                vec![
                    format!("{}", t.tau_px),
                    format!("{:.1}", t.reads),
                    format!("{:.0}", t.triangles),
                    format!("{:.1}", t.exact_objects),
                    format!("{:.1}", t.max_error_px),
                ]
            })
            .collect();
        output::table(&["tau_px", "reads", "triangles", "exact_objects", "max_error_px"], &rows);
        let rows: Vec<Vec<String>> = b
            .budgets
            .iter()
            .map(|r| {
                vec![r.budget.to_string(), format!("{:.1}", r.reads), format!("{:.1}", r.median_error_px)]
            })
            .collect();
        output::table(&["budget", "reads", "median_error_px"], &rows);
    }
    println!("wrote {} and the chart and frame strips in {}", json_path.display(), args.out.display());
    Ok(())
}

/// The size of each picture of a frame strip, pixels.
const STRIP_PX: (u32, u32) = (480, 320);

/// The middle of `scene` along x, twice its larger cross extent long.
fn middle_section(scene: &Aabb) -> Aabb {
    let e = scene.extent();
    let half = e.y.max(e.z).min(e.x / 2.0);
    let c = scene.center();
    Aabb::new(
        Point::new(c.x - half, scene.min.y, scene.min.z),
        Point::new(c.x + half, scene.max.y, scene.max.z),
    )
}

/// Images of one height placed left to right, 4 px of white between.
fn side_by_side(images: &[Image]) -> Image {
    const GAP: u32 = 4;
    let height = images.iter().map(|i| i.height).max().unwrap_or(1);
    let width = images.iter().map(|i| i.width + GAP).sum::<u32>().saturating_sub(GAP).max(1);
    let mut out = Image::new(width, height);
    out.rgb.fill(255);
    let mut x0 = 0;
    for img in images {
        for y in 0..img.height {
            let src = (y * img.width * 3) as usize..((y + 1) * img.width * 3) as usize;
            let at = ((y * width + x0) * 3) as usize;
            out.rgb[at..at + src.len()].copy_from_slice(&img.rgb[src]);
        }
        x0 += img.width + GAP;
    }
    out
}
