//! `mktree demo`: the README's first command. In well under a minute, on
//! the built-in tanker2 scene (the paper's Oil_Tanker_2): the default file
//! against SQLite's R*Tree with geometry blobs on the same queries, as block
//! reads per exact answer; one collision query with what decided each
//! object, level by level; and the speed-accuracy chart of the levels of
//! detail, written to files it names.

use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result};
use mktree::geom::Pose;
use mktree::query::{
    CollideOptions, Proof, TRADEOFF_SHIFT_MM, collide, collision_workload, object_mesh, tradeoff,
};
use mktree::scene::ObjectId;
use mktree::scene::generate::{GenOptions, Preset, generate_scene};
use mktree_bench::{PeerOptions, bench_scene};

use crate::chart::{self, Tradeoff};
use crate::cmd::bench_peers::{Bench, print_tables};
use crate::output;

/// Queries per set against SQLite, and collision queries of the chart.
const QUERIES: usize = 100;

pub fn run(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let started = Instant::now();
    let scene = generate_scene(&GenOptions { preset: Preset::Tanker2, objects: None, seed: 0 })?;
    let e = scene.aabb().extent();
    println!(
        "tanker2: {} objects, {} triangles, {:.0} x {:.0} x {:.0} mm\n",
        scene.len(),
        scene.triangle_count(),
        e.x,
        e.y,
        e.z
    );
    // 1. The default file against SQLite on the same queries, cold.
    println!("1. Block reads per query against SQLite (R*Tree + geometry blobs, same page size), cold:\n");
    let options = PeerOptions {
        queries: QUERIES,
        seed: 0,
        block_size: 16384,
        lod_levels: mktree::db::DEFAULT_LOD_LEVELS,
        query_sets: None,
        files_dir: Some(dir.into()),
    };
    let rows = bench_scene("tanker2", &scene, &options, &|_| {})?;
    print_tables(
        &Bench { queries: Some(QUERIES), seed: 0, block_size: 16384, query_file: None, rows: rows.clone() },
        &[rows],
    );
    // 2. One collision query, with what decided each object.
    let file = dir.join("bench-peers-tanker2.mkt");
    let db = crate::cmd::open_to_read(&file)?;
    let r = db.begin_read()?;
    let id = ObjectId(1000);
    let mesh = object_mesh(&r, id)?;
    let pose = Pose::from_degrees([40.0, 0.0, 25.0], [0.0, 0.0, 5.0])?;
    let opts = CollideOptions { clearance: 10.0, exclude: Some(id), ..CollideOptions::default() };
    let a = collide(&r, &mesh, &pose, &opts, None)?;
    println!(
        "\n2. Object {id} moved by (40, 0, 25) mm and turned 5 degrees: {} objects within {} mm, in {} block reads ({} node, {} geometry)",
        a.objects.len(),
        opts.clearance,
        a.stats.reads.total(),
        a.stats.reads.node,
        a.stats.reads.geometry
    );
    let count = |proof: Proof, accepted: bool| {
        a.decided.iter().filter(|d| d.proof == proof && d.accepted == accepted).count()
    };
    let table: Vec<Vec<String>> = [
        ("ruled out by its box (level 1)", count(Proof::BoxMisses, false)),
        ("ruled out by its voxel bound (levels 2 .. M-1)", count(Proof::VoxelsMiss, false)),
        ("proved by a face of its box (level 1)", count(Proof::Face, true)),
        ("proved by a cell of its voxel bound", count(Proof::Cell, true)),
        ("read and tested exactly (level M): meets", count(Proof::Exact, true)),
        ("read and tested exactly (level M): misses", count(Proof::Exact, false)),
    ]
    .iter()
    .map(|(what, n)| vec![what.to_string(), n.to_string()])
    .collect();
    output::table(&["objects met by the query's box", "count"], &table);
    // 3. The speed-accuracy trade-off of the levels of detail, as a chart.
    let workload = collision_workload(&r, QUERIES, 0)?;
    let levels = tradeoff(&r, &workload)?;
    println!(
        "\n3. {QUERIES} collision queries (objects moved up to {TRADEOFF_SHIFT_MM} mm) answered at each level the file stores:\n"
    );
    let table: Vec<Vec<String>> = levels
        .iter()
        .map(|l| {
            vec![
                l.level.to_string(),
                format!("{:.2}", l.mean_reads),
                format!("{:.3}", l.precision),
                format!("{:.3}", l.mean_milliseconds),
            ]
        })
        .collect();
    output::table(&["k", "reads per query", "precision", "ms per query"], &table);
    let (svg, png) = (dir.join("tradeoff.svg"), dir.join("tradeoff.png"));
    let series = [Tradeoff {
        name: "tanker2".into(),
        points: levels.iter().map(|l| (l.mean_reads, l.precision, l.level)).collect(),
    }];
    chart::tradeoff(&series, &svg, &png)?;
    println!(
        "\nchart: {} (and {}); files: {} and the SQLite database beside it; {:.1} s",
        svg.display(),
        png.display(),
        file.display(),
        started.elapsed().as_secs_f64()
    );
    Ok(())
}
