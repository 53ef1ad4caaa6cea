//! `mktree build`: bulk-load a scene into an .mkt file in one write
//! transaction (replacing the tree of an existing file atomically, or an
//! empty or torn file that a crash left while creating one).

use std::path::Path;
use std::sync::{Mutex, MutexGuard, PoisonError};
use std::time::Instant;

use anyhow::{Context, Result, bail};
use indicatif::{ProgressBar, ProgressStyle};
use mktree::bulk::{Hierarchy, LoadProgress, Report, Stage, TimeLeft, TimeLeftCheck};
use mktree::db::{CreateOptions, Database, StagedScene, WriterWait};
use mktree::scene::Scene;
use mktree::store::StorageError;
use serde_json::json;

use crate::args::{BuildArgs, LodArgs};
use crate::output;

/// Each stage of a build as it ended: its wall seconds, the process's
/// peak resident memory by then (Linux; `null` elsewhere), and how the
/// time left its progress bar told compared with the time it took (none
/// for the read and commit, which tell none). `build --json` reports
/// them, so that a long build shows which stage takes the time, which one
/// sets the peak, and whether its bar could be believed.
#[derive(Debug, Clone, serde::Serialize)]
struct StageRow {
    stage: &'static str,
    seconds: f64,
    peak_rss_bytes: Option<u64>,
    time_left: Vec<TimeLeftCheck>,
}

/// The stages ended so far, when the current one began, and the clock
/// that tells the time left in it.
struct Stages(Mutex<(Vec<StageRow>, Instant, TimeLeft)>);

impl Stages {
    fn new() -> Stages {
        Stages(Mutex::new((Vec::new(), Instant::now(), TimeLeft::new())))
    }

    fn lock(&self) -> MutexGuard<'_, (Vec<StageRow>, Instant, TimeLeft)> {
        self.0.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Ends stage `stage`, which began when the one before ended.
    fn end(&self, stage: &'static str) {
        let mut guard = self.lock();
        let (rows, began, clock) = &mut *guard;
        let seconds = began.elapsed().as_secs_f64();
        let time_left = clock.end(Instant::now());
        rows.push(StageRow { stage, seconds, peak_rss_bytes: crate::memory::peak_rss_bytes(), time_left });
        *began = Instant::now();
    }

    fn rows(self) -> Vec<StageRow> {
        self.0.into_inner().unwrap_or_else(PoisonError::into_inner).0
    }
}

/// Shows `p` on `pb`, restarting the bar (and its time left) at each new
/// stage, which ends the one before in `stages`. Each stage frees most of
/// what the one before allocated: handing it back to the system keeps the
/// peak at the largest stage, not the sum of what the allocator kept (ship
/// 10^6 staged: 673 MB to 612 MB).
fn show(pb: &ProgressBar, stages: &Stages, p: LoadProgress) {
    if pb.prefix() != p.stage.name() {
        stages.end(stage_name(&pb.prefix()));
        crate::memory::release_freed_memory();
        pb.set_prefix(p.stage.name());
        pb.reset();
    }
    output::show_progress(pb, &mut stages.lock().2, &p);
}

/// The static name of a stage the progress bar shows.
fn stage_name(prefix: &str) -> &'static str {
    use Stage::*;
    [Tree, Layout, Levels, Choose, Geometry, Groups, Nodes, Keys]
        .into_iter()
        .map(Stage::name)
        .chain(["read", "commit"])
        .find(|name| *name == prefix)
        .unwrap_or("build")
}

/// The database `build` writes into, and whether this run created its
/// file: a missing, empty or torn file is created anew, any other file that
/// is not an mktree file refused untouched (`Database::open_or_create`). An
/// existing file keeps its block size and M.
fn open_output(out: &Path, args: &BuildArgs, lod: &LodArgs) -> Result<(Database, bool)> {
    let options = CreateOptions {
        block_size: args.block_size(),
        lod_levels: lod.lods.unwrap_or(mktree::db::DEFAULT_LOD_LEVELS),
    };
    let (db, created) = match Database::open_or_create(out, options) {
        Err(StorageError::NotMktree) => {
            bail!("{} is not an mktree file; not overwriting it (give -o a new .mkt path)", out.display())
        }
        opened => opened.map_err(|e| crate::input::opening(e, out))?,
    };
    if args.block_size.is_some_and(|b| b != db.block_size()) {
        bail!("{} has {}-byte blocks; a new block size needs a new file", out.display(), db.block_size());
    }
    if lod.lods.is_some_and(|m| m != db.lod_levels()) {
        bail!("{} has {} levels of detail; a new M needs a new file", out.display(), db.lod_levels());
    }
    Ok((db, created))
}

