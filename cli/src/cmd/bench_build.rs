//! `mktree bench-build`: every bulk loader on the same scenes and queries
//! (`mktree_bench::bench_loaders`). A table, JSON, and with `--out` a chart.

use std::io::IsTerminal;

use anyhow::{Context, Result};
use mktree::bulk::Method;
use mktree_bench::{LoaderBench, LoaderOptions, SetResult, bench_loaders, leaf_rule};

use crate::args::BenchBuildArgs;
use crate::input::scene_or_preset;
use crate::output;

pub fn run(o: &BenchBuildArgs) -> Result<()> {
    anyhow::ensure!(o.queries > 0, "--queries must be at least 1");
    let options = LoaderOptions {
        methods: o.methods.clone().unwrap_or_else(|| Method::ALL.to_vec()),
        queries: o.queries,
        seed: o.seed,
        rate: o.rate,
        leaf: leaf_rule(o.block_size, o.page_objects),
        block_size: o.block_size,
    };
    let tty = std::io::stderr().is_terminal();
    let mut scenes = Vec::new();
    for arg in &o.scenes {
        let scene = scene_or_preset(arg, &o.import.options())?;
        anyhow::ensure!(!scene.is_empty(), "{arg}: the scene has no objects");
        scenes.push(bench_loaders(arg, &scene, &options, &mut |method| {
            if tty {
                eprint!("\r{arg}: {method} ...                    ");
            }
        })?);
        if tty {
            eprint!("\r{:60}\r", "");
        }
    }
    let bench = LoaderBench::new(&options, scenes);
    if let Some(dir) = &o.out {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        let json = dir.join("bench-build.json");
        std::fs::write(&json, serde_json::to_string_pretty(&bench)?)
            .with_context(|| format!("writing {}", json.display()))?;
        crate::chart::bench_build(&bench, &dir.join("bench-build.svg"), &dir.join("bench-build.png"))?;
    }
    if o.json {
        return output::json(&bench);
    }
    print_tables(&bench);
    Ok(())
}

fn print_tables(bench: &LoaderBench) {
    println!(
        "{} queries per set, seed {}, R {}, {}; means per query",
        bench.queries, bench.seed, bench.rate, bench.leaf
    );
    for s in &bench.scenes {
        let q = s.query_extent;
        println!(
            "\n{}: {} objects, extent {:.0} x {:.0} x {:.0} mm, cost model q = {:.0} x {:.0} x {:.0} mm",
            s.scene, s.objects, s.extent[0], s.extent[1], s.extent[2], q[0], q[1], q[2]
        );
        let Some(first) = s.methods.first() else { continue };
        let labels: Vec<String> = first.queries.iter().map(|r| r.query.clone()).collect();
        let mut header: Vec<&str> = vec!["method", "build s", "pages", "depth", "E[leaves]"];
        header.extend(labels.iter().map(String::as_str));
        let rows = |cell: &dyn Fn(&SetResult) -> String| -> Vec<Vec<String>> {
            s.methods
                .iter()
                .map(|m| {
                    let mut row = vec![
                        m.method.to_string(),
                        format!("{:.3}", m.build_seconds),
                        m.pages.to_string(),
                        m.depth.to_string(),
                        format!("{:.2}", m.expected_leaf_accesses),
                    ];
                    row.extend(m.queries.iter().map(cell));
                    row
                })
                .collect()
        };
        println!("leaves visited (lower bound: leaves holding an answer)");
        output::table(&header, &rows(&|r| format!("{:.2} ({:.2})", r.leaves_visited, r.answer_leaves)));
        if first.file.is_some() {
            println!("block reads, node + geometry (cold)");
            output::table(
                &header,
                &rows(&|r| match (r.reads, r.node_reads, r.geometry_reads) {
                    (Some(t), Some(n), Some(g)) => format!("{t:.2} = {n:.2} + {g:.2}"),
                    _ => "-".into(),
                }),
            );
        }
        println!(
            "{} over the best of median, sah and vsah",
            if first.file.is_some() { "block reads" } else { "leaves visited" }
        );
        output::table(
            &header,
            &rows(&|r| r.ratio_to_best_reference.map_or("-".into(), |x| format!("{x:.3}"))),
        );
    }
}
