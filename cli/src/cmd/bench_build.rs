//! `mktree bench-build`: every bulk loader on the same scenes and queries.
//! For each method and query set, the leaves a query reaches in the tree
//! held in memory and the leaves that hold an answer (its lower bound);
//! with `--block-size`, the tree written to a file and the exact block reads
//! of the same queries. A table, JSON, and with `--out` a chart.

use std::io::IsTerminal;
use std::time::Instant;

use anyhow::{Context, Result};
use mktree::build::{
    BuildParams, CostModel, Hierarchy, LeafRule, LookAhead, Method, QueryExtent, Report, build,
};
use mktree::db::{CreateOptions, Database};
use mktree::geom::Aabb;
use mktree::scene::Scene;
use mktree_bench::{QueryKind, TreeQueryCount, count_in_tree, run_boxes};
use serde::Serialize;

use crate::args::BenchBuildArgs;
use crate::output;

/// MemPage when neither a page nor a block size is given.
const DEFAULT_PAGE_OBJECTS: u32 = 100;
/// The methods a method is judged against: the best reference per query set.
const REFERENCES: [Method; 3] = [Method::Median, Method::Sah, Method::Vsah];

/// The whole run, as JSON.
#[derive(Serialize)]
pub struct Bench {
    pub queries: usize,
    pub seed: u64,
    pub rate: f64,
    /// "MemPage N objects" or "leaves fit one B-byte block".
    pub leaf: String,
    pub block_size: Option<u32>,
    pub scenes: Vec<SceneResult>,
}

#[derive(Serialize)]
pub struct SceneResult {
    pub scene: String,
    pub objects: usize,
    pub extent: [f64; 3],
    /// q of the cost model (refine's default), per axis.
    pub query_extent: [f64; 3],
    pub methods: Vec<MethodResult>,
}

#[derive(Serialize)]
pub struct MethodResult {
    pub method: &'static str,
    /// LAA's look-ahead; none for the other methods.
    pub look_ahead: Option<String>,
    pub build_seconds: f64,
    /// Leaves: one page each.
    pub pages: usize,
    pub depth: u32,
    /// The cost model's expected leaf accesses for q = `query_extent`.
    pub expected_leaf_accesses: f64,
    pub file: Option<FileResult>,
    pub queries: Vec<SetResult>,
}

#[derive(Serialize)]
pub struct FileResult {
    pub block_size: u32,
    pub node_blocks: u64,
    pub geometry_blocks: u64,
    pub file_bytes: u64,
}

/// Means per query of one query set.
#[derive(Serialize)]
pub struct SetResult {
    pub query: String,
    #[serde(flatten)]
    pub kind: QueryKind,
    pub leaves_visited: f64,
    /// The lower bound: leaves holding an object whose box meets the query.
    pub answer_leaves: f64,
    /// Objects whose box meets the query.
    pub answers: f64,
    /// With a file: exact block reads (cold) and exact answers.
    pub node_reads: Option<f64>,
    pub geometry_reads: Option<f64>,
    pub reads: Option<f64>,
    pub exact_answers: Option<f64>,
    /// `reads` (or, without a file, `leaves_visited`) over the least of
    /// median, sah and vsah on this set; none when those did not run.
    pub ratio_to_best_reference: Option<f64>,
}

impl SetResult {
    /// What the method is judged on: block reads, or leaves without a file.
    pub fn measure(&self) -> f64 {
        self.reads.unwrap_or(self.leaves_visited)
    }
}

