//! The redb backend against mktree's own file (the `redb` feature): one
//! scene bulk-loaded into a file with the default 16 KiB blocks, into a
//! file with the redb backend's 16,368-byte blocks, and into a table of a
//! redb database with those blocks; the same box queries on each. The
//! table's mktree block reads must equal the second file's (the same tree,
//! read by the same code): a difference is a bug, never a number.

use std::path::Path;
use std::time::Instant;

use mktree::db::{CreateOptions, DEFAULT_BLOCK_SIZE, DEFAULT_LOD_LEVELS, Database};
use mktree::query::{QueryOptions, Region, query_region};
use mktree::redb::{BackendCounter, CountingBackend, TreeDefinition};
use mktree::{BuildParams, ReadTransaction, Scene};
use redb::ReadableDatabase;

use crate::bench_peers::{QuerySet, standard_sets};
use crate::error::{BenchError, io};

const INDEX: TreeDefinition = TreeDefinition::new("index");

/// One query set of one scene, means per query.
#[derive(Debug, Clone, serde::Serialize)]
pub struct RedbRow {
    /// The scene's name.
    pub scene: String,
    /// Objects in it.
    pub objects: usize,
    /// The query set's label.
    pub set: String,
    /// Queries in the set.
    pub queries: usize,
    /// mktree block reads in its own file of 16 KiB blocks.
    pub file_reads: f64,
    /// mktree block reads in the table (16,368-byte blocks); the same in a
    /// file of those blocks.
    pub table_reads: f64,
    /// Pages redb read from its file for those, with no page cache.
    pub redb_page_reads: f64,
    /// Their bytes.
    pub redb_bytes_read: f64,
    /// Exact answer time, own file of 16 KiB blocks (every block read from
    /// the OS's cache), ms.
    pub file_ms: f64,
    /// The same in a file of 16,368-byte blocks, ms.
    pub file_16368_ms: f64,
    /// The table, redb's page cache warm, ms.
    pub table_warm_ms: f64,
    /// The table, no redb page cache (pages from the OS's cache), ms.
    pub table_uncached_ms: f64,
    /// Bytes of the file of 16 KiB blocks.
    pub file_bytes: u64,
    /// Bytes of the file of 16,368-byte blocks.
    pub file_16368_bytes: u64,
    /// Bytes of the redb database holding the tree alone.
    pub redb_file_bytes: u64,
    /// The same after redb's `compact`.
    pub redb_compacted_bytes: u64,
}

/// Sums over one set: (block reads, redb reads, redb bytes, seconds).
#[derive(Default)]
struct Run {
    reads: u64,
    redb_reads: u64,
    redb_bytes: u64,
    seconds: f64,
}

/// Runs `set` on `r` twice (the first warms the caches) and sums the second
/// run; `counter` counts redb's reads, if given.
fn run(r: &ReadTransaction, set: &QuerySet, counter: Option<&BackendCounter>) -> Result<Run, BenchError> {
    let once = |out: &mut Run| -> Result<(), BenchError> {
        let before = counter.map(BackendCounter::get);
        let started = Instant::now();
        for b in &set.boxes {
            let a = query_region(r, &Region::Box(*b), &QueryOptions::default(), None)?;
            out.reads += a.stats.reads.total();
        }
        out.seconds += started.elapsed().as_secs_f64();
        if let (Some(c), Some(before)) = (counter, before) {
            let after = c.get();
            out.redb_reads += after.reads - before.reads;
            out.redb_bytes += after.bytes_read - before.bytes_read;
        }
        Ok(())
    };
    once(&mut Run::default())?;
    let mut out = Run::default();
    once(&mut out)?;
    Ok(out)
}

fn file(scene: &Scene, path: &Path, block_size: u32) -> Result<Database, BenchError> {
    let db = Database::create(path, CreateOptions { block_size, lod_levels: DEFAULT_LOD_LEVELS })?;
    let mut w = db.begin_write()?;
    w.bulk_load(scene, &BuildParams::for_blocks(block_size), &|_| {})?;
    w.commit()?;
    Ok(db)
}

/// The redb database at `path`, with `cache_bytes` of page cache, over a
/// counting backend.
fn open_redb(path: &Path, cache_bytes: usize) -> Result<(redb::Database, BackendCounter), BenchError> {
    let f = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .create(true)
        .truncate(false)
        .open(path)
        .map_err(io(format!("opening {}", path.display())))?;
    let redb = |e: redb::Error| BenchError::Mktree(mktree::StorageError::from(e).into());
    let backend = CountingBackend::new(redb::backends::FileBackend::new(f).map_err(|e| redb(e.into()))?);
    let counter = backend.counter();
    let db = redb::Builder::new()
        .set_cache_size(cache_bytes)
        .create_with_backend(backend)
        .map_err(|e| redb(e.into()))?;
    Ok((db, counter))
}

fn bytes(path: &Path) -> Result<u64, BenchError> {
    Ok(std::fs::metadata(path).map_err(io(format!("reading {}", path.display())))?.len())
}

