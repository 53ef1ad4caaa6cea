//! The peer benchmark (`mktree bench-peers`): mktree against the index an
//! embedder would otherwise pick, SQLite's R*Tree plus a table of geometry
//! blobs in pages of mktree's block size, on the same scene and queries,
//! with rstar's in-memory R-tree as a reference line.
//!
//! Per scene and query set: the mean pages (blocks) each side reads for the
//! exact answer and for the box filter, each query from a cold cache, with
//! their ratios; the answers, which must agree query by query (a
//! disagreement is an error, never a number); rstar's tests; both file
//! sizes; and the mean time of an exact query once every block is cached.

use std::path::{Path, PathBuf};
use std::time::Instant;

use mktree::geom::Aabb;
use mktree::scene::Scene;
use serde::Serialize;

use crate::error::{BenchError, io};
use crate::peers::mktree::{MktreePeer, build_file};
use crate::peers::rstar::RstarPeer;
use crate::peers::sqlite::{SqlitePeer, check_page_size};
use crate::query_sets::{COLLISION_MARGIN_MM, QueryKind};

/// Queries per generated set when none is asked for.
pub const DEFAULT_QUERIES: usize = 200;

/// How to run the benchmark.
#[derive(Debug, Clone, PartialEq)]
pub struct PeerOptions {
    /// Queries per generated set.
    pub queries: usize,
    /// Seed of the generated sets.
    pub seed: u64,
    /// mktree's block size and SQLite's page size, in bytes.
    pub block_size: u32,
    /// M, the levels of detail of mktree's file (the default, or 1 for none).
    pub lod_levels: u8,
    /// Query sets to run instead of the generated ones (see [`parse_query_file`]).
    pub query_sets: Option<Vec<QuerySet>>,
    /// Keep the built files here (`bench-peers-NAME.mkt`, `.sqlite`,
    /// replacing earlier ones); none: a temporary directory, removed after.
    pub files_dir: Option<PathBuf>,
}

/// A named list of query boxes.
#[derive(Debug, Clone, PartialEq)]
pub struct QuerySet {
    /// The kind of query: "box 5%", "collide +50", or a query file's label.
    pub label: String,
    /// The boxes, in mm.
    pub boxes: Vec<Aabb>,
}

/// One scene and query set: means per query over the set.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PeerRow {
    /// The scene as named.
    pub scene: String,
    /// Objects in the scene.
    pub objects: usize,
    /// The query set's label.
    pub set: String,
    /// Queries in the set.
    pub queries: usize,
    /// mktree's block size = SQLite's page size, bytes.
    pub block_size: u32,
    /// Objects whose triangles meet the query (both peers agree).
    pub exact_answers: f64,
    /// Objects whose stored box meets the query, by mktree's quantized
    /// boxes (a superset of the exact answer; it may differ from SQLite's
    /// on boxes that graze the query).
    pub mktree_filter_answers: f64,
    /// Objects whose f32 box in the R*Tree meets the query.
    pub sqlite_filter_answers: f64,
    /// mktree's block reads for the exact answer (level M).
    pub mktree_exact_reads: f64,
    /// Of which node blocks.
    pub mktree_exact_node_reads: f64,
    /// Of which geometry blocks.
    pub mktree_exact_geometry_reads: f64,
    /// The least mktree's exact answers could read on this file: the node
    /// blocks on the paths to the answer (the root's at least, for a query
    /// meeting its box), plus the geometry blocks read (of the objects its
    /// boxes and stored bounds left undecided).
    pub mktree_exact_lower_bound: f64,
    /// SQLite's page reads for the exact answer (R*Tree, then blobs).
    pub sqlite_exact_reads: f64,
    /// `mktree_exact_reads` / `sqlite_exact_reads`.
    pub exact_reads_ratio: Option<f64>,
    /// mktree's block reads for the box filter (level 1).
    pub mktree_filter_reads: f64,
    /// SQLite's page reads for the box filter (the R*Tree alone).
    pub sqlite_filter_reads: f64,
    /// `mktree_filter_reads` / `sqlite_filter_reads`.
    pub filter_reads_ratio: Option<f64>,
    /// The least mktree's box filter could read: the node blocks on the
    /// paths to its answer.
    pub mktree_filter_lower_bound: f64,
    /// Bytes mktree reads for the exact answer (reads x block size).
    pub mktree_exact_bytes: f64,
    /// Bytes SQLite reads for the exact answer (pages x page size).
    pub sqlite_exact_bytes: f64,
    /// Bytes mktree reads for the filter.
    pub mktree_filter_bytes: f64,
    /// Bytes SQLite reads for the filter.
    pub sqlite_filter_bytes: f64,
    /// rstar: inner nodes whose box the query tested.
    pub rstar_nodes_tested: f64,
    /// rstar: object boxes the query tested.
    pub rstar_leaves_tested: f64,
    /// The mktree file's size.
    pub mktree_file_bytes: u64,
    /// The SQLite file's size (after VACUUM).
    pub sqlite_file_bytes: u64,
    /// `mktree_file_bytes` / `sqlite_file_bytes`.
    pub file_bytes_ratio: Option<f64>,
    /// mktree's exact query time with every block cached, ms.
    pub mktree_warm_ms: f64,
    /// SQLite's exact query time with every page cached, ms.
    pub sqlite_warm_ms: f64,
    /// `mktree_warm_ms` / `sqlite_warm_ms`.
    pub warm_time_ratio: Option<f64>,
    /// Building the mktree file (once per scene), s.
    pub mktree_build_seconds: f64,
    /// Loading and vacuuming the SQLite file (once per scene), s.
    pub sqlite_load_seconds: f64,
}

