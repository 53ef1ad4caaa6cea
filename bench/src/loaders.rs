//! Every bulk loader on the same scenes and queries (`mktree bench-build`).
//! For each method and query set, the leaves a query reaches in the tree
//! held in memory and the leaves that hold an answer (its lower bound);
//! with a block size, the tree written to a file and the exact block reads
//! of the same queries; and each method's measure over the best reference
//! method's on each set.

use std::time::Instant;

use mktree::bulk::{
    BuildParams, CostModel, Hierarchy, LeafRule, LookAhead, Method, QueryExtent, Report, build,
};
use mktree::db::{CreateOptions, Database};
use mktree::geom::Aabb;
use mktree::scene::Scene;
use serde::Serialize;

use crate::{BenchError, QueryKind, TreeQueryCount, count_in_tree, run_boxes};

/// MemPage when neither a page nor a block size is given.
const DEFAULT_PAGE_OBJECTS: u32 = 100;
/// The methods a method is judged against: the best reference per query set.
const REFERENCES: [Method; 3] = [Method::Median, Method::Sah, Method::Vsah];

/// How the loaders are compared.
#[derive(Debug, Clone, PartialEq)]
pub struct LoaderOptions {
    /// The methods to run (LAA with look-ahead max).
    pub methods: Vec<Method>,
    /// Queries per query set.
    pub queries: usize,
    /// The query sets' seed.
    pub seed: u64,
    /// R of MOA, LAA and refine's candidate cuts.
    pub rate: f64,
    /// What a leaf holds ([`leaf_rule`]).
    pub leaf: LeafRule,
    /// With a block size, each tree is also written and read from a file.
    pub block_size: Option<u32>,
}

/// The leaf rule of a run: leaves that fit one block of `block_size`, or
/// else MemPage `page_objects` (100 by default).
pub fn leaf_rule(block_size: Option<u32>, page_objects: Option<u32>) -> LeafRule {
    match (block_size, page_objects) {
        (Some(b), _) => BuildParams::for_blocks(b).leaf,
        (None, p) => LeafRule::Objects(p.unwrap_or(DEFAULT_PAGE_OBJECTS)),
    }
}

/// The whole run, as JSON.
#[derive(Debug, Clone, Serialize)]
pub struct LoaderBench {
    /// Queries per query set.
    pub queries: usize,
    /// The query sets' seed.
    pub seed: u64,
    /// R of MOA, LAA and refine.
    pub rate: f64,
    /// "MemPage N objects" or "leaves fit one B-byte block".
    pub leaf: String,
    /// The files' block size, if trees were written.
    pub block_size: Option<u32>,
    /// One result per scene.
    pub scenes: Vec<LoaderScene>,
}

impl LoaderBench {
    /// The run of `options` over `scenes`.
    pub fn new(options: &LoaderOptions, scenes: Vec<LoaderScene>) -> LoaderBench {
        let leaf = match options.leaf {
            LeafRule::Objects(n) => format!("MemPage {n} objects"),
            LeafRule::Bytes { capacity } => format!("leaves fit one block ({capacity} bytes of geometry)"),
        };
        LoaderBench {
            queries: options.queries,
            seed: options.seed,
            rate: options.rate,
            leaf,
            block_size: options.block_size,
            scenes,
        }
    }
}

/// Every method on one scene.
#[derive(Debug, Clone, Serialize)]
pub struct LoaderScene {
    /// The scene's name or file.
    pub scene: String,
    /// Its objects.
    pub objects: usize,
    /// Its box's extent, per axis.
    pub extent: [f64; 3],
    /// q of the cost model (refine's default), per axis.
    pub query_extent: [f64; 3],
    /// One result per method, in the order run.
    pub methods: Vec<MethodResult>,
}

