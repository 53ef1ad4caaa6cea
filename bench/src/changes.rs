//! What a change costs, against SQLite in the same run: a scene loaded into
//! mktree and into SQLite's R*Tree plus a blob table (the same objects, the
//! same page size), then, on each, single-object commits of inserts, moves
//! and removals, and one commit of many mixed changes. Per commit: wall
//! time (median and 95th percentile), bytes the process wrote
//! (`/proc/self/io` `write_bytes`, the same measure for both), and for
//! mktree the blocks and syncs its device saw. Then the usual box queries
//! on the changed mktree file against a fresh bulk load of the same objects.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use mktree::bulk::BuildParams;
use mktree::db::{CreateOptions, Database, WriteTransaction};
use mktree::geom::Vector;
use mktree::scene::{Key, Mesh, Object, Scene};
use mktree::store::BlockDevice;
use mktree::store::device::{CountingDevice, FileDevice};
use rusqlite::Connection;
use serde::Serialize;

use crate::rng::Rng;
use crate::stream::{StreamEngine, StreamJob, StreamRole, StreamRow, stream};
use crate::{BenchError, QuerySet, WorkloadStats, record, run_boxes};

/// How the changes run.
#[derive(Debug, Clone, PartialEq)]
pub struct ChangeOptions {
    /// Single-object commits of each kind (insert, move, remove).
    pub singles: usize,
    /// Changes in the one mixed commit.
    pub batch: usize,
    /// Which objects change, and how.
    pub seed: u64,
    /// mktree's block size (SQLite's page size) and levels of detail.
    pub create: CreateOptions,
    /// The `mktree` binary, to run the two-process stream of `singles`
    /// moves with ([`crate::stream`]); `None`: no stream.
    pub worker: Option<PathBuf>,
}

/// One engine's commits of one kind.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ChangeRow {
    /// `mktree`, `sqlite-wal` or `sqlite-rollback`.
    pub engine: String,
    /// `insert`, `move`, `remove` or `mixed N` (one commit of N changes).
    pub phase: String,
    /// Commits timed.
    pub commits: usize,
    /// Median and 95th percentile of a commit's wall time, ms.
    pub median_ms: f64,
    /// The 95th percentile, ms.
    pub p95_ms: f64,
    /// Mean bytes the process wrote per commit (`/proc/self/io`).
    pub bytes_per_commit: f64,
    /// mktree: mean blocks its device wrote per commit (slot copies
    /// included); SQLite: bytes per commit over the page size.
    pub blocks_per_commit: f64,
    /// mktree: mean syncs per commit; SQLite: not counted (0).
    pub syncs_per_commit: f64,
    /// mktree: share of commits written in place (copy on write).
    pub in_place: f64,
    /// The file's bytes after the phase (SQLite: with its WAL).
    pub file_bytes: u64,
}

/// The whole run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ChangesReport {
    /// Objects of the scene.
    pub objects: usize,
    /// Every engine's phases.
    pub rows: Vec<ChangeRow>,
    /// Per query set: (label, the changed mktree file, a fresh bulk load of its objects).
    pub reads: Vec<(String, WorkloadStats, WorkloadStats)>,
    /// The changed file's blocks against a fresh load's.
    pub file_blocks: (u32, u32),
    /// Per engine, single-object moves committed by one process while
    /// another queries (empty without [`ChangeOptions::worker`]).
    pub streams: Vec<StreamRow>,
}

/// One change of the run, the same for every engine.
#[derive(Debug, Clone)]
enum Op {
    Insert(u64, Object),
    Move(u64, Vector),
    Remove(u64),
}

/// Bytes this process has written to storage so far (Linux); 0 elsewhere.
fn written_bytes() -> u64 {
    let Ok(io) = std::fs::read_to_string("/proc/self/io") else { return 0 };
    io.lines().find_map(|l| l.strip_prefix("write_bytes: ")).and_then(|v| v.trim().parse().ok()).unwrap_or(0)
}

