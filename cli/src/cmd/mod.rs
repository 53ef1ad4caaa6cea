//! One file per subcommand, each parsing nothing (`args.rs` does), calling
//! the library or `mktree-bench`, and printing (`output.rs`); `run`
//! dispatches. No file here imports another.

mod batch;
mod bench_build;
mod bench_changes;
mod bench_import;
mod bench_peers;
mod bench_queries;
mod bench_remote;
mod bench_replace;
mod bench_view;
mod build;
mod catalog;
mod check;
mod clash;
mod clash_status;
mod collide;
mod compact;
mod demo;
mod dump;
mod export_tiles;
mod gen_info;
mod get;
mod insert;
mod lods;
mod navigate;
mod optimize;
mod publish;
mod query;
mod remove;
mod render;
mod serve;
mod stats;
mod sweep;
mod tradeoff;
mod verify;
mod view;

use anyhow::Result;

use crate::args::{CatalogAction, Cli, Command};

/// Runs the parsed subcommand through its group's dispatch.
pub fn run(cli: Cli) -> Result<()> {
    match cli.command {
        c @ (Command::Gen { .. }
        | Command::Info { .. }
        | Command::Stats { .. }
        | Command::Dump { .. }
        | Command::Sweep { .. }
        | Command::Build { .. }
        | Command::Verify { .. }) => scenes(c),
        c @ (Command::Lods { .. }
        | Command::Node { .. }
        | Command::Query { .. }
        | Command::Collide { .. }
        | Command::Clash { .. }
        | Command::ClashStatus { .. }
        | Command::Get { .. }
        | Command::Catalog { .. }
        | Command::Check { .. }) => reads(c),
        c @ (Command::View { .. }
        | Command::Export3dTiles { .. }
        | Command::Serve { .. }
        | Command::Render { .. }
        | Command::Navigate { .. }) => views(c),
        c @ (Command::Batch { .. }
        | Command::Insert { .. }
        | Command::Move { .. }
        | Command::Remove { .. }
        | Command::Compact { .. }
        | Command::Publish { .. }
        | Command::Optimize { .. }) => writes(c),
        c @ (Command::Tradeoff { .. }
        | Command::Demo { .. }
        | Command::BenchQueries { .. }
        | Command::BenchBuild(_)
        | Command::BenchPeers(_)
        | Command::BenchRemote(_)
        | Command::BenchReplace(_)
        | Command::BenchChanges(_)
        | Command::BenchChangesWorker(_)
        | Command::BenchView(_)
        | Command::BenchImport { .. }) => benches(c),
    }
}

/// A subcommand `run` sent to another group's dispatch: a bug in `run`,
/// reported as an error rather than a panic.
fn misrouted(command: &Command) -> Result<()> {
    anyhow::bail!("internal error: the dispatch sent {command:?} to the wrong group")
}

/// Scenes: generate, describe, build into a file (or in memory) and verify.
fn scenes(command: Command) -> Result<()> {
    match command {
        Command::Gen { preset, objects, seed, output } => gen_info::generate(&preset, objects, seed, &output),
        Command::Info { scene, json, import } => gen_info::info(&scene, &import.options(), json),
        Command::Stats { input, build, json } => stats::run(&input, &build, json),
        Command::Dump { input, build, json } => dump::run(&input, &build, json),
        Command::Sweep { scene, pages, rates, look_ahead, json, import } => {
            sweep::run(&scene, &import.options(), pages, &rates, look_ahead, json)
        }
        Command::Build { scene, output, build, lod, wait, key_names, memory, stage, json } => {
            build::run(&scene, &output, &build, &lod, build::Write { wait, key_names, memory, stage }, json)
        }
        Command::Verify { file, scene, queries, json, import } => {
            verify::run(&file, &scene, queries, &import.options(), json)
        }
        other => misrouted(&other),
    }
}

