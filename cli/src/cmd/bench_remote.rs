//! `mktree bench-remote`: a local .mkt file against the same file at a URL,
//! through a proxy that adds round trips, via `mktree_bench::bench_remote`.
//! Two tables (the local answers; the remote rows, cold and warm per added
//! round trip), or JSON; with `--out`, bench-remote.json and a chart of the
//! wall time per query against the added round trip (SVG and PNG).

use std::io::IsTerminal;

use anyhow::{Context, Result};
use mktree::store::device::RemoteOptions;
use mktree_bench::{Cache, RemoteBench, RemoteBenchOptions, bench_remote};

use crate::args::BenchRemoteArgs;
use crate::chart::{self, LatencySeries};
use crate::output;

/// Runs the benchmark and prints (and with --out, writes) the result.
pub fn run(o: &BenchRemoteArgs) -> Result<()> {
    let options = RemoteBenchOptions {
        queries: o.queries,
        seed: o.seed,
        latencies_ms: o.latency.clone(),
        remote: RemoteOptions {
            cache_bytes: o.cache_bytes,
            open_bytes: o.open_bytes,
            gap_share: o.gap_share,
            store_options: o.store_options.clone(),
            ..RemoteOptions::default()
        },
    };
    let tty = std::io::stderr().is_terminal();
    let progress = |step: &str| {
        if tty {
            eprint!("\r{step:70.70}");
        }
    };
    let result = bench_remote(&o.file, &o.url, &options, &progress);
    if tty {
        eprint!("\r{:70}\r", "");
    }
    let bench = result?;
    if let Some(dir) = &o.out {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        let json = dir.join("bench-remote.json");
        std::fs::write(&json, serde_json::to_string_pretty(&bench)?)
            .with_context(|| format!("writing {}", json.display()))?;
        let [cold, warm] = [Cache::Cold, Cache::Warm].map(|c| series(&bench, c));
        chart::bench_remote(&cold, &warm, &dir.join("bench-remote.svg"), &dir.join("bench-remote.png"))?;
    }
    if o.json {
        return output::json(&bench);
    }
    print_tables(&bench);
    Ok(())
}

/// Per query set: (added round trip, mean ms per query) of `cache`'s rows.
fn series(b: &RemoteBench, cache: Cache) -> Vec<LatencySeries> {
    b.local
        .iter()
        .map(|l| LatencySeries {
            name: l.set.clone(),
            points: b
                .rows
                .iter()
                .filter(|r| r.cache == cache && r.set == l.set)
                .map(|r| (r.latency_ms, r.total_ms))
                .collect(),
        })
        .collect()
}

fn print_tables(b: &RemoteBench) {
    println!(
        "{} ({} objects, {}-byte blocks, depth {}) against {}: {} queries per set, seed {}; \
         every answer and its block reads checked equal to the local file's\n",
        b.file, b.objects, b.block_size, b.depth, b.url, b.queries, b.seed
    );
    let kib = |x: f64| format!("{:.0}", x / 1024.0);
    let f2 = |x: f64| format!("{x:.2}");
    let local: Vec<Vec<String>> = b
        .local
        .iter()
        .map(|l| {
            vec![
                l.set.clone(),
                format!("{:.1}", l.answers),
                f2(l.block_reads),
                f2(l.node_reads),
                f2(l.geometry_reads),
                kib(l.block_bytes),
                format!("{:.3}", l.wall_ms),
            ]
        })
        .collect();
    output::table(&["set", "answers", "block reads", "node", "geometry", "block KiB", "local ms"], &local);
    println!(
        "\nmeans per query; cold: a fresh reader per query (open counted apart), warm: one reader, \
         its cache filled by a first pass; ratio: query bytes / local block bytes; total: with the open\n"
    );
    let rows: Vec<Vec<String>> = b
        .rows
        .iter()
        .map(|r| {
            let open = r.open.map_or_else(
                || "-".into(),
                |o| format!("{:.1} / {:.1} / {}", o.requests, o.round_trips, kib(o.bytes)),
            );
            vec![
                format!("{}", r.latency_ms),
                r.set.clone(),
                r.cache.label().into(),
                f2(r.block_reads),
                open,
                f2(r.query.requests),
                f2(r.query.round_trips),
                kib(r.query.bytes),
                r.bytes_ratio.map_or_else(|| "-".into(), |x| format!("{x:.2}")),
                format!("{:.1} / {:.1}", r.query.wall_ms, r.query.wall_ms_p95),
                format!("{:.1} / {:.1}", r.total_ms, r.total_ms_p95),
            ]
        })
        .collect();
    output::table(
        &[
            "+rtt ms",
            "set",
            "cache",
            "block reads",
            "open req / rt / KiB",
            "requests",
            "round trips",
            "KiB",
            "ratio",
            "query ms mean / p95",
            "total ms mean / p95",
        ],
        &rows,
    );
}