/// The changes: `singles` inserts (copies of random objects, shifted), as
/// many moves and removals of distinct objects, then `batch` mixed.
fn plan(scene: &Scene, opts: &ChangeOptions) -> (Vec<Vec<Op>>, Vec<Op>) {
    let n = scene.len() as u64;
    let mut rng = Rng::new(opts.seed, 0x4348_4e47);
    let mut order: Vec<u64> = (0..n).collect();
    rng.shuffle(&mut order);
    let extent = scene.aabb().extent();
    let shift = |rng: &mut Rng, scale: f64| {
        Vector::new(
            (rng.unit() - 0.5) * extent.x * scale,
            (rng.unit() - 0.5) * extent.y * scale,
            (rng.unit() - 0.5) * extent.z * scale,
        )
    };
    let mut fresh_key = 1u64 << 40;
    let mut insert = |rng: &mut Rng| {
        let i = rng.below(n) as usize;
        let o = &scene.objects()[i];
        let by = shift(rng, 0.01);
        fresh_key += 1;
        Op::Insert(fresh_key, Object { key: None, ..moved(o, by) })
    };
    let mut taken = order.into_iter();
    let inserts = (0..opts.singles).map(|_| insert(&mut rng)).collect();
    let moves = taken.by_ref().take(opts.singles).map(|k| Op::Move(k, shift(&mut rng, 0.01))).collect();
    let removes = taken.by_ref().take(opts.singles).map(Op::Remove).collect();
    let phases = vec![inserts, moves, removes];
    let mut mixed = Vec::with_capacity(opts.batch);
    for j in 0..opts.batch {
        match j % 3 {
            0 => mixed.push(insert(&mut rng)),
            1 => mixed.extend(taken.next().map(|k| Op::Move(k, shift(&mut rng, 0.01)))),
            _ => mixed.extend(taken.next().map(Op::Remove)),
        }
    }
    (phases, mixed)
}

/// `o` translated by `by`.
fn moved(o: &Object, by: Vector) -> Object {
    let points: Vec<_> = o.mesh.vertices().map(|p| p + by).collect();
    let mesh = Mesh::from_world(&points, o.mesh.triangles().to_vec()).unwrap_or_else(|_| o.mesh.clone());
    Object { mesh, ..o.clone() }
}

fn file_len(path: &Path) -> u64 {
    std::fs::metadata(path).map_or(0, |m| m.len())
}

pub(crate) fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return 0.0;
    }
    let i = ((sorted.len() as f64 - 1.0) * p).round() as usize;
    sorted[i.min(sorted.len() - 1)]
}

/// Accumulates one phase's commits.
#[derive(Default)]
struct Phase {
    ms: Vec<f64>,
    bytes: u64,
    blocks: u64,
    syncs: u64,
    in_place: usize,
}

impl Phase {
    fn row(mut self, engine: &str, phase: &str, file_bytes: u64) -> ChangeRow {
        self.ms.sort_by(f64::total_cmp);
        let c = self.ms.len().max(1) as f64;
        ChangeRow {
            engine: engine.into(),
            phase: phase.into(),
            commits: self.ms.len(),
            median_ms: percentile(&self.ms, 0.5),
            p95_ms: percentile(&self.ms, 0.95),
            bytes_per_commit: self.bytes as f64 / c,
            blocks_per_commit: self.blocks as f64 / c,
            syncs_per_commit: self.syncs as f64 / c,
            in_place: self.in_place as f64 / c,
            file_bytes,
        }
    }
}

/// Runs the changes on `scene` in files under `dir` (removed afterwards).
pub fn bench_changes(
    scene: &Scene,
    params: &BuildParams,
    sets: &[QuerySet],
    opts: &ChangeOptions,
    dir: &Path,
) -> Result<ChangesReport, BenchError> {
    if scene.is_empty() {
        return Err(BenchError::Invalid("the scene has no objects".into()));
    }
    let run = Run::new(scene, opts, dir);

    // mktree, on a file through a counting device.
    let path = dir.join("bench-changes.mkt");
    let mut mktree = MktreeFile::load(&run.keyed, params, opts.create, &path)?;
    let mut rows = run.time_phases("mktree", |ops, batch| mktree.phase(ops, batch), || file_len(&path))?;
    let AgainstFresh { reads, file_blocks } = mktree.against_fresh(params, sets, opts.create, dir)?;
    // The stream runs on the changed file, from two other processes.
    let mut streams: Vec<StreamRow> =
        run.stream_on("mktree", StreamEngine::Mktree, &path)?.into_iter().collect();
    let _ = std::fs::remove_file(&path);

    // SQLite, with a write-ahead log and with its rollback journal.
    for (engine, journal) in [("sqlite-wal", "WAL"), ("sqlite-rollback", "DELETE")] {
        let (sqlite_rows, stream) = run.sqlite(engine, journal)?;
        rows.extend(sqlite_rows);
        streams.extend(stream);
    }
    Ok(ChangesReport { objects: scene.len(), rows, reads, file_blocks, streams })
}