/// The generated sets over object boxes `boxes`: boxes whose sides are 1%,
/// 5% and 20% of the scene's extent, and collisions (an object's box grown
/// by 50 mm).
pub fn standard_sets(boxes: &[Aabb], queries: usize, seed: u64) -> Vec<QuerySet> {
    [
        QueryKind::Box { share: 0.01 },
        QueryKind::Box { share: 0.05 },
        QueryKind::Box { share: 0.2 },
        QueryKind::Collision { margin_mm: COLLISION_MARGIN_MM },
    ]
    .iter()
    .map(|k| QuerySet { label: k.label(), boxes: k.generate(boxes, queries, seed) })
    .collect()
}

/// Query sets from a query file: one box per line, `x0,y0,z0,x1,y1,z1`
/// (mm) and optionally `,LABEL`, the set it belongs to ("file" when none).
/// Sets come in the order their labels first appear; blank lines and lines
/// starting with `#` are skipped.
pub fn parse_query_file(text: &str) -> Result<Vec<QuerySet>, BenchError> {
    let mut sets: Vec<QuerySet> = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let bad = |what: String| BenchError::Invalid(format!("query file line {}: {what}", n + 1));
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        let (numbers, label) = match fields.len() {
            6 => (&fields[..], "file"),
            7 => (&fields[..6], fields[6]),
            k => return Err(bad(format!("{k} fields; want x0,y0,z0,x1,y1,z1[,LABEL]"))),
        };
        let mut c = [0.0; 6];
        for (slot, text) in c.iter_mut().zip(numbers) {
            *slot = text
                .parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or_else(|| bad(format!("{text:?} is not a finite number")))?;
        }
        if c[0] > c[3] || c[1] > c[4] || c[2] > c[5] {
            return Err(bad("a box has x0 <= x1, y0 <= y1 and z0 <= z1".into()));
        }
        let q = Aabb::from_array(c);
        match sets.iter_mut().find(|s| s.label == label) {
            Some(s) => s.boxes.push(q),
            None => sets.push(QuerySet { label: label.to_string(), boxes: vec![q] }),
        }
    }
    if sets.is_empty() {
        return Err(BenchError::Invalid("the query file holds no query".into()));
    }
    Ok(sets)
}