pub fn run(o: &BenchBuildArgs) -> Result<()> {
    anyhow::ensure!(o.queries > 0, "--queries must be at least 1");
    let methods = o.methods.clone().unwrap_or_else(|| Method::ALL.to_vec());
    let leaf = match (o.block_size, o.page_objects) {
        (Some(b), _) => mktree::build::BuildParams::for_blocks(b).leaf,
        (None, p) => LeafRule::Objects(p.unwrap_or(DEFAULT_PAGE_OBJECTS)),
    };
    let tty = std::io::stderr().is_terminal();
    let mut scenes = Vec::new();
    for arg in &o.scenes {
        let scene = crate::cmd::scene_or_preset(arg, &o.import.options())?;
        anyhow::ensure!(!scene.is_empty(), "{arg}: the scene has no objects");
        let boxes = scene.object_boxes();
        let sets: Vec<(QueryKind, Vec<Aabb>)> =
            QueryKind::STANDARD.iter().map(|k| (*k, k.generate(&boxes, o.queries, o.seed))).collect();
        let model = CostModel::of_boxes(&boxes, QueryExtent::Auto);
        let mut results = Vec::new();
        for &method in &methods {
            if tty {
                eprint!("\r{arg}: {method} ...                    ");
            }
            let params = BuildParams {
                method,
                rate: o.rate,
                leaf,
                look_ahead: LookAhead::Max,
                ..BuildParams::paper()
            };
            results.push(bench_method(&scene, &boxes, &params, &sets, &model, o.block_size)?);
        }
        if tty {
            eprint!("\r{:60}\r", "");
        }
        judge(&mut results);
        let e = scene.aabb().extent();
        scenes.push(SceneResult {
            scene: arg.clone(),
            objects: scene.len(),
            extent: [e.x, e.y, e.z],
            query_extent: model.query_extent(),
            methods: results,
        });
    }
    let leaf = match leaf {
        LeafRule::Objects(n) => format!("MemPage {n} objects"),
        LeafRule::Bytes { capacity } => format!("leaves fit one block ({capacity} bytes of geometry)"),
    };
    let bench =
        Bench { queries: o.queries, seed: o.seed, rate: o.rate, leaf, block_size: o.block_size, scenes };
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

/// Builds one tree, counts its leaves per query, and with a block size
/// writes it to a temporary file and counts its block reads.
fn bench_method(
    scene: &Scene,
    boxes: &[Aabb],
    params: &BuildParams,
    sets: &[(QueryKind, Vec<Aabb>)],
    model: &CostModel,
    block_size: Option<u32>,
) -> Result<MethodResult> {
    let sizes: Vec<u64> = scene.objects().iter().map(|o| mktree::build::object_bytes(&o.mesh)).collect();
    let started = Instant::now();
    let tree = build(boxes, Some(&sizes), params, &|_| {})?;
    let build_seconds = started.elapsed().as_secs_f64();
    let report = Report::of(&tree);
    let mut queries: Vec<SetResult> =
        sets.iter().map(|(kind, qs)| in_memory(&tree, boxes, *kind, qs)).collect();
    let file = match block_size {
        Some(b) => Some(in_file(scene, &tree, params, build_seconds, b, sets, &mut queries)?),
        None => None,
    };
    Ok(MethodResult {
        method: params.method.name(),
        look_ahead: (params.method == Method::Laa).then(|| params.look_ahead.to_string()),
        build_seconds,
        pages: report.leaves,
        depth: report.depth,
        expected_leaf_accesses: model.expected_leaf_accesses(&tree),
        file,
        queries,
    })
}

/// Means of the in-memory counts of one query set.
fn in_memory(tree: &Hierarchy, boxes: &[Aabb], kind: QueryKind, queries: &[Aabb]) -> SetResult {
    let sum = queries.iter().fold(TreeQueryCount::default(), |s, q| {
        let c = count_in_tree(tree, boxes, q);
        TreeQueryCount {
            leaves_visited: s.leaves_visited + c.leaves_visited,
            answer_leaves: s.answer_leaves + c.answer_leaves,
            answers: s.answers + c.answers,
        }
    });
    let n = queries.len().max(1) as f64;
    SetResult {
        query: kind.label(),
        kind,
        leaves_visited: sum.leaves_visited as f64 / n,
        answer_leaves: sum.answer_leaves as f64 / n,
        answers: sum.answers as f64 / n,
        node_reads: None,
        geometry_reads: None,
        reads: None,
        exact_answers: None,
        ratio_to_best_reference: None,
    }
}

/// Writes `tree` to a temporary file of `block_size`-byte blocks, runs every
/// query set on it cold, and removes the file.
fn in_file(
    scene: &Scene,
    tree: &Hierarchy,
    params: &BuildParams,
    build_seconds: f64,
    block_size: u32,
    sets: &[(QueryKind, Vec<Aabb>)],
    results: &mut [SetResult],
) -> Result<FileResult> {
    let path =
        std::env::temp_dir().join(format!("mktree-bench-build-{}-{}.mkt", std::process::id(), params.method));
    let _ = std::fs::remove_file(&path);
    let measured = (|| -> Result<FileResult> {
        let db = Database::create(&path, CreateOptions { block_size, ..CreateOptions::default() })
            .with_context(|| format!("creating {}", path.display()))?;
        let mut w = db.begin_write()?;
        w.write_tree(scene, tree, params, build_seconds)?;
        w.commit()?;
        let txn = db.begin_read()?;
        let info = txn.info().context("the committed file has no tree")?;
        for ((_, queries), r) in sets.iter().zip(results.iter_mut()) {
            let s = run_boxes(&txn, queries)?;
            r.node_reads = Some(s.mean_node_reads);
            r.geometry_reads = Some(s.mean_geometry_reads);
            r.reads = Some(s.mean_total_reads);
            r.exact_answers = Some(s.mean_objects);
        }
        Ok(FileResult {
            block_size,
            node_blocks: u64::from(info.node_blocks),
            geometry_blocks: info.geometry_blocks,
            file_bytes: u64::from(info.file_blocks) * u64::from(info.block_size),
        })
    })();
    let _ = std::fs::remove_file(&path);
    measured
}

/// Fills each set's ratio to the best reference method on it.
fn judge(results: &mut [MethodResult]) {
    let sets = results.first().map_or(0, |m| m.queries.len());
    for s in 0..sets {
        let best = results
            .iter()
            .filter(|m| REFERENCES.iter().any(|r| r.name() == m.method))
            .map(|m| m.queries[s].measure())
            .fold(None, |b: Option<f64>, v| Some(b.map_or(v, |b| b.min(v))));
        for m in results.iter_mut() {
            let r = &mut m.queries[s];
            r.ratio_to_best_reference = best.filter(|&b| b > 0.0).map(|b| r.measure() / b);
        }
    }
}

fn print_tables(bench: &Bench) {
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