/// The single-object phases' names, in [`plan`]'s order.
const PHASES: [&str; 3] = ["insert", "move", "remove"];

/// What every engine's run shares: the scene, its changes and the options.
struct Run<'a> {
    /// The scene, each object keyed by its index.
    keyed: Scene,
    /// The single-object changes of each of [`PHASES`].
    phases: Vec<Vec<Op>>,
    /// The changes of the one mixed commit.
    mixed: Vec<Op>,
    /// How the changes run.
    opts: &'a ChangeOptions,
    /// Where the files are made.
    dir: &'a Path,
}

impl<'a> Run<'a> {
    /// `scene` keyed by index, and the changes [`plan`] makes of it.
    fn new(scene: &Scene, opts: &'a ChangeOptions, dir: &'a Path) -> Run<'a> {
        let keyed = Scene::new(
            scene.objects().iter().enumerate().map(|(i, o)| o.clone().with_key(i as u64)).collect(),
        );
        let (phases, mixed) = plan(&keyed, opts);
        Run { keyed, phases, mixed, opts, dir }
    }

    /// `engine`'s rows: each single-object phase through `phase`, then the
    /// mixed changes as one commit, each with the `file_bytes` after it.
    fn time_phases(
        &self,
        engine: &str,
        mut phase: impl FnMut(&[Op], bool) -> Result<Phase, BenchError>,
        file_bytes: impl Fn() -> u64,
    ) -> Result<Vec<ChangeRow>, BenchError> {
        let mut rows = Vec::new();
        for (ops, name) in self.phases.iter().zip(PHASES) {
            rows.push(phase(ops, false)?.row(engine, name, file_bytes()));
        }
        let mixed = phase(&self.mixed, true)?;
        rows.push(mixed.row(engine, &format!("mixed {}", self.mixed.len()), file_bytes()));
        Ok(rows)
    }

    /// The two-process stream of moves on `file`, as `name`'s row; `None`
    /// without [`ChangeOptions::worker`].
    fn stream_on(
        &self,
        name: &str,
        engine: StreamEngine,
        file: &Path,
    ) -> Result<Option<StreamRow>, BenchError> {
        let Some(exe) = &self.opts.worker else { return Ok(None) };
        let job = StreamJob {
            engine,
            role: StreamRole::Writer,
            file: file.to_path_buf(),
            keys: self.keyed.len() as u64,
            commits: self.opts.singles,
            extent: self.keyed.aabb(),
            seed: self.opts.seed,
            stop: PathBuf::new(),
        };
        stream(exe, name, job).map(Some)
    }

    /// SQLite's rows and stream as `engine`, with `journal` as its journal mode.
    fn sqlite(&self, engine: &str, journal: &str) -> Result<(Vec<ChangeRow>, Option<StreamRow>), BenchError> {
        let path = self.dir.join(format!("bench-changes-{engine}.sqlite"));
        remove_sqlite_files(&path);
        let conn = sqlite_load(&self.keyed, &path, self.opts.create.block_size, journal)?;
        let rows = self.time_phases(
            engine,
            |ops, batch| self.sqlite_phase(&conn, ops, batch),
            || sqlite_len(&path),
        )?;
        drop(conn);
        let stream = self.stream_on(engine, StreamEngine::Sqlite, &path)?;
        remove_sqlite_files(&path);
        Ok((rows, stream))
    }

    /// Times `ops` on `conn`: one commit per change, or with `batch` one for all.
    fn sqlite_phase(&self, conn: &Connection, ops: &[Op], batch: bool) -> Result<Phase, BenchError> {
        let mut phase = Phase::default();
        for chunk in commits(ops, batch) {
            let bytes = written_bytes();
            let started = Instant::now();
            conn.execute_batch("BEGIN")?;
            for op in chunk {
                sqlite_apply(conn, &self.keyed, op)?;
            }
            conn.execute_batch("COMMIT")?;
            phase.ms.push(started.elapsed().as_secs_f64() * 1e3);
            let b = written_bytes() - bytes;
            phase.bytes += b;
            phase.blocks += b / u64::from(self.opts.create.block_size);
        }
        Ok(phase)
    }
}

