//! `mktree demo`: the README's first command. In a few seconds, on the
//! generated tanker2 scene (after the paper's Oil_Tanker_2), one sentence
//! per result:
//!
//! 1. the default file against SQLite's R*Tree with a table of geometry
//!    blobs, on the same queries: block reads per exact answer and per box
//!    filter, and the files' sizes (`mktree_bench::bench_scene`; the wide
//!    table is `mktree bench-peers`');
//! 2. a file of five levels of detail (box, cuberille, voxel sets of 100
//!    and 25 mm, exact), each bound stored only where the read model says
//!    it pays: clearance queries (which objects come within 200 mm of a
//!    moved object) answered exactly with and without the levels below M
//!    (`mktree_bench::collision_levels`), the default file on the same
//!    queries, and the query where the levels saved most, decided level by
//!    level;
//! 3. the speed-accuracy trade-off of both files' levels on those queries
//!    (`mktree::query::tradeoff`), as sentences and as a chart (SVG, PNG).

use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result};
use mktree::db::{CreateOptions, DEFAULT_LOD_LEVELS, Database};
use mktree::query::{TRADEOFF_SHIFT_MM, TradeoffRow, collision_workload, tradeoff};
use mktree::scene::Scene;
use mktree::scene::generate::{GenOptions, Preset, generate_scene};
use mktree::{BuildParams, LodParams, ReadTransaction};
use mktree_bench::{LevelsQuery, PeerOptions, PeerRow, bench_scene, collision_levels};

use crate::chart::{self, Tradeoff};
use crate::output;

/// Queries per set against SQLite, and clearance queries.
const QUERIES: usize = 100;
/// Block size of both files, and SQLite's page size.
const BLOCK: u32 = 16384;
/// M of the file that shows the levels deciding collisions.
const LEVELS: u8 = 5;
/// eps of its voxel levels 3 and 4, mm: the default (from the median
/// object's sides, 328 mm on tanker2) is coarser than the scene's pipes.
const EPS_MM: [f64; 2] = [100.0, 25.0];
/// How far each query object moves along each axis, at most, mm.
const SHIFT_MM: f64 = 100.0;
/// The clearance asked for, mm: an object within it of the moved one
/// collides. At 0, a bound can rule an object out but never prove a
/// contact (that takes the surfaces); at 200 mm a surface cell of a bound
/// inside the clearance zone proves one.
const CLEARANCE_MM: f64 = 200.0;

pub fn run(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let started = Instant::now();
    let scene = generate_scene(&GenOptions { preset: Preset::Tanker2, objects: None, seed: 0 })?;
    let e = scene.aabb().extent();
    println!(
        "tanker2, a generated oil-tanker block after the paper's Oil_Tanker_2: {} objects, {} triangles, \
         {:.1} x {:.1} x {:.1} m.\n",
        scene.len(),
        scene.triangle_count(),
        e.x / 1e3,
        e.y / 1e3,
        e.z / 1e3
    );

    // 1. The default file against SQLite on the same queries, cold.
    let options = PeerOptions {
        queries: QUERIES,
        seed: 0,
        block_size: BLOCK,
        lod_levels: DEFAULT_LOD_LEVELS,
        query_sets: None,
        files_dir: Some(dir.into()),
    };
    let rows = bench_scene("tanker2", &scene, &options, &|_| {})?;
    println!(
        "1. Against SQLite: an R*Tree of the objects' boxes and a table of their geometry in 16 KiB pages, \
         beside the default mktree file of 16 KiB blocks; {QUERIES} queries per set, each from a cold cache, \
         the same answers from both.\n"
    );
    for row in &rows {
        print_peer_sentence(row);
    }
    print_filter_and_files(&rows);

    // 2. Clearance queries decided level by level, in a file of five levels.
    let default_file = dir.join("bench-peers-tanker2.mkt");
    let m5 = dir.join("tanker2-m5.mkt");
    build_levels_file(&scene, &m5)?;
    let (default_db, m5_db) = (crate::input::open_to_read(&default_file)?, crate::input::open_to_read(&m5)?);
    let (default_r, m5_r) = (default_db.begin_read()?, m5_db.begin_read()?);
    let queries = collision_levels(&m5_r, QUERIES, SHIFT_MM, CLEARANCE_MM, 0)?;
    let default_queries = collision_levels(&default_r, QUERIES, SHIFT_MM, CLEARANCE_MM, 0)?;
    print_levels(&queries, &default_queries, &m5);

    // 3. Speed against accuracy, both files, the same queries.
    let m5_rows = tradeoff_of(&m5_r)?;
    let default_rows = tradeoff_of(&default_r)?;
    println!(
        "\n3. Speed against accuracy (`mktree tradeoff`): {QUERIES} collision queries (objects moved up to \
         {TRADEOFF_SHIFT_MM} mm, clearance 0, their own originals among the answers) stopped at each level k, \
         which keeps every object that level k cannot rule out:\n"
    );
    print_tradeoff("Five-level file", &m5_rows);
    print_tradeoff("Default file", &default_rows);
    let (svg, png) = (dir.join("tradeoff.svg"), dir.join("tradeoff.png"));
    let series = [
        Tradeoff {
            name: format!("tanker2, M = {LEVELS}, eps {} and {} mm", EPS_MM[0], EPS_MM[1]),
            points: points(&m5_rows),
        },
        Tradeoff { name: "tanker2, default file (M = 4)".into(), points: points(&default_rows) },
    ];
    chart::tradeoff(&series, &svg, &png)?;
    println!(
        "\nThe chart: {} and {}. The files: {}, {} and the SQLite database beside them. {:.1} s.",
        svg.display(),
        png.display(),
        default_file.display(),
        m5.display(),
        started.elapsed().as_secs_f64()
    );
    Ok(())
}