/// Runs the benchmark on one scene named `name`: builds both files, runs
/// every query set (the options' own, or the standard ones) and returns a
/// row per set. `progress` hears each step.
///
/// ```
/// use mktree::scene::generate::{GenOptions, Preset, generate_scene};
/// use mktree_bench::{PeerOptions, bench_scene};
///
/// let scene = generate_scene(&GenOptions { preset: Preset::Tanker1, objects: None, seed: 0 })?;
/// let options = PeerOptions { queries: 3, seed: 1, block_size: 16384, lod_levels: 4, query_sets: None, files_dir: None };
/// let rows = bench_scene("tanker1", &scene, &options, &|step| eprintln!("{step}"))?;
/// assert_eq!(rows.len(), 4); // boxes of 1%, 5%, 20%, collisions
/// assert!(rows.iter().all(|r| r.sqlite_exact_reads > 0.0 && r.mktree_exact_reads > 0.0));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn bench_scene(
    name: &str,
    scene: &Scene,
    options: &PeerOptions,
    progress: &dyn Fn(&str),
) -> Result<Vec<PeerRow>, BenchError> {
    if scene.is_empty() {
        return Err(BenchError::Invalid(format!("{name}: the scene has no objects")));
    }
    // Before any file is built: the block size is also SQLite's page size.
    check_page_size(options.block_size)?;
    let boxes = scene.object_boxes();
    let sets = match &options.query_sets {
        Some(sets) => sets.clone(),
        None if options.queries == 0 => {
            return Err(BenchError::Invalid("queries per set must be at least 1".into()));
        }
        None => standard_sets(&boxes, options.queries, options.seed),
    };
    let scratch;
    let dir = match &options.files_dir {
        Some(dir) => {
            std::fs::create_dir_all(dir).map_err(io(format!("creating {}", dir.display())))?;
            dir.as_path()
        }
        None => {
            scratch = tempfile::tempdir().map_err(io("creating a temporary directory"))?;
            scratch.path()
        }
    };
    let stem = format!("bench-peers-{}", file_stem(name));
    let (mkt_path, sql_path) = (dir.join(format!("{stem}.mkt")), dir.join(format!("{stem}.sqlite")));
    for path in [&mkt_path, &sql_path] {
        remove_if_present(path)?;
    }
    progress(&format!("{name}: building the mktree file"));
    let mkt = build_file(scene, &mkt_path, options.block_size, options.lod_levels)?;
    let mktree_build_seconds = mkt.build_seconds();
    progress(&format!("{name}: loading the SQLite file"));
    let started = Instant::now();
    let sql = SqlitePeer::load(scene, &sql_path, options.block_size)?;
    let sqlite_load_seconds = started.elapsed().as_secs_f64();
    let rst = RstarPeer::load(&boxes);
    let peers = Peers { mkt: &mkt, sql: &sql, rst: &rst };
    let (mktree_file_bytes, sqlite_file_bytes) = (mkt.file_bytes()?, sql.file_bytes()?);
    let mut rows = Vec::new();
    for set in &sets {
        progress(&format!("{name}: {} ({} queries)", set.label, set.boxes.len()));
        let m = peers.measure(name, set)?;
        let n = set.boxes.len().max(1) as f64;
        let mean = |x: u64| x as f64 / n;
        let (block, page) = (f64::from(mkt.block_size()), f64::from(sql.page_size()));
        rows.push(PeerRow {
            scene: name.to_string(),
            objects: scene.len(),
            set: set.label.clone(),
            queries: set.boxes.len(),
            block_size: options.block_size,
            exact_answers: mean(m.exact_answers),
            mktree_filter_answers: mean(m.mktree_filter_answers),
            sqlite_filter_answers: mean(m.sqlite_filter_answers),
            mktree_exact_reads: mean(m.mktree_exact.total),
            mktree_exact_node_reads: mean(m.mktree_exact.node),
            mktree_exact_geometry_reads: mean(m.mktree_exact.geometry),
            mktree_exact_lower_bound: mean(m.mktree_exact_lower),
            sqlite_exact_reads: mean(m.sqlite_exact),
            exact_reads_ratio: ratio(m.mktree_exact.total as f64, m.sqlite_exact as f64),
            mktree_filter_reads: mean(m.mktree_filter),
            sqlite_filter_reads: mean(m.sqlite_filter),
            filter_reads_ratio: ratio(m.mktree_filter as f64, m.sqlite_filter as f64),
            mktree_filter_lower_bound: mean(m.mktree_filter_lower),
            mktree_exact_bytes: mean(m.mktree_exact.total) * block,
            sqlite_exact_bytes: mean(m.sqlite_exact) * page,
            mktree_filter_bytes: mean(m.mktree_filter) * block,
            sqlite_filter_bytes: mean(m.sqlite_filter) * page,
            rstar_nodes_tested: mean(m.rstar_nodes),
            rstar_leaves_tested: mean(m.rstar_leaves),
            mktree_file_bytes,
            sqlite_file_bytes,
            file_bytes_ratio: ratio(mktree_file_bytes as f64, sqlite_file_bytes as f64),
            mktree_warm_ms: m.mktree_warm_seconds / n * 1e3,
            sqlite_warm_ms: m.sqlite_warm_seconds / n * 1e3,
            warm_time_ratio: ratio(m.mktree_warm_seconds, m.sqlite_warm_seconds),
            mktree_build_seconds,
            sqlite_load_seconds,
        });
    }
    Ok(rows)
}