/// `ops` as commits: one change each, or with `batch` all in one.
fn commits(ops: &[Op], batch: bool) -> std::slice::Chunks<'_, Op> {
    ops.chunks(if batch { ops.len().max(1) } else { 1 })
}

/// The mktree side: a file through a counting device, and the objects it
/// should hold after the changes so far.
struct MktreeFile {
    /// The file's device, whose counts give each commit's blocks and syncs.
    dev: Arc<CountingDevice<FileDevice>>,
    /// The database on `dev`.
    db: Database,
    /// The objects by key, for the fresh load to compare with.
    model: BTreeMap<Key, Object>,
}

impl MktreeFile {
    /// A new file at `path` (replacing any), bulk loaded with `keyed`.
    fn load(
        keyed: &Scene,
        params: &BuildParams,
        create: CreateOptions,
        path: &Path,
    ) -> Result<Self, BenchError> {
        let _ = std::fs::remove_file(path);
        let file = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .create_new(true)
            .open(path)
            .map_err(|source| BenchError::Io { what: path.display().to_string(), source })?;
        let dev = Arc::new(CountingDevice::new(FileDevice::new(file)));
        let db = Database::create_on(dev.clone() as Arc<dyn BlockDevice>, create)?;
        let mut w = db.begin_write()?;
        w.bulk_load(keyed, params, &|_| {})?;
        w.commit()?;
        let model =
            keyed.objects().iter().map(|o| (o.key.clone().unwrap_or(Key::Int(0)), o.clone())).collect();
        Ok(MktreeFile { dev, db, model })
    }

    /// Times `ops`: one commit per change, or with `batch` one for all.
    fn phase(&mut self, ops: &[Op], batch: bool) -> Result<Phase, BenchError> {
        let mut phase = Phase::default();
        for chunk in commits(ops, batch) {
            let (bytes, counts) = (written_bytes(), self.dev.counts());
            let started = Instant::now();
            let mut w = self.db.begin_write()?;
            for op in chunk {
                mktree_apply(&mut w, &mut self.model, op)?;
            }
            let stats = w.commit_with_stats()?;
            phase.ms.push(started.elapsed().as_secs_f64() * 1e3);
            let after = self.dev.counts();
            phase.bytes += written_bytes() - bytes;
            phase.blocks += after.writes - counts.writes;
            phase.syncs += after.syncs - counts.syncs;
            phase.in_place += usize::from(stats.in_place);
        }
        Ok(phase)
    }

    /// The changed file's reads of each set's boxes against a fresh load of
    /// the same objects (in `dir`, removed afterwards), and both files' blocks.
    fn against_fresh(
        self,
        params: &BuildParams,
        sets: &[QuerySet],
        create: CreateOptions,
        dir: &Path,
    ) -> Result<AgainstFresh, BenchError> {
        let MktreeFile { db, model, .. } = self;
        let fresh_path = dir.join("bench-changes-fresh.mkt");
        let _ = std::fs::remove_file(&fresh_path);
        let fresh = Database::create(&fresh_path, create)?;
        let now = Scene::new(model.iter().map(|(k, o)| o.clone().with_key(k.clone())).collect());
        let mut w = fresh.begin_write()?;
        w.bulk_load(&now, params, &|_| {})?;
        w.commit()?;
        let (changed, clean) = (db.begin_read()?, fresh.begin_read()?);
        let mut reads = Vec::new();
        for set in sets {
            reads.push((set.label.clone(), run_boxes(&changed, &set.boxes)?, run_boxes(&clean, &set.boxes)?));
        }
        let file_blocks =
            (changed.info().map_or(0, |i| i.file_blocks), clean.info().map_or(0, |i| i.file_blocks));
        drop((changed, clean, fresh, db));
        let _ = std::fs::remove_file(&fresh_path);
        Ok(AgainstFresh { reads, file_blocks })
    }
}

/// The changed mktree file against a fresh load of its objects.
struct AgainstFresh {
    /// [`ChangesReport::reads`].
    reads: Vec<(String, WorkloadStats, WorkloadStats)>,
    /// [`ChangesReport::file_blocks`].
    file_blocks: (u32, u32),
}

