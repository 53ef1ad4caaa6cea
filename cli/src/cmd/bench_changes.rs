//! `mktree bench-changes`: change commits on mktree and on SQLite's R*Tree
//! plus blobs (WAL and rollback journal, `synchronous = FULL`) in the same
//! run, through `mktree_bench::bench_changes`.

use anyhow::{Result, bail};
use mktree::Aabb;
use mktree::bulk::BuildParams;
use mktree::db::CreateOptions;
use mktree_bench::stream::{StreamEngine, StreamJob, StreamRole};
use mktree_bench::{ChangeOptions, bench_changes, standard_sets};

use crate::args::{BenchChangesArgs, StreamWorkerArgs};
use crate::output;

pub fn run(args: &BenchChangesArgs) -> Result<()> {
    if args.singles == 0 && args.batch == 0 {
        bail!("nothing to measure: --singles and --batch are both 0");
    }
    let options = args.import.options();
    let create = CreateOptions::default();
    let params = BuildParams::for_blocks(create.block_size);
    let mut reports = Vec::new();
    for name in &args.scenes {
        let scene = crate::input::scene_or_preset(name, &options)?;
        let sets = standard_sets(&scene.object_boxes(), args.queries, args.seed);
        let worker = if args.no_stream { None } else { Some(std::env::current_exe()?) };
        let opts =
            ChangeOptions { singles: args.singles, batch: args.batch, seed: args.seed, create, worker };
        let report = bench_changes(&scene, &params, &sets, &opts, &args.dir)?;
        if !args.json {
            print(name, &report);
        }
        reports.push((name.clone(), report));
    }
    if let Some(path) = &args.chart {
        let (svg, png) = (path.with_extension("svg"), path.with_extension("png"));
        crate::chart::commit_times(&commit_series(&reports), &svg, &png)?;
        eprintln!("wrote {} and {}", svg.display(), png.display());
    }
    if args.json {
        let rows: Vec<_> =
            reports.iter().map(|(name, r)| serde_json::json!({ "scene": name, "report": r })).collect();
        return output::json(&serde_json::json!({ "scenes": rows }));
    }
    Ok(())
}

/// Per engine and kind of single-object commit, (objects, median ms) over the scenes.
fn commit_series(reports: &[(String, mktree_bench::ChangesReport)]) -> Vec<crate::chart::CommitSeries> {
    let mut series: Vec<crate::chart::CommitSeries> = Vec::new();
    for (_, r) in reports {
        for row in r.rows.iter().filter(|row| ["insert", "move", "remove"].contains(&row.phase.as_str())) {
            let name = format!("{} {}", row.engine, row.phase);
            let point = (r.objects as f64, row.median_ms);
            match series.iter_mut().find(|s| s.name == name) {
                Some(s) => s.points.push(point),
                None => series.push(crate::chart::CommitSeries { name, points: vec![point] }),
            }
        }
    }
    series
}

fn print(name: &str, r: &mktree_bench::ChangesReport) {
    println!(
        "{name} ({} objects): per commit, median / p95 ms, bytes written, blocks written, syncs",
        r.objects
    );
    println!(
        "| engine | phase | commits | median ms | p95 ms | bytes | blocks | syncs | in place | file bytes after |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for row in &r.rows {
        println!(
            "| {} | {} | {} | {:.2} | {:.2} | {:.0} | {:.1} | {:.1} | {:.0}% | {} |",
            row.engine,
            row.phase,
            row.commits,
            row.median_ms,
            row.p95_ms,
            row.bytes_per_commit,
            row.blocks_per_commit,
            row.syncs_per_commit,
            100.0 * row.in_place,
            row.file_bytes
        );
    }
    println!(
        "mean block reads per exact query after the changes, changed file / fresh bulk load of the same objects:"
    );
    for (label, changed, fresh) in &r.reads {
        println!(
            "  {label}: {:.2} / {:.2} ({:.3}x)",
            changed.mean_total_reads,
            fresh.mean_total_reads,
            changed.mean_total_reads / fresh.mean_total_reads.max(f64::MIN_POSITIVE)
        );
    }
    println!("  file blocks: {} / {}", r.file_blocks.0, r.file_blocks.1);
    if !r.streams.is_empty() {
        println!("single-object moves committed by one process while another queries (box 1%), per commit:");
        println!("| engine | commits | median ms | p95 ms | reader queries | failed |");
        println!("|---|---|---|---|---|---|");
        for s in &r.streams {
            println!(
                "| {} | {} | {:.2} | {:.2} | {} | {} |",
                s.engine, s.commits, s.median_ms, s.p95_ms, s.reader_queries, s.reader_failed
            );
            if let Some(e) = &s.first_error {
                println!("  {}: first failure: {e}", s.engine);
            }
        }
    }
}

/// One side of the stream, in its own process: its report as JSON.
pub fn worker(args: &StreamWorkerArgs) -> Result<()> {
    let engine = match args.engine.as_str() {
        "mktree" => StreamEngine::Mktree,
        "sqlite" => StreamEngine::Sqlite,
        other => bail!("--engine {other}: mktree or sqlite"),
    };
    let role = match args.role.as_str() {
        "writer" => StreamRole::Writer,
        "reader" => StreamRole::Reader,
        other => bail!("--role {other}: writer or reader"),
    };
    let job = StreamJob {
        engine,
        role,
        file: args.file.clone(),
        keys: args.keys,
        commits: args.commits,
        extent: Aabb::from_array(args.extent),
        seed: args.seed,
        stop: args.stop.clone(),
    };
    output::json(&mktree_bench::stream::worker(&job)?)
}
