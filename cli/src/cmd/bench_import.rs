//! `mktree bench-import`: import alone, timed. Each scene file is read
//! `--repeat` times through `mktree::scene::import::load`, so the figures
//! are those of `build`'s first stage (file cache warm after the first run).

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result};
use serde::Serialize;

use crate::args::ImportArgs;
use crate::output;

#[derive(Serialize)]
struct Row {
    file: PathBuf,
    bytes: u64,
    objects: usize,
    triangles: usize,
    /// Rayon's pool size: `RAYON_NUM_THREADS`, else the cores.
    threads: usize,
    /// Wall time of each run.
    seconds: Vec<f64>,
    /// From the fastest run.
    triangles_per_second: f64,
    megabytes_per_second: f64,
}

pub fn run(files: &[PathBuf], repeat: usize, import: &ImportArgs, as_json: bool) -> Result<()> {
    let options = import.options();
    let mut rows = Vec::new();
    for file in files {
        let bytes = std::fs::metadata(file).with_context(|| format!("reading {}", file.display()))?.len();
        let mut seconds = Vec::new();
        let mut counts = (0, 0);
        for _ in 0..repeat.max(1) {
            let started = Instant::now();
            let imported = mktree::scene::import::load(file, &options)?;
            seconds.push(started.elapsed().as_secs_f64());
            counts = (imported.scene.len(), imported.scene.triangle_count());
        }
        let best = seconds.iter().copied().fold(f64::INFINITY, f64::min).max(f64::MIN_POSITIVE);
        rows.push(Row {
            file: file.clone(),
            bytes,
            objects: counts.0,
            triangles: counts.1,
            threads: rayon::current_num_threads(),
            triangles_per_second: counts.1 as f64 / best,
            megabytes_per_second: bytes as f64 / 1e6 / best,
            seconds,
        });
    }
    if as_json {
        return output::json(&rows);
    }
    let table: Vec<Vec<String>> = rows
        .iter()
        .map(|r| {
            let runs: Vec<String> = r.seconds.iter().map(|s| format!("{s:.3}")).collect();
            vec![
                r.file.display().to_string(),
                r.objects.to_string(),
                r.triangles.to_string(),
                r.threads.to_string(),
                runs.join(" "),
                format!("{:.2}", r.triangles_per_second / 1e6),
                format!("{:.0}", r.megabytes_per_second),
            ]
        })
        .collect();
    output::table(&["file", "objects", "triangles", "threads", "seconds", "M tri/s", "MB/s"], &table);
    Ok(())
}