/// The three peers of one scene.
struct Peers<'a> {
    mkt: &'a MktreePeer,
    sql: &'a SqlitePeer,
    rst: &'a RstarPeer,
}

/// Sums over one query set.
#[derive(Default)]
struct Sums {
    exact_answers: u64,
    mktree_filter_answers: u64,
    sqlite_filter_answers: u64,
    mktree_exact: crate::peers::mktree::Reads,
    mktree_exact_lower: u64,
    sqlite_exact: u64,
    mktree_filter: u64,
    mktree_filter_lower: u64,
    sqlite_filter: u64,
    rstar_nodes: u64,
    rstar_leaves: u64,
    mktree_warm_seconds: f64,
    sqlite_warm_seconds: f64,
}

impl Peers<'_> {
    /// Runs every query of `set` on each peer, cold, checking that the
    /// answers agree; then times the exact answers warm.
    fn measure(&self, scene: &str, set: &QuerySet) -> Result<Sums, BenchError> {
        let mut s = Sums::default();
        let mut exact_answers = Vec::with_capacity(set.boxes.len());
        for (i, q) in set.boxes.iter().enumerate() {
            let at = |what: &str| format!("{scene}, {}, query {i} {q:?} ({what})", set.label);
            let (me, se) = (self.mkt.exact(q)?, self.sql.exact(q)?);
            agree(&at("exact answer"), ("mktree", &me.objects), ("SQLite", &se.objects))?;
            let (mf, sf) = (self.mkt.filter(q)?, self.sql.filter(q)?);
            let r = self.rst.query(q);
            // The R*Tree and rstar hold the same f32 boxes; mktree's are
            // quantized otherwise, so its filter need only hold the exact answer.
            agree(&at("box filter"), ("rstar", &r.objects), ("SQLite", &sf.objects))?;
            holds(&at("mktree's box filter"), &mf.objects, &me.objects)?;
            holds(&at("SQLite's box filter"), &sf.objects, &me.objects)?;
            s.exact_answers += me.objects.len() as u64;
            s.mktree_filter_answers += mf.objects.len() as u64;
            s.sqlite_filter_answers += sf.objects.len() as u64;
            s.mktree_exact.node += me.reads.node;
            s.mktree_exact.geometry += me.reads.geometry;
            s.mktree_exact.total += me.reads.total;
            s.mktree_exact_lower += self.mkt.answer_node_blocks(q, &me.objects) + me.reads.geometry;
            s.mktree_filter_lower += self.mkt.answer_node_blocks(q, &mf.objects);
            s.sqlite_exact += se.pages;
            s.mktree_filter += mf.reads.total;
            s.sqlite_filter += sf.pages;
            s.rstar_nodes += r.nodes;
            s.rstar_leaves += r.leaves;
            exact_answers.push(me.objects);
        }
        // Warm: a pass fills each side's cache, then the timed pass runs
        // the same queries, alternating sides so both share the machine's
        // load of the moment.
        let cache = self.mkt.warm_cache();
        let warm = self.sql.warm()?;
        for q in &set.boxes {
            self.mkt.warm_exact(&cache, q)?;
            warm.exact(q)?;
        }
        for ((i, q), want) in set.boxes.iter().enumerate().zip(&exact_answers) {
            let at = |what: &str| format!("{scene}, {}, query {i} {q:?} ({what})", set.label);
            let started = Instant::now();
            let m = self.mkt.warm_exact(&cache, q)?;
            s.mktree_warm_seconds += started.elapsed().as_secs_f64();
            let started = Instant::now();
            let l = warm.exact(q)?;
            s.sqlite_warm_seconds += started.elapsed().as_secs_f64();
            agree(&at("warm exact answer"), ("mktree", &m.objects), ("mktree cold", want))?;
            agree(&at("warm exact answer"), ("SQLite", &l.objects), ("SQLite cold", want))?;
            if m.reads.total > 0 || l.pages > 0 {
                return Err(BenchError::Invalid(format!(
                    "{}: warm, mktree read {} blocks and SQLite {} pages: a cache does not hold the file",
                    at("warm exact answer"),
                    m.reads.total,
                    l.pages
                )));
            }
        }
        Ok(s)
    }
}

