//! The two-process stream of `bench-changes`: one process commits
//! single-object moves while another queries the same file, for mktree and
//! for SQLite (the R*Tree plus blobs, `synchronous = FULL`, a 5 s busy
//! timeout as an application would set). Each side is a worker process
//! ([`worker`], run by the CLI's hidden `bench-changes-worker`), so they
//! share nothing but the file: the writer reports each commit's wall time,
//! the reader how many queries it ran and how many failed.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use mktree::Aabb;
use mktree::db::{Database, WriterWait};
use mktree::geom::{Point, Vector};
use mktree::scene::{Key, Mesh};
use rusqlite::{Connection, OpenFlags};
use serde::{Deserialize, Serialize};

use crate::peers::sqlite::{BLOB_SQL, FILTER_SQL};
use crate::rng::Rng;
use crate::{BenchError, record};

/// The engine a worker drives.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StreamEngine {
    /// An .mkt file.
    Mktree,
    /// SQLite's R*Tree plus blobs, as `bench-changes` loads it.
    Sqlite,
}

/// What a worker does.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StreamRole {
    /// Commits `commits` single-object moves, one per transaction.
    Writer,
    /// Runs box queries of 1% of the extent until the stop file appears.
    Reader,
}

/// One worker's job.
#[derive(Debug, Clone, PartialEq)]
pub struct StreamJob {
    /// The engine.
    pub engine: StreamEngine,
    /// Writer or reader.
    pub role: StreamRole,
    /// The file both workers open.
    pub file: PathBuf,
    /// Objects' integer keys lie below this (a key with no object is skipped).
    pub keys: u64,
    /// The writer's commits.
    pub commits: usize,
    /// The scene's box, for the moves' size and the reader's boxes.
    pub extent: Aabb,
    /// The seed of the keys, moves and boxes.
    pub seed: u64,
    /// The reader stops once this file exists.
    pub stop: PathBuf,
}

/// What a worker measured.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct WorkerReport {
    /// The writer's wall time per commit, ms.
    pub commits_ms: Vec<f64>,
    /// The reader's queries.
    pub queries: u64,
    /// The reader's queries that failed.
    pub failed: u64,
    /// The first failure's message.
    pub first_error: Option<String>,
}

/// The stream's figures for one engine.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StreamRow {
    /// `mktree`, `sqlite-wal` or `sqlite-rollback`.
    pub engine: String,
    /// The writer's commits.
    pub commits: usize,
    /// Median wall time per commit, ms.
    pub median_ms: f64,
    /// 95th percentile, ms.
    pub p95_ms: f64,
    /// Queries the reader ran meanwhile.
    pub reader_queries: u64,
    /// Of them, those that failed.
    pub reader_failed: u64,
    /// The first failure's message.
    pub first_error: Option<String>,
}

