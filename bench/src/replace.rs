//! What piecewise change does to a tree: scene A bulk-loaded, then replaced
//! by scene B object by object in write transactions (delete a_i, insert
//! b_i), with box-query reads measured at stops against a fresh bulk load
//! of the same objects, then after `optimize`, and the file's size before
//! and after `compact`.

use std::path::Path;
use std::time::Instant;

use mktree::bulk::BuildParams;
use mktree::db::{CreateOptions, Database};
use mktree::scene::{Key, Object, Scene};
use serde::Serialize;

use crate::rng::Rng;
use crate::{BenchError, QuerySet, WorkloadStats, run_boxes};

/// How the replacement runs.
#[derive(Debug, Clone, PartialEq)]
pub struct ReplaceOptions {
    /// Shares of the scene replaced at which reads are measured, ascending.
    pub stops: Vec<f64>,
    /// Objects replaced per write transaction, as a share of the scene.
    pub batch: f64,
    /// The order objects are replaced in.
    pub seed: u64,
    /// The files' block size and levels of detail.
    pub create: CreateOptions,
}

/// Reads at one stop: the changed file against a fresh load of its objects.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ReplaceRow {
    /// Share of the scene replaced.
    pub replaced: f64,
    /// Write transactions so far.
    pub commits: usize,
    /// Mean seconds per commit so far.
    pub mean_commit_seconds: f64,
    /// Commits so far that wrote the tree whole instead of in place.
    pub whole: usize,
    /// The changed file's blocks, and how many of them are free.
    pub file_blocks: u32,
    /// Free blocks of the changed file.
    pub free_blocks: u32,
    /// A fresh bulk load's blocks.
    pub fresh_blocks: u32,
    /// The changed file's layout drift as `stats` reports it: the read
    /// model's node reads on its layout over a fresh packing's, at the
    /// worst scale.
    pub layout_drift: f64,
    /// Per query set: (label, changed file, fresh load).
    pub reads: Vec<(String, WorkloadStats, WorkloadStats)>,
}

/// The whole run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ReplaceReport {
    /// One row per stop, the first at 0 (the bulk load of A itself).
    pub rows: Vec<ReplaceRow>,
    /// After the last stop and `optimize`: per query set, (label, reads),
    /// to set against the last row's fresh load.
    pub optimized: Vec<(String, WorkloadStats)>,
    /// The changed file's blocks before and after `compact` (after `optimize`).
    pub compact: (u32, u32),
}

/// Replaces `a` by `b` in a file under `dir` built with `params`, measuring
/// `sets` at each stop.
pub fn bench_replace(
    a: &Scene,
    b: &Scene,
    params: &BuildParams,
    sets: &[QuerySet],
    opts: &ReplaceOptions,
    dir: &Path,
) -> Result<ReplaceReport, BenchError> {
    let path = dir.join("bench-replace.mkt");
    let _ = std::fs::remove_file(&path);
    let db = Database::create(&path, opts.create)?;
    if a.is_empty() || b.is_empty() {
        return Err(BenchError::Invalid("both scenes need objects".into()));
    }
    let mut w = db.begin_write()?;
    w.bulk_load(&keyed(a, 0), params, &|_| {})?;
    w.commit()?;
    let n = a.len().max(b.len());
    let mut order: Vec<usize> = (0..n).collect();
    Rng::new(opts.seed, 0x5245_504c).shuffle(&mut order);
    let per_commit = ((opts.batch * n as f64).ceil() as usize).max(1);
    let (mut done, mut commits, mut seconds, mut whole) = (0usize, 0usize, 0.0f64, 0usize);
    let mut rows = Vec::new();
    for stop in std::iter::once(0.0).chain(opts.stops.iter().copied()) {
        let until = ((stop * n as f64).round() as usize).min(n);
        while done < until {
            let started = Instant::now();
            let mut w = db.begin_write()?;
            for &i in &order[done..until.min(done + per_commit)] {
                if i < a.len() {
                    w.remove(&Key::Int(i as u64))?;
                }
                if let Some(o) = b.objects().get(i) {
                    w.insert(o.clone().with_key(b_key(i)))?;
                }
            }
            whole += usize::from(!w.commit_with_stats()?.in_place);
            seconds += started.elapsed().as_secs_f64();
            commits += 1;
            done = until.min(done + per_commit);
        }
        let now = current(a, b, &order[..done]);
        let fresh_path = dir.join("bench-replace-fresh.mkt");
        let _ = std::fs::remove_file(&fresh_path);
        let fresh = Database::create(&fresh_path, opts.create)?;
        let mut w = fresh.begin_write()?;
        w.bulk_load(&now, params, &|_| {})?;
        w.commit()?;
        let (changed, clean) = (db.begin_read()?, fresh.begin_read()?);
        let info =
            changed.info().ok_or_else(|| BenchError::Invalid("the changed file holds no tree".into()))?;
        let fresh_blocks = clean.info().map_or(0, |i| i.file_blocks);
        let layout_drift = changed.layout_drift()?.map_or(1.0, |d| d.worst_ratio());
        let mut reads = Vec::new();
        for set in sets {
            reads.push((set.label.clone(), run_boxes(&changed, &set.boxes)?, run_boxes(&clean, &set.boxes)?));
        }
        rows.push(ReplaceRow {
            replaced: stop,
            commits,
            mean_commit_seconds: if commits == 0 { 0.0 } else { seconds / commits as f64 },
            whole,
            file_blocks: info.file_blocks,
            free_blocks: info.free_blocks,
            fresh_blocks,
            layout_drift,
            reads,
        });
        drop((changed, clean, fresh));
        let _ = std::fs::remove_file(&fresh_path);
    }
    let mut w = db.begin_write()?;
    w.optimize()?;
    w.commit()?;
    let optimized = {
        let r = db.begin_read()?;
        let mut reads = Vec::new();
        for set in sets {
            reads.push((set.label.clone(), run_boxes(&r, &set.boxes)?));
        }
        reads
    };
    let c = db.compact()?;
    drop(db);
    let _ = std::fs::remove_file(&path);
    Ok(ReplaceReport { rows, optimized, compact: (c.blocks_before, c.blocks_after) })
}

/// B's object i keeps a key apart from A's.
fn b_key(i: usize) -> Key {
    Key::Int((1 << 40) + i as u64)
}

/// `scene` with object i keyed `first + i`.
fn keyed(scene: &Scene, first: u64) -> Scene {
    Scene::new(
        scene.objects().iter().enumerate().map(|(i, o)| o.clone().with_key(first + i as u64)).collect(),
    )
}

/// A's objects not yet replaced, then B's replacing ones, keyed as in the file.
fn current(a: &Scene, b: &Scene, replaced: &[usize]) -> Scene {
    let mut gone = vec![false; a.len().max(b.len())];
    for &i in replaced {
        gone[i] = true;
    }
    let from_a =
        a.objects().iter().enumerate().filter(|(i, _)| !gone[*i]).map(|(i, o)| o.clone().with_key(i as u64));
    let from_b =
        replaced.iter().filter_map(|&i| b.objects().get(i).map(|o: &Object| o.clone().with_key(b_key(i))));
    Scene::new(from_a.chain(from_b).collect())
}
