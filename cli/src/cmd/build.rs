//! `mktree build`: bulk-load a scene into an .mkt file in one write
//! transaction (replacing the tree of an existing file atomically).

use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use indicatif::{ProgressBar, ProgressStyle};
use mktree::build::{BuildProgress, Hierarchy, Report, build, estimate_work};
use mktree::db::{CreateOptions, Database, WriterWait};
use mktree::scene::Scene;
use mktree::store::format::geometry::record_len;
use serde_json::json;

use crate::args::{BuildArgs, LodArgs};
use crate::output;

/// A progress bar over objects placed in leaves (on stderr, hidden when not a terminal).
fn progress_bar(scene: &Scene, build: &BuildArgs) -> ProgressBar {
    let pb = ProgressBar::new(scene.len() as u64);
    pb.set_style(
        ProgressStyle::with_template(
            "{spinner} building [{bar:40}] {pos}/{len} objects placed {msg} ({elapsed})",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let work = estimate_work(scene.len(), None, &build.params());
    pb.set_message(format!("~{work:.2e} object visits estimated"));
    pb
}

/// Builds the tree of `scene` in memory, with a progress bar.
pub fn build_in_memory(scene: &Scene, args: &BuildArgs) -> Result<Hierarchy> {
    let sizes: Vec<u64> = scene.objects().iter().map(|o| record_len(&o.mesh)).collect();
    let pb = progress_bar(scene, args);
    let tree = build(&scene.object_boxes(), Some(&sizes), &args.params(), &|p: BuildProgress| {
        pb.set_position(p.objects_placed)
    })?;
    pb.finish_and_clear();
    Ok(tree)
}

pub fn run(
    scene_path: &Path,
    out: &Path,
    args: &BuildArgs,
    lod: &LodArgs,
    wait: bool,
    as_json: bool,
) -> Result<()> {
    let scene = crate::cmd::read_scene(scene_path, &args.import.options())?;
    let started = Instant::now();
    let db = if out.exists() {
        let db = Database::open(out).with_context(|| format!("opening {}", out.display()))?;
        if args.block_size.is_some_and(|b| b != db.block_size()) {
            bail!("{} has {}-byte blocks; a new block size needs a new file", out.display(), db.block_size());
        }
        if lod.lods.is_some_and(|m| m != db.lod_levels()) {
            bail!("{} has {} levels of detail; a new M needs a new file", out.display(), db.lod_levels());
        }
        db
    } else {
        Database::create(
            out,
            CreateOptions {
                block_size: args.block_size(),
                lod_levels: lod.lods.unwrap_or(mktree::db::DEFAULT_LOD_LEVELS),
            },
        )
        .with_context(|| format!("creating {}", out.display()))?
    };
    let pb = progress_bar(&scene, args);
    let mut w = db.begin_write_with(if wait { WriterWait::Wait } else { WriterWait::Fail })?;
    w.set_lod_params(lod.params());
    let tree = w.bulk_load(&scene, &args.params(), &|p: BuildProgress| pb.set_position(p.objects_placed))?;
    w.commit()?;
    pb.finish_and_clear();
    let seconds = started.elapsed().as_secs_f64();
    let info = db.begin_read()?.info().context("the committed file has no tree")?;
    let bytes = u64::from(info.file_blocks) * u64::from(info.block_size);
    let report = Report::of(&tree);
    if as_json {
        return output::json(
            &json!({ "file": info, "file_bytes": bytes, "seconds": seconds, "report": report }),
        );
    }
    println!(
        "{}: {} objects, {} nodes ({} leaves, {} levels) in {} blocks of {} bytes ({} node, {} geometry), {} bytes; {:.3} s ({:.1} MB/s written)",
        out.display(),
        info.objects,
        info.nodes,
        info.leaves,
        report.depth,
        info.file_blocks,
        info.block_size,
        info.node_blocks,
        info.geometry_blocks,
        bytes,
        seconds,
        bytes as f64 / seconds / 1e6
    );
    Ok(())
}