/// A query set's label as words: "box 5%" -> "boxes of 5% of the scene's extent".
fn set_words(set: &str) -> String {
    if let Some(share) = set.strip_prefix("box ") {
        format!("boxes of {share} of the scene's extent")
    } else if let Some(mm) = set.strip_prefix("collide +") {
        format!("objects' boxes grown by {mm} mm")
    } else {
        set.to_string()
    }
}

fn print_peer_sentence(row: &PeerRow) {
    let ratio = row.exact_reads_ratio.map_or("no ratio".into(), |r| format!("{r:.2}"));
    println!(
        "   Exact answers to {} ({:.1} objects each) read {:.2} blocks per query: {ratio} of the {:.2} pages \
         SQLite reads.",
        set_words(&row.set),
        row.exact_answers,
        row.mktree_exact_reads,
        row.sqlite_exact_reads
    );
}

fn print_filter_and_files(rows: &[PeerRow]) {
    let ratios: Vec<f64> = rows.iter().filter_map(|r| r.filter_reads_ratio).collect();
    let (lo, hi) = ratios.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), &r| (lo.min(r), hi.max(r)));
    if !ratios.is_empty() {
        println!(
            "   The box filter alone (every object whose stored box meets the query) reads {lo:.2} to {hi:.2} of \
             SQLite's pages."
        );
    }
    if let Some(row) = rows.first() {
        println!(
            "   The file is {:.2} times the size of SQLite's ({:.2} MB against {:.2} MB). Every figure in a table: \
             `mktree bench-peers tanker2`.",
            row.mktree_file_bytes as f64 / row.sqlite_file_bytes.max(1) as f64,
            row.mktree_file_bytes as f64 / 1e6,
            row.sqlite_file_bytes as f64 / 1e6
        );
    }
}

/// tanker2 in a new file at `path` of `LEVELS` levels, eps `EPS_MM`, each
/// bound stored where it pays (the default policy).
fn build_levels_file(scene: &Scene, path: &Path) -> Result<()> {
    if path.exists() {
        std::fs::remove_file(path).with_context(|| format!("replacing {}", path.display()))?;
    }
    let db = Database::create(path, CreateOptions { block_size: BLOCK, lod_levels: LEVELS })
        .map_err(|e| crate::input::opening(e, path))?;
    let mut w = db.begin_write()?;
    w.set_lod_params(LodParams { eps: Some(EPS_MM.to_vec()), ..LodParams::default() });
    w.bulk_load(scene, &BuildParams::default(), &|_| {})?;
    w.commit()?;
    Ok(())
}