/// One method's tree and its query counts.
#[derive(Debug, Clone, Serialize)]
pub struct MethodResult {
    /// The method's name.
    pub method: &'static str,
    /// LAA's look-ahead; none for the other methods.
    pub look_ahead: Option<String>,
    /// Wall seconds of the build.
    pub build_seconds: f64,
    /// Leaves: one page each.
    pub pages: usize,
    /// The tree's depth.
    pub depth: u32,
    /// The cost model's expected leaf accesses for q = `query_extent`.
    pub expected_leaf_accesses: f64,
    /// The file, when the tree was written.
    pub file: Option<FileResult>,
    /// One result per query set.
    pub queries: Vec<SetResult>,
}

/// The file a tree was written to.
#[derive(Debug, Clone, Serialize)]
pub struct FileResult {
    /// Its block size.
    pub block_size: u32,
    /// Its node blocks.
    pub node_blocks: u64,
    /// Its geometry blocks.
    pub geometry_blocks: u64,
    /// Its size.
    pub file_bytes: u64,
}

/// Means per query of one query set.
#[derive(Debug, Clone, Serialize)]
pub struct SetResult {
    /// The set's label.
    pub query: String,
    /// The set's kind.
    #[serde(flatten)]
    pub kind: QueryKind,
    /// Leaves reached in the tree held in memory.
    pub leaves_visited: f64,
    /// The lower bound: leaves holding an object whose box meets the query.
    pub answer_leaves: f64,
    /// Objects whose box meets the query.
    pub answers: f64,
    /// With a file: exact node block reads (cold).
    pub node_reads: Option<f64>,
    /// With a file: exact geometry block reads (cold).
    pub geometry_reads: Option<f64>,
    /// With a file: all block reads (cold).
    pub reads: Option<f64>,
    /// With a file: exact answers.
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

/// Every method of `options` on `scene` (named `name`), each judged
/// against the references; `on_method` hears of each method as it starts.
pub fn bench_loaders(
    name: &str,
    scene: &Scene,
    options: &LoaderOptions,
    on_method: &mut dyn FnMut(Method),
) -> Result<LoaderScene, BenchError> {
    let boxes = scene.object_boxes();
    let sets: Vec<(QueryKind, Vec<Aabb>)> =
        QueryKind::STANDARD.iter().map(|k| (*k, k.generate(&boxes, options.queries, options.seed))).collect();
    let model = CostModel::of_boxes(&boxes, QueryExtent::Auto);
    let mut results = Vec::new();
    for &method in &options.methods {
        on_method(method);
        let params = BuildParams {
            method,
            rate: options.rate,
            leaf: options.leaf,
            look_ahead: LookAhead::Max,
            ..BuildParams::paper()
        };
        results.push(bench_method(scene, &boxes, &params, &sets, &model, options.block_size)?);
    }
    judge(&mut results);
    let e = scene.aabb().extent();
    Ok(LoaderScene {
        scene: name.to_string(),
        objects: scene.len(),
        extent: [e.x, e.y, e.z],
        query_extent: model.query_extent(),
        methods: results,
    })
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
) -> Result<MethodResult, BenchError> {
    let sizes: Vec<u64> = scene.objects().iter().map(|o| mktree::bulk::object_bytes(&o.mesh)).collect();
    let started = Instant::now();
    let tree = build(boxes, Some(&sizes), params, &|_| {}).map_err(mktree::Error::from)?;
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
) -> Result<FileResult, BenchError> {
    let path =
        std::env::temp_dir().join(format!("mktree-bench-build-{}-{}.mkt", std::process::id(), params.method));
    let _ = std::fs::remove_file(&path);
    let measured = (|| -> Result<FileResult, BenchError> {
        let db = Database::create(&path, CreateOptions { block_size, ..CreateOptions::default() })?;
        let mut w = db.begin_write()?;
        w.write_tree(scene, tree, params, build_seconds)?;
        w.commit()?;
        let txn = db.begin_read()?;
        let info = txn.info().ok_or_else(|| BenchError::Invalid("the committed file has no tree".into()))?;
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