/// How `build` writes: wait for another writer, key objects by their
/// names, the memory it may use, whether to stage an OBJ whatever its size.
pub struct Write {
    pub wait: bool,
    pub key_names: bool,
    pub memory: u64,
    pub stage: bool,
}

/// The scene `build` loads: read whole, or staged on disk.
enum Input {
    Whole(Scene),
    Staged(StagedScene),
}

/// Reads the scene at `path`: an OBJ file larger than half of `memory` is
/// staged in a spill file in `spill_dir` (an object's mesh in memory takes
/// about as many bytes as its OBJ text, and the build needs room beside
/// the scene); any other scene is read whole.
fn read_input(path: &Path, args: &BuildArgs, write: &Write, spill_dir: &Path) -> Result<Input> {
    let reading = ProgressBar::new_spinner().with_prefix("read").with_message(path.display().to_string());
    reading.set_style(
        ProgressStyle::with_template("{spinner} {prefix:>8} {msg} ({elapsed})")
            .unwrap_or_else(|_| ProgressStyle::default_spinner()),
    );
    reading.enable_steady_tick(std::time::Duration::from_millis(200));
    let streams = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("obj"));
    let large =
        std::fs::metadata(path).is_ok_and(|m| m.is_file() && (write.stage || m.len() > write.memory / 2));
    let input = if streams && large {
        reading.set_message(format!("{} (staged in {})", path.display(), spill_dir.display()));
        let (mut staged, degenerate) = StagedScene::import(path, &args.import.options(), spill_dir)?;
        crate::input::warn_degenerate(degenerate);
        if write.key_names {
            staged.key_by_names()?;
        }
        Input::Staged(staged)
    } else {
        let mut scene = crate::input::read_scene(path, &args.import.options())?;
        if write.key_names {
            scene.key_by_names()?;
        }
        Input::Whole(scene)
    };
    reading.finish_and_clear();
    crate::memory::release_freed_memory();
    Ok(input)
}

pub fn run(
    scene_path: &Path,
    out: &Path,
    args: &BuildArgs,
    lod: &LodArgs,
    write: Write,
    as_json: bool,
) -> Result<()> {
    let stages = Stages::new();
    let mut input = read_input(scene_path, args, &write, crate::input::folder_of(out))?;
    stages.end("read");
    let started = Instant::now();
    let (db, created) = open_output(out, args, lod)?;
    let pb = output::progress_bar();
    let written = (|| -> Result<Hierarchy> {
        let mut w = db.begin_write_with(if write.wait { WriterWait::Wait } else { WriterWait::Fail })?;
        w.set_lod_params(lod.params());
        let tree = match &mut input {
            Input::Whole(scene) => w.bulk_load(scene, &args.params(), &|p| show(&pb, &stages, p))?,
            Input::Staged(staged) => {
                w.bulk_load_staged(staged, &args.params(), &|p| show(&pb, &stages, p))?
            }
        };
        stages.end(stage_name(&pb.prefix()));
        pb.set_prefix("commit");
        pb.set_length(1);
        pb.reset();
        w.commit()?;
        stages.end("commit");
        Ok(tree)
    })();
    pb.finish_and_clear();
    let tree = match written {
        Ok(tree) => tree,
        Err(e) if created => {
            // A refused scene leaves no file behind that looks like an output.
            drop(db);
            return Err(match std::fs::remove_file(out) {
                Ok(()) => e,
                Err(removing) => e.context(format!("{} is left without a tree ({removing})", out.display())),
            });
        }
        Err(e) => return Err(e),
    };
    let seconds = started.elapsed().as_secs_f64();
    let info = db.begin_read()?.info().context("the committed file has no tree")?;
    let bytes = u64::from(info.file_blocks) * u64::from(info.block_size);
    let report = Report::of(&tree);
    if as_json {
        return output::json(&json!({
            "file": info,
            "file_bytes": bytes,
            "seconds": seconds,
            "report": report,
            "stages": stages.rows(),
        }));
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