/// Reads of a file: its levels and nodes, queries, clashes, a key's object, its check.
fn reads(command: Command) -> Result<()> {
    match command {
        Command::Lods { file, json } => lods::table(&file, json),
        Command::Node { file, node, lod, objects, export, json } => {
            lods::node(&file, node, lod, objects, export.as_deref(), json)
        }
        Command::Query { file, shape, level, json } => {
            query::run(&file, &query::shape(&shape)?, &level.options(), json)
        }
        Command::Collide { file, mesh, object, translate, rotate_deg, clearance, level, json, import } => {
            let query = collide::Query { mesh, object, translate, rotate_deg, clearance };
            collide::run(&file, &query, &level.options(), &import.options(), json)
        }
        Command::Clash { file, clearance, lod, json, typed } if typed.any() => {
            if clearance != 0.0 || lod.is_some() {
                anyhow::bail!(
                    "--clearance and --lod belong to the untyped run: a typed test takes --distance"
                );
            }
            clash::typed(&file, &typed, json)
        }
        Command::Clash { file, clearance, lod, json, .. } => clash::run(&file, clearance, lod, json),
        Command::ClashStatus { file, test, a, b, kind, set, text, store, json } => {
            let pair = clash_status::Pair { a, b, kind, set, text };
            clash_status::run(&file, &test, &pair, store.as_deref(), json)
        }
        Command::Get { file, key, text, mesh, json } => {
            get::run(&file, &crate::input::parse_key(&key, text)?, mesh, json)
        }
        Command::Check { file, json } => check::run(&file, json),
        Command::Catalog { action } => match action {
            CatalogAction::Create { output, models, json } => catalog::create(&output, &models, json),
            CatalogAction::Show { catalog, json } => catalog::show(&catalog, json),
            CatalogAction::Query { catalog, shape, level, concurrency, json } => {
                let region = query::shape(&shape)?;
                catalog::query(&catalog, &region, &level.options(), concurrency, json)
            }
        },
        other => misrouted(&other),
    }
}

/// Views of a file: the view's cut, 3D Tiles and their server, pictures, a camera's path.
fn views(command: Command) -> Result<()> {
    match command {
        Command::View { file, view } => view::run(&file, &view),
        Command::Export3dTiles { file, out, json } => export_tiles::run(&file, &out, json),
        Command::Serve { tiles, port, vendor } => serve::run(&tiles, port, vendor.as_deref()),
        Command::Render { file, view, node, lod, objects, output, json } => {
            let what = match (node, lod) {
                (Some(node), Some(k)) => render::What::Node { node, k, objects },
                _ => render::What::Cut,
            };
            render::run(&file, &view, what, &output, json)
        }
        Command::Navigate {
            file,
            path,
            cache_blocks,
            fov_deg,
            aspect,
            near,
            far,
            lod,
            tolerance,
            height_px,
            budget,
            json,
        } => {
            let lens = [fov_deg, aspect, near, far];
            match tolerance {
                Some(tau) => {
                    let opts = mktree::ViewOptions { tolerance_px: tau, budget, shapes: false };
                    navigate::run_view(&file, &path, cache_blocks, lens, height_px, &opts, json)
                }
                None => navigate::run(&file, &path, cache_blocks, lens, lod, json),
            }
        }
        other => misrouted(&other),
    }
}

/// Changes to a file: a batch of requests, inserts, moves, removals, compaction, a new layout.
fn writes(command: Command) -> Result<()> {
    match command {
        Command::Batch { file, queries, max_line, commit_every, wait } => {
            batch::run(&file, queries.as_deref(), max_line, commit_every, wait)
        }
        Command::Insert { file, scene, key_names, json } => {
            insert::run_insert(&file, &scene, key_names, json)
        }
        Command::Move { file, key, text, by, json } => {
            insert::run_move(&file, &crate::input::parse_key(&key, text)?, by, json)
        }
        Command::Remove { file, keys, text, wait, json } => {
            let keys = keys.iter().map(|k| crate::input::parse_key(k, text)).collect::<Result<Vec<_>>>()?;
            remove::run(&file, &keys, wait, json)
        }
        Command::Compact { file, wait, json } => compact::run(&file, wait, json),
        Command::Publish { file, url, json } => publish::run(&file, &url, json),
        Command::Optimize { file, wait, json } => optimize::run(&file, wait, json),
        other => misrouted(&other),
    }
}

/// Measurements: the benches, the tradeoff over levels, and the demo that runs them.
fn benches(command: Command) -> Result<()> {
    match command {
        Command::Tradeoff { files, queries, seed, out, json } => {
            tradeoff::run(&files, queries, seed, &out, json)
        }
        Command::Demo { dir } => demo::run(&dir),
        Command::BenchQueries { files, queries, shares, seed, json } => {
            bench_queries::run(&files, queries, &shares, seed, json)
        }
        Command::BenchBuild(args) => bench_build::run(&args),
        Command::BenchPeers(args) => bench_peers::run(&args),
        Command::BenchRemote(args) => bench_remote::run(&args),
        Command::BenchReplace(args) => bench_replace::run(&args),
        Command::BenchChanges(args) => bench_changes::run(&args),
        Command::BenchChangesWorker(args) => bench_changes::worker(&args),
        Command::BenchView(args) => bench_view::run(&args),
        Command::BenchImport { files, repeat, json, import } => {
            bench_import::run(&files, repeat, &import, json)
        }
        other => misrouted(&other),
    }
}