/// An error naming the objects of `exact` that the filter `filter` lost.
fn holds(at: &str, filter: &[u32], exact: &[u32]) -> Result<(), BenchError> {
    let lost: Vec<u32> = exact.iter().filter(|o| filter.binary_search(o).is_err()).copied().collect();
    if lost.is_empty() {
        return Ok(());
    }
    Err(BenchError::Mismatch(format!("{at} lost exact answers {lost:?}")))
}

/// An error naming the query and the objects only one side found, unless
/// both sides, each a name and its ids, hold the same ids.
pub(crate) fn agree(
    at: &str,
    (a_name, a): (&str, &[u32]),
    (b_name, b): (&str, &[u32]),
) -> Result<(), BenchError> {
    if a == b {
        return Ok(());
    }
    let only = |a: &[u32], b: &[u32]| -> Vec<u32> { a.iter().filter(|x| !b.contains(x)).copied().collect() };
    let few = |v: Vec<u32>| -> String {
        let shown: Vec<String> = v.iter().take(8).map(u32::to_string).collect();
        let more = if v.len() > 8 { format!(" and {} more", v.len() - 8) } else { String::new() };
        format!("[{}]{more}", shown.join(", "))
    };
    Err(BenchError::Mismatch(format!(
        "answers differ on {at}: {a_name} {} objects, {b_name} {}; only {a_name}: {}; only {b_name}: {}",
        a.len(),
        b.len(),
        few(only(a, b)),
        few(only(b, a)),
    )))
}

/// `a / b`, none when `b` is 0.
fn ratio(a: f64, b: f64) -> Option<f64> {
    (b > 0.0).then(|| a / b)
}

/// A file name made of the scene's name: its file stem for a path, letters,
/// digits and dashes only.
fn file_stem(name: &str) -> String {
    let base = Path::new(name).file_stem().and_then(|s| s.to_str()).unwrap_or(name);
    base.chars().map(|c| if c.is_ascii_alphanumeric() { c } else { '-' }).collect()
}

fn remove_if_present(path: &Path) -> Result<(), BenchError> {
    match std::fs::remove_file(path) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
            Err(BenchError::Io { what: format!("removing {}", path.display()), source: e })
        }
        _ => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_query_file_gives_labelled_sets_in_order() {
        let text = "# a comment\n0,0,0,1,1,1,near\n\n2,2,2,3,3,3\n -1, -1, -1, 0, 0, 0 , near\n";
        let sets = parse_query_file(text).unwrap();
        assert_eq!(sets.len(), 2);
        assert_eq!((sets[0].label.as_str(), sets[0].boxes.len()), ("near", 2));
        assert_eq!(sets[0].boxes[1], Aabb::from_array([-1.0, -1.0, -1.0, 0.0, 0.0, 0.0]));
        assert_eq!((sets[1].label.as_str(), sets[1].boxes.len()), ("file", 1));
    }

    #[test]
    fn a_bad_query_file_names_the_line_and_the_fault() {
        let err = |t: &str| parse_query_file(t).unwrap_err().to_string();
        assert_eq!(
            err("0,0,0,1,1,1\n0,0,0,1,1"),
            "query file line 2: 5 fields; want x0,y0,z0,x1,y1,z1[,LABEL]"
        );
        assert_eq!(err("0,0,x,1,1,1"), "query file line 1: \"x\" is not a finite number");
        assert_eq!(err("0,0,inf,1,1,1"), "query file line 1: \"inf\" is not a finite number");
        assert_eq!(err("2,0,0,1,1,1"), "query file line 1: a box has x0 <= x1, y0 <= y1 and z0 <= z1");
        assert_eq!(err("# nothing\n"), "the query file holds no query");
    }

    #[test]
    fn a_disagreement_names_the_objects_one_side_found() {
        assert!(agree("q", ("mktree", &[1, 2]), ("SQLite", &[1, 2])).is_ok());
        let e = agree("q", ("mktree", &[1, 2, 3]), ("SQLite", &[2, 4])).unwrap_err().to_string();
        assert_eq!(
            e,
            "answers differ on q: mktree 3 objects, SQLite 2; only mktree: [1, 3]; only SQLite: [4]"
        );
    }

    #[test]
    fn files_are_named_after_the_scene() {
        assert_eq!(file_stem("ship:100000"), "ship-100000");
        assert_eq!(file_stem("scenes/plant.obj"), "plant");
        assert_eq!(ratio(1.0, 0.0), None);
        assert_eq!(ratio(1.0, 4.0), Some(0.25));
    }
}
