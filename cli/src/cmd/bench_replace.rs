//! `mktree bench-replace`: scene A bulk-loaded, then replaced by scene B
//! object by object, with box-query reads at 10%, 50% and 100% against a
//! fresh bulk load of the same objects, through `mktree_bench::bench_replace`.

use anyhow::{Result, bail};
use mktree::bulk::BuildParams;
use mktree::db::CreateOptions;
use mktree_bench::{ReplaceOptions, bench_replace, standard_sets};

use crate::args::BenchReplaceArgs;
use crate::output;

pub fn run(args: &BenchReplaceArgs) -> Result<()> {
    if !(args.batch > 0.0 && args.batch <= 1.0) {
        bail!("--batch {} is not a share in (0, 1]", args.batch);
    }
    let options = args.import.options();
    let a = crate::input::scene_or_preset(&args.scene, &options)?;
    let b = match &args.revision {
        Some(r) => crate::input::scene_or_preset(r, &options)?,
        None if std::path::Path::new(&args.scene).exists() => {
            bail!("{} is a file: name the revision that replaces it with --revision", args.scene)
        }
        None => crate::input::scene_or_seeded_preset(&args.scene, &options, 1)?,
    };
    let create = CreateOptions::default();
    let params = BuildParams::for_blocks(create.block_size);
    let sets = standard_sets(&a.object_boxes(), args.queries, args.seed);
    let opts = ReplaceOptions { stops: vec![0.1, 0.5, 1.0], batch: args.batch, seed: args.seed, create };
    let report = bench_replace(&a, &b, &params, &sets, &opts, &args.dir)?;
    if args.json {
        return output::json(&report);
    }
    println!(
        "{} replaced by {} ({} and {} objects), {:.0}% per commit; mean block reads per exact query, changed / fresh bulk load",
        args.scene,
        args.revision.as_deref().unwrap_or("its seed-1 revision"),
        a.len(),
        b.len(),
        100.0 * args.batch
    );
    let labels: Vec<&str> = report.rows[0].reads.iter().map(|r| r.0.as_str()).collect();
    println!(
        "| replaced | commits (written whole) | ms/commit | blocks (free) | fresh blocks | layout drift | {} |",
        labels.join(" | ")
    );
    println!("|---|---|---|---|---|---|{}", "---|".repeat(labels.len()));
    for row in &report.rows {
        let cells: Vec<String> = row
            .reads
            .iter()
            .map(|(_, changed, fresh)| {
                format!(
                    "{:.2} / {:.2} ({:.2}x)",
                    changed.mean_total_reads,
                    fresh.mean_total_reads,
                    changed.mean_total_reads / fresh.mean_total_reads.max(f64::MIN_POSITIVE)
                )
            })
            .collect();
        println!(
            "| {:.0}% | {} ({}) | {:.2} | {} ({}) | {} | {:.2}x | {} |",
            100.0 * row.replaced,
            row.commits,
            row.whole,
            1e3 * row.mean_commit_seconds,
            row.file_blocks,
            row.free_blocks,
            row.fresh_blocks,
            row.layout_drift,
            cells.join(" | ")
        );
    }
    if let Some(last) = report.rows.last() {
        let cells: Vec<String> = report
            .optimized
            .iter()
            .zip(&last.reads)
            .map(|((label, now), (_, _, fresh))| {
                let ratio = now.mean_total_reads / fresh.mean_total_reads.max(f64::MIN_POSITIVE);
                format!("{label} {:.2} / {:.2} ({ratio:.2}x)", now.mean_total_reads, fresh.mean_total_reads)
            })
            .collect();
        println!("after optimize, / fresh bulk load: {}", cells.join(", "));
    }
    println!("compact: {} -> {} blocks", report.compact.0, report.compact.1);
    Ok(())
}