/// Runs the reader and then the writer of `engine` on `file` as two
/// processes of `exe` (the `mktree` binary), and gathers their reports.
pub fn stream(exe: &Path, name: &str, mut job: StreamJob) -> Result<StreamRow, BenchError> {
    job.stop = job.file.with_extension("stop");
    let _ = std::fs::remove_file(&job.stop);
    let spawn = |role: StreamRole| -> Result<std::process::Child, BenchError> {
        let StreamJob { engine, file, keys, commits, extent, seed, stop, .. } = &job;
        let b = extent.to_array();
        Command::new(exe)
            .arg("bench-changes-worker")
            .args(["--engine", if *engine == StreamEngine::Mktree { "mktree" } else { "sqlite" }])
            .args(["--role", if role == StreamRole::Writer { "writer" } else { "reader" }])
            .arg("--file")
            .arg(file)
            .args([
                "--keys",
                &keys.to_string(),
                "--commits",
                &commits.to_string(),
                "--seed",
                &seed.to_string(),
            ])
            .arg("--extent")
            .arg(b.map(|x| x.to_string()).join(","))
            .arg("--stop")
            .arg(stop)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .map_err(|source| BenchError::Io { what: format!("running {}", exe.display()), source })
    };
    let ready = ready_file(&job.stop);
    let _ = std::fs::remove_file(&ready);
    let mut reader = spawn(StreamRole::Reader)?;
    // The writer starts once the reader has the file open and queries.
    let waiting = Instant::now();
    while !ready.exists() {
        if reader.try_wait().ok().flatten().is_some() || waiting.elapsed() > Duration::from_secs(60) {
            break;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    let writer = spawn(StreamRole::Writer)?;
    let report = |child: std::process::Child, role: &str| -> Result<WorkerReport, BenchError> {
        let out = child
            .wait_with_output()
            .map_err(|source| BenchError::Io { what: format!("the {role} process"), source })?;
        if !out.status.success() {
            return Err(BenchError::Invalid(format!(
                "the {role} process failed: {}",
                String::from_utf8_lossy(&out.stderr).trim()
            )));
        }
        serde_json::from_slice(&out.stdout)
            .map_err(|e| BenchError::Invalid(format!("the {role} process's report: {e}")))
    };
    let written = report(writer, "writer");
    // The reader stops even when the writer failed.
    std::fs::write(&job.stop, b"")
        .map_err(|source| BenchError::Io { what: job.stop.display().to_string(), source })?;
    let read = report(reader, "reader");
    let _ = std::fs::remove_file(&job.stop);
    let _ = std::fs::remove_file(&ready);
    let (written, read) = (written?, read?);
    let mut ms = written.commits_ms.clone();
    ms.sort_by(f64::total_cmp);
    Ok(StreamRow {
        engine: name.to_string(),
        commits: ms.len(),
        median_ms: crate::changes::percentile(&ms, 0.5),
        p95_ms: crate::changes::percentile(&ms, 0.95),
        reader_queries: read.queries,
        reader_failed: read.failed,
        first_error: read.first_error,
    })
}

/// Runs one worker's job (in its own process).
pub fn worker(job: &StreamJob) -> Result<WorkerReport, BenchError> {
    if job.keys == 0 {
        return Err(BenchError::Invalid("a stream needs objects (--keys 0)".into()));
    }
    let mut rng = Rng::new(job.seed, if job.role == StreamRole::Writer { 0x5752 } else { 0x5244 });
    match (job.engine, job.role) {
        (StreamEngine::Mktree, StreamRole::Writer) => {
            let db = Database::open(&job.file)?;
            write_moves(job, &mut rng, |key, by| {
                let mut w = db.begin_write_with(WriterWait::Wait)?;
                if !w.move_by(&Key::Int(key), by)? {
                    return Ok(false);
                }
                w.commit()?;
                Ok(true)
            })
        }
        (StreamEngine::Mktree, StreamRole::Reader) => {
            let db = Database::open_read_only(&job.file)?;
            read_boxes(job, &mut rng, |b| {
                let r = db.begin_read()?;
                Ok(r.query_box(b)?.objects.len())
            })
        }
        (StreamEngine::Sqlite, StreamRole::Writer) => {
            let conn = Connection::open(&job.file)?;
            conn.execute_batch("PRAGMA busy_timeout = 5000; PRAGMA synchronous = FULL;")?;
            write_moves(job, &mut rng, |key, by| sqlite_move(&conn, key, by))
        }
        (StreamEngine::Sqlite, StreamRole::Reader) => {
            let conn = Connection::open_with_flags(&job.file, OpenFlags::SQLITE_OPEN_READ_ONLY)?;
            conn.execute_batch("PRAGMA busy_timeout = 5000;")?;
            read_boxes(job, &mut rng, |b| sqlite_box(&conn, b))
        }
    }
}

/// The writer's loop: `job.commits` commits of `apply(key, by)`, each
/// timed, skipping keys with no object (`apply` gives false).
fn write_moves(
    job: &StreamJob,
    rng: &mut Rng,
    mut apply: impl FnMut(u64, Vector) -> Result<bool, BenchError>,
) -> Result<WorkerReport, BenchError> {
    let e = job.extent.extent();
    let mut report = WorkerReport::default();
    let mut misses = 0usize;
    while report.commits_ms.len() < job.commits {
        let key = rng.below(job.keys);
        let by = Vector::new((rng.unit() - 0.5) * e.x * 0.01, (rng.unit() - 0.5) * e.y * 0.01, 0.0);
        let started = Instant::now();
        if apply(key, by)? {
            report.commits_ms.push(started.elapsed().as_secs_f64() * 1e3);
        } else {
            misses += 1;
            if misses > 100 * job.commits.max(1) {
                return Err(BenchError::Invalid("the keys name almost no objects".into()));
            }
        }
    }
    Ok(report)
}

/// The reader's loop: boxes of 1% of the extent about random points until
/// the stop file appears, counting failures (a query that errs).
fn read_boxes(
    job: &StreamJob,
    rng: &mut Rng,
    mut query: impl FnMut(&Aabb) -> Result<usize, BenchError>,
) -> Result<WorkerReport, BenchError> {
    let (lo, e) = (job.extent.min, job.extent.extent());
    let mut report = WorkerReport::default();
    let deadline = Instant::now() + Duration::from_secs(3600);
    let ready = ready_file(&job.stop);
    while report.queries == 0 || (!job.stop.exists() && Instant::now() < deadline) {
        let c = Point::new(lo.x + rng.unit() * e.x, lo.y + rng.unit() * e.y, lo.z + rng.unit() * e.z);
        let h = Vector::new(e.x * 0.005, e.y * 0.005, e.z * 0.005);
        report.queries += 1;
        if let Err(err) = query(&Aabb::new(c - h, c + h)) {
            report.failed += 1;
            report.first_error.get_or_insert_with(|| err.to_string());
        }
        if report.queries == 1 {
            std::fs::write(&ready, b"")
                .map_err(|source| BenchError::Io { what: ready.display().to_string(), source })?;
        }
    }
    Ok(report)
}

/// The file a reader makes once it has run its first query.
fn ready_file(stop: &Path) -> PathBuf {
    stop.with_extension("ready")
}

/// Moves row `key` by `by` in one transaction, reading its blob first as
/// mktree's move reads the object; false when there is no such row.
fn sqlite_move(conn: &Connection, key: u64, by: Vector) -> Result<bool, BenchError> {
    conn.execute_batch("BEGIN IMMEDIATE")?;
    let moved = (|| {
        let blob: Option<Vec<u8>> = conn
            .query_row(BLOB_SQL, [key as i64], |r| r.get(0))
            .map(Some)
            .or_else(|e| if e == rusqlite::Error::QueryReturnedNoRows { Ok(None) } else { Err(e) })?;
        let Some(blob) = blob else { return Ok(false) };
        let rec = record::decode(&blob).map_err(|source| BenchError::Record { rank: key as u32, source })?;
        let anchor = rec.anchor() + by;
        let points: Vec<Point> = rec
            .offsets()
            .iter()
            .map(|o| anchor + Vector::new(f64::from(o[0]), f64::from(o[1]), f64::from(o[2])))
            .collect();
        let mesh = Mesh::from_world(&points, rec.triangles().to_vec())
            .map_err(|e| BenchError::Invalid(format!("row {key}'s mesh: {e}")))?;
        crate::changes::sqlite_put(conn, key, &mesh)?;
        Ok(true)
    })();
    match moved {
        Ok(found) => {
            conn.execute_batch(if found { "COMMIT" } else { "ROLLBACK" })?;
            Ok(found)
        }
        Err(e) => {
            let _ = conn.execute_batch("ROLLBACK");
            Err(e)
        }
    }
}

/// An exact-query stand-in: the R*Tree's candidates and their blobs, by
/// the peer benchmark's statements.
fn sqlite_box(conn: &Connection, b: &Aabb) -> Result<usize, BenchError> {
    let mut filter = conn.prepare_cached(FILTER_SQL)?;
    let ids: Vec<i64> = filter
        .query_map(rusqlite::params![b.min.x, b.max.x, b.min.y, b.max.y, b.min.z, b.max.z], |r| r.get(0))?
        .collect::<Result<_, _>>()?;
    let mut blob = conn.prepare_cached(BLOB_SQL)?;
    for &id in &ids {
        let data: Vec<u8> = blob.query_row([id], |r| r.get(0))?;
        record::decode(&data).map_err(|source| BenchError::Record { rank: id as u32, source })?;
    }
    Ok(ids.len())
}