/// `op` in the write transaction `w`, and in `model` as well.
fn mktree_apply(
    w: &mut WriteTransaction<'_>,
    model: &mut BTreeMap<Key, Object>,
    op: &Op,
) -> Result<(), BenchError> {
    match op {
        Op::Insert(k, o) => {
            w.insert(o.clone().with_key(*k))?;
            model.insert(Key::Int(*k), o.clone());
        }
        Op::Move(k, by) => {
            w.move_by(&Key::Int(*k), *by)?;
            if let Some(o) = model.get(&Key::Int(*k)).map(|o| moved(o, *by)) {
                model.insert(Key::Int(*k), o);
            }
        }
        Op::Remove(k) => {
            w.remove(&Key::Int(*k))?;
            model.remove(&Key::Int(*k));
        }
    }
    Ok(())
}

/// A SQLite file's bytes with its write-ahead log.
fn sqlite_len(path: &Path) -> u64 {
    ["", "-wal"]
        .iter()
        .filter_map(|s| std::fs::metadata(format!("{}{s}", path.display())).ok())
        .map(|m| m.len())
        .sum()
}

/// Removes a SQLite file and any log, shared memory or journal beside it.
fn remove_sqlite_files(path: &Path) {
    for suffix in ["", "-wal", "-shm", "-journal"] {
        let _ = std::fs::remove_file(format!("{}{suffix}", path.display()));
    }
}

/// A new SQLite file of `scene`: the R*Tree of boxes and the blob table,
/// keyed by the objects' integer keys, `synchronous = FULL`.
fn sqlite_load(scene: &Scene, path: &Path, page_size: u32, journal: &str) -> Result<Connection, BenchError> {
    let mut conn = Connection::open(path)?;
    conn.execute_batch(&format!(
        "PRAGMA page_size = {page_size};
         PRAGMA journal_mode = {journal};
         PRAGMA synchronous = FULL;
         CREATE VIRTUAL TABLE boxes USING rtree(id, min_x, max_x, min_y, max_y, min_z, max_z);
         CREATE TABLE geometry(id INTEGER PRIMARY KEY, data BLOB);"
    ))?;
    let tx = conn.transaction()?;
    for (i, o) in scene.objects().iter().enumerate() {
        sqlite_put(&tx, i as u64, &o.mesh)?;
    }
    tx.commit()?;
    Ok(conn)
}

pub(crate) fn sqlite_put(conn: &Connection, key: u64, mesh: &Mesh) -> Result<(), BenchError> {
    let (lo, hi) = mesh.aabb().to_f32_outward();
    let b = [lo[0], hi[0], lo[1], hi[1], lo[2], hi[2]].map(f64::from);
    let id = key as i64;
    conn.execute(
        "INSERT OR REPLACE INTO boxes VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7)",
        rusqlite::params![id, b[0], b[1], b[2], b[3], b[4], b[5]],
    )?;
    let blob =
        record::encode(key as u32, mesh).map_err(|source| BenchError::Record { rank: key as u32, source })?;
    conn.execute("INSERT OR REPLACE INTO geometry(id, data) VALUES (?1, ?2)", rusqlite::params![id, blob])?;
    Ok(())
}

fn sqlite_apply(conn: &Connection, scene: &Scene, op: &Op) -> Result<(), BenchError> {
    match op {
        Op::Insert(k, o) => sqlite_put(conn, *k, &o.mesh),
        Op::Move(k, by) => {
            // As mktree's move does, the object is read before it is written moved.
            let blob: Vec<u8> = conn.query_row(crate::peers::sqlite::BLOB_SQL, [*k as i64], |r| r.get(0))?;
            record::decode(&blob).map_err(|source| BenchError::Record { rank: *k as u32, source })?;
            let o = scene.objects().get(*k as usize).map(|o| moved(o, *by));
            match o {
                Some(o) => sqlite_put(conn, *k, &o.mesh),
                None => Ok(()),
            }
        }
        Op::Remove(k) => {
            conn.execute("DELETE FROM boxes WHERE id = ?1", [*k as i64])?;
            conn.execute("DELETE FROM geometry WHERE id = ?1", [*k as i64])?;
            Ok(())
        }
    }
}