/// What level k of the five-level file tests.
fn level_words(k: usize, m: usize) -> String {
    match k {
        1 => "1, its box".into(),
        2 => "2, its cuberille".into(),
        k if k == m => format!("{k}, its exact triangles"),
        k => format!("{k}, its voxel set of {} mm", EPS_MM.get(k - 3).copied().unwrap_or(0.0)),
    }
}

/// "1 object", "2 objects".
fn objects(n: u64) -> String {
    format!("{n} object{}", if n == 1 { "" } else { "s" })
}

/// Mean of `f` over the queries.
fn mean(queries: &[LevelsQuery], f: impl Fn(&LevelsQuery) -> u64) -> f64 {
    queries.iter().map(f).sum::<u64>() as f64 / queries.len().max(1) as f64
}

fn print_levels(queries: &[LevelsQuery], default_queries: &[LevelsQuery], file: &Path) {
    println!(
        "\n2. Levels of detail in clearance queries: tanker2 again, in a file of {LEVELS} levels (box, cuberille, \
         voxel sets of {} and {} mm, exact triangles), each bound stored only where it pays ({}).\n",
        EPS_MM[0],
        EPS_MM[1],
        file.display()
    );
    let between = |v: &Vec<u64>| v.iter().skip(1).take(v.len().saturating_sub(2)).sum::<u64>();
    let ruled_out: u64 = queries.iter().map(|q| between(&q.ruled_out)).sum();
    let proved: u64 = queries.iter().map(|q| between(&q.proved)).sum();
    println!(
        "   Over {} queries (an object moved up to {SHIFT_MM} mm along each axis: which objects come within \
         {CLEARANCE_MM} mm of it?), levels 2 to {} ruled out {} and proved {} to be within it, without reading \
         their triangles.",
        queries.len(),
        LEVELS - 1,
        objects(ruled_out),
        objects(proved)
    );
    println!(
        "   The exact answers read {:.2} blocks per query ({:.2} of geometry), against {:.2} ({:.2}) in the same \
         file read without its levels below {LEVELS}, and {:.2} ({:.2}) in the default file.",
        mean(queries, |q| q.reads),
        mean(queries, |q| q.geometry_reads),
        mean(queries, |q| q.reads_without_levels),
        mean(queries, |q| q.geometry_reads_without_levels),
        mean(default_queries, |q| q.reads),
        mean(default_queries, |q| q.geometry_reads)
    );
    let best =
        queries.iter().max_by_key(|q| (q.reads_saved(), q.decided_between(), std::cmp::Reverse(q.object)));
    let Some(best) = best else { return };
    let t = best.translate;
    println!(
        "   The query where they saved most: object {} moved by ({:.0}, {:.0}, {:.0}) mm has {} objects within \
         {CLEARANCE_MM} mm, found in {} block reads instead of {}. Where each object at the leaves it reached was \
         decided:\n",
        best.object, t[0], t[1], t[2], best.answer, best.reads, best.reads_without_levels
    );
    let m = best.ruled_out.len();
    let table: Vec<Vec<String>> = (1..=m)
        .map(|k| vec![level_words(k, m), best.ruled_out[k - 1].to_string(), best.proved[k - 1].to_string()])
        .collect();
    output::table(&["level k: the object's", "ruled out", "proved within clearance"], &table);
}

/// Every level of `txn`'s file on `mktree tradeoff`'s collision queries.
fn tradeoff_of(txn: &ReadTransaction) -> Result<Vec<TradeoffRow>> {
    Ok(tradeoff(txn, &collision_workload(txn, QUERIES, 0)?)?)
}

fn print_tradeoff(name: &str, rows: &[TradeoffRow]) {
    let words: Vec<String> = rows
        .iter()
        .map(|row| {
            if Some(row) == rows.last() {
                format!("level {} (exact) {:.2} reads and 100%", row.level, row.mean_reads)
            } else {
                format!("level {} {:.2} reads and {:.1}%", row.level, row.mean_reads, row.precision * 100.0)
            }
        })
        .collect();
    println!(
        "   {name}, block reads per query and share of the reported objects that collide: {}.",
        words.join("; ")
    );
}

fn points(rows: &[TradeoffRow]) -> Vec<(f64, f64, u8)> {
    rows.iter().map(|l| (l.mean_reads, l.precision, l.level)).collect()
}