/// Measures `scene` (named `name`) with `queries` queries per standard set
/// from `seed`, its files in `dir`.
pub fn bench_redb(
    name: &str,
    scene: &Scene,
    queries: usize,
    seed: u64,
    dir: &Path,
    progress: &dyn Fn(&str),
) -> Result<Vec<RedbRow>, BenchError> {
    let redb = |e: redb::Error| BenchError::Mktree(mktree::StorageError::from(e).into());
    let bs = mktree::redb::DEFAULT_BLOCK_SIZE;
    let sets = standard_sets(&scene.object_boxes(), queries, seed);
    let paths = [dir.join("bench-redb.mkt"), dir.join("bench-redb-16368.mkt"), dir.join("bench-redb.redb")];
    for p in &paths {
        if p.exists() {
            std::fs::remove_file(p).map_err(io(format!("removing {}", p.display())))?;
        }
    }
    progress(&format!("{name}: the files"));
    let own = file(scene, &paths[0], DEFAULT_BLOCK_SIZE)?;
    let same = file(scene, &paths[1], bs)?;
    progress(&format!("{name}: the redb table"));
    {
        let (db, _) = open_redb(&paths[2], 1 << 30)?;
        let txn = db.begin_write().map_err(|e| redb(e.into()))?;
        INDEX.write(&txn, |w| w.bulk_load(scene, &BuildParams::for_blocks(bs), &|_| {}).map(|_| ()))?;
        txn.commit().map_err(|e| redb(e.into()))?;
    }
    let redb_file_bytes = bytes(&paths[2])?;
    let (own_r, same_r) = (own.begin_read()?, same.begin_read()?);
    let mut rows = Vec::new();
    for set in &sets {
        progress(&format!("{name}: {}", set.label));
        let f = run(&own_r, set, None)?;
        let s = run(&same_r, set, None)?;
        let (db, counter) = open_redb(&paths[2], 0)?;
        let txn = db.begin_read().map_err(|e| redb(e.into()))?;
        let uncached = run(&INDEX.read(&txn)?, set, Some(&counter))?;
        drop((txn, db));
        let (db, _) = open_redb(&paths[2], 1 << 30)?;
        let txn = db.begin_read().map_err(|e| redb(e.into()))?;
        let warm = run(&INDEX.read(&txn)?, set, None)?;
        drop((txn, db));
        if uncached.reads != s.reads || warm.reads != s.reads {
            return Err(BenchError::Mismatch(format!(
                "{name} {}: the table read {} blocks, the file of its block size {}",
                set.label, uncached.reads, s.reads
            )));
        }
        let n = set.boxes.len().max(1) as f64;
        rows.push(RedbRow {
            scene: name.to_string(),
            objects: scene.len(),
            set: set.label.clone(),
            queries: set.boxes.len(),
            file_reads: f.reads as f64 / n,
            table_reads: s.reads as f64 / n,
            redb_page_reads: uncached.redb_reads as f64 / n,
            redb_bytes_read: uncached.redb_bytes as f64 / n,
            file_ms: f.seconds / n * 1e3,
            file_16368_ms: s.seconds / n * 1e3,
            table_warm_ms: warm.seconds / n * 1e3,
            table_uncached_ms: uncached.seconds / n * 1e3,
            file_bytes: bytes(&paths[0])?,
            file_16368_bytes: bytes(&paths[1])?,
            redb_file_bytes,
            redb_compacted_bytes: 0,
        });
    }
    let (mut db, _) = open_redb(&paths[2], 1 << 30)?;
    while db.compact().map_err(|e| redb(e.into()))? {}
    drop(db);
    let compacted = bytes(&paths[2])?;
    for r in &mut rows {
        r.redb_compacted_bytes = compacted;
    }
    drop((own_r, same_r, own, same));
    for p in &paths {
        std::fs::remove_file(p).map_err(io(format!("removing {}", p.display())))?;
    }
    Ok(rows)
}

/// `rows` as a Markdown table.
pub fn redb_table(rows: &[RedbRow]) -> String {
    let mut out = String::from(
        "| scene | set | block reads: file / table | redb pages (KiB) per query, no cache | ms file / file 16368 / table warm / table uncached | MB file / file 16368 / redb / redb compacted |\n|---|---|---|---|---|---|\n",
    );
    let mb = |b: u64| b as f64 / 1e6;
    for r in rows {
        out.push_str(&format!(
            "| {} | {} | {:.2} / {:.2} | {:.2} ({:.0}) | {:.3} / {:.3} / {:.3} / {:.3} | {:.1} / {:.1} / {:.1} / {:.1} |\n",
            r.scene,
            r.set,
            r.file_reads,
            r.table_reads,
            r.redb_page_reads,
            r.redb_bytes_read / 1024.0,
            r.file_ms,
            r.file_16368_ms,
            r.table_warm_ms,
            r.table_uncached_ms,
            mb(r.file_bytes),
            mb(r.file_16368_bytes),
            mb(r.redb_file_bytes),
            mb(r.redb_compacted_bytes),
        ));
    }
    out
}
