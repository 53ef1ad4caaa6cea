//! The SQLite peer: what an embedder would otherwise pick, SQLite's R*Tree
//! of object boxes plus a table of geometry blobs, in pages of mktree's
//! block size, with every page the queries read counted exactly.
//!
//! The file: `boxes`, an R*Tree (`rtree(id, min_x, max_x, ...)`), and
//! `geometry(id INTEGER PRIMARY KEY, data BLOB)`, each blob byte for byte
//! mktree's object record (`record.rs`). Rows go in by the Hilbert order of
//! the box centres and SQLite orders a table by rowid, so the rowid (the
//! R*Tree id) is the object's Hilbert rank and near objects share pages.
//! The bundled SQLite is built with `SQLITE_ENABLE_RTREE` (libsqlite3-sys
//! turns it on for the `bundled` feature).
//!
//! Counting: SQLite's pager counts a cache miss for every page it reads
//! from the file (`SQLITE_DBSTATUS_CACHE_MISS`). One exception: by default
//! SQLite reads a blob's overflow pages straight from the file, around its
//! cache and uncounted. The workspace's `.cargo/config.toml` builds the
//! bundled SQLite with `-DSQLITE_DIRECT_OVERFLOW_READ=0` (through
//! libsqlite3-sys's `LIBSQLITE3_FLAGS`), so every page goes through the
//! pager; [`SqlitePeer::load`] refuses a build that still reads around it.

use std::path::{Path, PathBuf};

use mktree::geom::Aabb;
use mktree::scene::Scene;
use rusqlite::types::ValueRef;
use rusqlite::{Connection, OpenFlags, OptionalExtension, Statement, ffi};

use crate::error::{BenchError, io};
use crate::record;

/// The R*Tree filter: objects whose stored box meets the closed query box.
pub(crate) const FILTER_SQL: &str = "SELECT id FROM boxes \
     WHERE max_x >= ?1 AND min_x <= ?2 AND max_y >= ?3 AND min_y <= ?4 AND max_z >= ?5 AND min_z <= ?6";
/// One object's geometry by rowid.
pub(crate) const BLOB_SQL: &str = "SELECT data FROM geometry WHERE id = ?1";
/// A page cache no query fills, in KiB (SQLite allocates it as pages are
/// read): each page is read at most once per query, as mktree reads each
/// block at most once per query.
const UNBOUNDED_CACHE_KIB: i64 = 64 * 1024 * 1024;

/// A SQLite file holding a scene: its path, page size and rowid map.
#[derive(Debug)]
pub struct SqlitePeer {
    path: PathBuf,
    page_size: u32,
    /// The object id of each rowid (Hilbert rank). This map is the
    /// benchmark's bookkeeping, not index work: an embedder would store its
    /// own ids in the rows; here the ids must match mktree's to compare
    /// answers, and the rank keeps the rows in Hilbert order.
    object_of_rank: Vec<u32>,
}

/// One query's answer and the pages it read.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Counted {
    /// Sorted object ids.
    pub objects: Vec<u32>,
    /// Pages read from the file (cache misses of a fresh connection).
    pub pages: u64,
}

impl SqlitePeer {
    /// Writes `scene` into a new SQLite file at `path` (which must not
    /// exist) with `page_size`-byte pages, then VACUUMs it.
    pub fn load(scene: &Scene, path: &Path, page_size: u32) -> Result<SqlitePeer, BenchError> {
        check_page_size(page_size)?;
        if path.exists() {
            return Err(BenchError::Invalid(format!("{} exists already", path.display())));
        }
        let mut conn = Connection::open(path)?;
        refuse_uncounted_reads(&conn)?;
        // The page size must be set before the first table is made.
        conn.execute_batch(&format!(
            "PRAGMA page_size = {page_size};
             CREATE VIRTUAL TABLE boxes USING rtree(id, min_x, max_x, min_y, max_y, min_z, max_z);
             CREATE TABLE geometry(id INTEGER PRIMARY KEY, data BLOB);"
        ))?;
        let got: u32 = conn.query_row("PRAGMA page_size", [], |r| r.get(0))?;
        if got != page_size {
            return Err(BenchError::Invalid(format!("SQLite kept {got}-byte pages, not {page_size}")));
        }
        let objects = scene.objects();
        let boxes: Vec<Aabb> = objects.iter().map(|o| o.mesh.aabb()).collect();
        let object_of_rank = mktree::bulk::curve_order(&boxes);
        let tx = conn.transaction()?;
        {
            let mut add_box = tx.prepare("INSERT INTO boxes VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7)")?;
            let mut add_blob = tx.prepare("INSERT INTO geometry(id, data) VALUES (?1, ?2)")?;
            for (rank, &id) in (0u32..).zip(&object_of_rank) {
                let mesh = &objects[id as usize].mesh;
                // The R*Tree keeps f32 boxes. Given the box already rounded
                // outward to f32, as mktree stores it, SQLite keeps it as is
                // (its own rounding may widen a value by an ulp or two), so
                // both filters test the very same boxes.
                let (lo, hi) = boxes[id as usize].to_f32_outward();
                let b = [lo[0], hi[0], lo[1], hi[1], lo[2], hi[2]].map(f64::from);
                add_box.execute(rusqlite::params![rank, b[0], b[1], b[2], b[3], b[4], b[5]])?;
                let blob = record::encode(id, mesh).map_err(|source| BenchError::Record { rank, source })?;
                add_blob.execute(rusqlite::params![rank, blob])?;
            }
        }
        tx.commit()?;
        conn.execute_batch("VACUUM")?;
        conn.close().map_err(|(_, e)| e)?;
        Ok(SqlitePeer { path: path.to_path_buf(), page_size, object_of_rank })
    }

    /// Bytes per page.
    pub fn page_size(&self) -> u32 {
        self.page_size
    }

    /// The file's size in bytes.
    pub fn file_bytes(&self) -> Result<u64, BenchError> {
        Ok(std::fs::metadata(&self.path).map_err(io(format!("reading {}", self.path.display())))?.len())
    }

    /// The objects whose R*Tree box meets `query`, on a fresh connection.
    pub fn filter(&self, query: &Aabb) -> Result<Counted, BenchError> {
        let (objects, pages) = counted(&self.path, |conn| {
            let ranks = filter_ranks(&mut conn.prepare(FILTER_SQL)?, query)?;
            Ok(self.objects_of(&ranks))
        })?;
        Ok(Counted { objects, pages })
    }

    /// The objects whose triangles meet `query`, on a fresh connection: the
    /// filter, then each candidate's record by rowid, tested exactly.
    pub fn exact(&self, query: &Aabb) -> Result<Counted, BenchError> {
        let (objects, pages) = counted(&self.path, |conn| self.exact_on(conn, query))?;
        Ok(Counted { objects, pages })
    }

    /// One connection whose cache holds the whole file once it is warm.
    pub fn warm(&self) -> Result<WarmSqlite<'_>, BenchError> {
        let conn = open_read_only(&self.path)?;
        Ok(WarmSqlite { peer: self, conn })
    }

    fn objects_of(&self, ranks: &[u32]) -> Vec<u32> {
        let mut ids: Vec<u32> =
            ranks.iter().filter_map(|&r| self.object_of_rank.get(r as usize).copied()).collect();
        ids.sort_unstable();
        ids
    }

    /// The exact answer on `conn` (cold or warm), in one read transaction,
    /// as an mktree query runs on one snapshot: its statements share one
    /// lock instead of taking and checking one each.
    fn exact_on(&self, conn: &Connection, query: &Aabb) -> Result<Vec<u32>, BenchError> {
        conn.execute_batch("BEGIN")?;
        let answer = self.exact_in_transaction(conn, query);
        conn.execute_batch("COMMIT")?;
        answer
    }

    fn exact_in_transaction(&self, conn: &Connection, query: &Aabb) -> Result<Vec<u32>, BenchError> {
        let (mut filter, mut blob) = (conn.prepare_cached(FILTER_SQL)?, conn.prepare_cached(BLOB_SQL)?);
        let mut ranks = filter_ranks(&mut filter, query)?;
        // In rowid order: the rows of one page are read together.
        ranks.sort_unstable();
        let mut hits = Vec::new();
        for rank in ranks {
            let decoded = blob
                .query_row([rank], |row| {
                    Ok(match row.get_ref(0)? {
                        ValueRef::Blob(b) => Some(record::decode(b)),
                        _ => None,
                    })
                })
                .optional()?;
            let bad = |what: &str| BenchError::Invalid(format!("geometry row {rank} {what}"));
            let rec = decoded
                .ok_or_else(|| bad("is missing"))?
                .ok_or_else(|| bad("holds no blob"))?
                .map_err(|source| BenchError::Record { rank, source })?;
            if self.object_of_rank.get(rank as usize) != Some(&rec.object_id()) {
                return Err(bad(&format!("holds object {}, not the object of its rank", rec.object_id())));
            }
            if rec.meets_box(query) {
                hits.push(rec.object_id());
            }
        }
        hits.sort_unstable();
        Ok(hits)
    }
}

/// A connection whose page cache can hold the whole file: after one pass
/// over a query set, every page those queries read is cached.
pub struct WarmSqlite<'a> {
    peer: &'a SqlitePeer,
    conn: Connection,
}

impl WarmSqlite<'_> {
    /// The exact answer to `query` through the cache, and the pages read
    /// from the file since the previous call (none once warm).
    pub fn exact(&self, query: &Aabb) -> Result<Counted, BenchError> {
        let objects = self.peer.exact_on(&self.conn, query)?;
        Ok(Counted { objects, pages: take_page_reads(&self.conn)? })
    }
}

/// Refuses a page size SQLite does not have (it would keep its own).
pub(crate) fn check_page_size(page_size: u32) -> Result<(), BenchError> {
    if (512..=65536).contains(&page_size) && page_size.is_power_of_two() {
        return Ok(());
    }
    Err(BenchError::Invalid(format!(
        "SQLite pages are powers of two from 512 to 65536 bytes, not {page_size}"
    )))
}

/// The rowids the R*Tree returns for `query`.
fn filter_ranks(filter: &mut Statement<'_>, q: &Aabb) -> Result<Vec<u32>, BenchError> {
    let args = [q.min.x, q.max.x, q.min.y, q.max.y, q.min.z, q.max.z];
    let rows = filter.query_map(args, |r| r.get::<_, u32>(0))?;
    Ok(rows.collect::<Result<_, _>>()?)
}

/// A read-only connection to `path` with a page cache no query fills.
fn open_read_only(path: &Path) -> Result<Connection, BenchError> {
    let conn = Connection::open_with_flags(
        path,
        OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_NO_MUTEX,
    )?;
    // Also loads the schema (page 1): the open cost, before any count.
    conn.execute_batch(&format!("PRAGMA cache_size = -{UNBOUNDED_CACHE_KIB}"))?;
    Ok(conn)
}

/// Runs `query` on a fresh read-only connection (an empty page cache) and
/// counts the pages it reads. Opening and loading the schema (page 1, the
/// counterpart of mktree's header and meta blocks, which its counts also
/// leave out) come before the count. The query prepares its statements
/// inside the count: preparing the R*Tree statement connects the virtual
/// table, which reads the R*Tree's root node, and mktree counts its root
/// block, so SQLite's root counts too.
pub(crate) fn counted<T>(
    path: &Path,
    query: impl FnOnce(&Connection) -> Result<T, BenchError>,
) -> Result<(T, u64), BenchError> {
    let conn = open_read_only(path)?;
    take_page_reads(&conn)?;
    let out = query(&conn)?;
    Ok((out, take_page_reads(&conn)?))
}

/// Pages `conn` read from its file since the last call (its pager's cache
/// misses, `SQLITE_DBSTATUS_CACHE_MISS`), and restarts the count.
#[allow(unsafe_code)]
fn take_page_reads(conn: &Connection) -> Result<u64, BenchError> {
    let (mut current, mut highwater) = (0, 0);
    // SAFETY: `conn.handle()` is the open handle `conn` owns; the borrow of
    // `conn` keeps it open for this call, and `Connection` is not `Sync`, so
    // no other thread uses it meanwhile. `current` and `highwater` are live
    // ints that sqlite3_db_status only writes.
    let rc = unsafe {
        ffi::sqlite3_db_status(
            conn.handle(),
            ffi::SQLITE_DBSTATUS_CACHE_MISS,
            &mut current,
            &mut highwater,
            1,
        )
    };
    if rc != ffi::SQLITE_OK {
        return Err(rusqlite::Error::SqliteFailure(ffi::Error::new(rc), None).into());
    }
    u64::try_from(current).map_err(|_| BenchError::Invalid(format!("SQLite counted {current} page reads")))
}

/// Refuses a SQLite that reads overflow pages around its pager (see the
/// module's note): their reads would go uncounted.
fn refuse_uncounted_reads(conn: &Connection) -> Result<(), BenchError> {
    let mut stmt = conn.prepare("PRAGMA compile_options")?;
    let options = stmt.query_map([], |r| r.get::<_, String>(0))?.collect::<Result<Vec<_>, _>>()?;
    if options.iter().any(|o| o == "DIRECT_OVERFLOW_READ") {
        return Err(BenchError::Invalid(
            "this SQLite reads overflow pages around its page cache, where they are not counted; \
             build it with LIBSQLITE3_FLAGS=-DSQLITE_DIRECT_OVERFLOW_READ=0 (the workspace's .cargo/config.toml does)"
                .into(),
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A table `t(id INTEGER PRIMARY KEY, data BLOB)` of `rows` rows of
    /// `len`-byte blobs, in `page_size`-byte pages.
    fn table(path: &Path, page_size: u32, rows: u32, len: usize) -> Connection {
        let conn = Connection::open(path).unwrap();
        refuse_uncounted_reads(&conn).unwrap();
        conn.execute_batch(&format!(
            "PRAGMA page_size = {page_size}; CREATE TABLE t(id INTEGER PRIMARY KEY, data BLOB); BEGIN;"
        ))
        .unwrap();
        for id in 0..rows {
            conn.execute("INSERT INTO t VALUES (?1, ?2)", rusqlite::params![id, vec![id as u8; len]])
                .unwrap();
        }
        conn.execute_batch("COMMIT").unwrap();
        conn
    }

    /// Pages of table `t` of each type, from SQLite's own `dbstat` table.
    fn pages_of(conn: &Connection, kind: &str) -> u64 {
        let n: i64 = conn
            .query_row("SELECT count(*) FROM dbstat WHERE name = 't' AND pagetype = ?1", [kind], |r| r.get(0))
            .unwrap();
        n as u64
    }

    /// Pages read by lookups of `ids` in one fresh connection, each count
    /// since the previous lookup.
    fn lookups(path: &Path, ids: &[u32]) -> Vec<u64> {
        let conn = open_read_only(path).unwrap();
        let mut stmt = conn.prepare("SELECT data FROM t WHERE id = ?1").unwrap();
        take_page_reads(&conn).unwrap();
        ids.iter()
            .map(|&id| {
                let data: Vec<u8> = stmt.query_row([id], |r| r.get(0)).unwrap();
                assert!(!data.is_empty());
                take_page_reads(&conn).unwrap()
            })
            .collect()
    }

    #[test]
    fn a_rowid_lookup_reads_the_interior_page_and_one_leaf() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.sqlite");
        // 2,000 rows of 100 bytes in 4 KiB pages: a root interior page over
        // ~60 leaves (dbstat confirms the shape).
        let conn = table(&path, 4096, 2000, 100);
        assert_eq!(pages_of(&conn, "internal"), 1);
        assert!(pages_of(&conn, "leaf") > 10);
        assert_eq!(pages_of(&conn, "overflow"), 0);
        drop(conn);
        // Root + leaf; then another leaf (root cached); then the same leaf.
        assert_eq!(lookups(&path, &[1000, 10, 11]), vec![2, 1, 0]);
    }

    #[test]
    fn a_blob_larger_than_a_page_reads_its_overflow_pages_too() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.sqlite");
        // One row of 14,000 bytes in 4 KiB pages: its leaf is the root. By
        // SQLite's rule the leaf keeps ~1,700 bytes, so that the rest fills
        // whole overflow pages of 4,092 bytes: three of them.
        let conn = table(&path, 4096, 1, 14_000);
        let overflow = pages_of(&conn, "overflow");
        assert_eq!(pages_of(&conn, "leaf"), 1);
        assert_eq!(overflow, 3);
        drop(conn);
        assert_eq!(lookups(&path, &[0, 0]), vec![1 + overflow, 0]);
    }

    #[test]
    fn the_peer_answers_as_brute_force_does() {
        use mktree::scene::{Mesh, Object};
        // Boxes on a line, and one slanted triangle whose box meets more than it does.
        let mut objects: Vec<Object> = (0..40)
            .map(|i| {
                let lo = f64::from(i) * 100.0;
                let b = Aabb::from_array([lo, 0.0, 0.0, lo + 60.0, 50.0, 50.0]);
                Object::new(format!("b{i}"), Mesh::of_box(&b).unwrap())
            })
            .collect();
        let tri = [[0.0, 200.0, 0.0], [1000.0, 200.0, 0.0], [0.0, 1200.0, 0.0]].map(Into::into);
        objects.push(Object::new("t", Mesh::from_world(&tri, vec![[0, 1, 2]]).unwrap()));
        let scene = Scene::new(objects);
        let dir = tempfile::tempdir().unwrap();
        let peer = SqlitePeer::load(&scene, &dir.path().join("s.sqlite"), 1024).unwrap();
        assert!(peer.file_bytes().unwrap().is_multiple_of(1024));
        let warm = peer.warm().unwrap();
        for q in [
            Aabb::from_array([150.0, 10.0, 10.0, 420.0, 20.0, 20.0]),
            Aabb::from_array([800.0, 800.0, -1.0, 900.0, 900.0, 1.0]),
            Aabb::from_array([100.0, 300.0, -1.0, 200.0, 400.0, 1.0]),
            Aabb::from_array([1e5, 0.0, 0.0, 1e5 + 1.0, 1.0, 1.0]),
        ] {
            let region = mktree::query::Region::Box(q);
            let exact: Vec<u32> =
                mktree::query::brute_force_region(&scene, &region).iter().map(|o| o.0).collect();
            let by_box: Vec<u32> = (0..scene.len() as u32)
                .filter(|&i| scene.objects()[i as usize].mesh.aabb().intersects(&q))
                .collect();
            let (e, f) = (peer.exact(&q).unwrap(), peer.filter(&q).unwrap());
            assert_eq!((&e.objects, &f.objects), (&exact, &by_box), "{q:?}");
            warm.exact(&q).unwrap();
            assert_eq!(warm.exact(&q).unwrap(), Counted { objects: exact.clone(), pages: 0 });
            assert!(e.pages >= f.pages && f.pages > 0, "{q:?}: {} then {}", f.pages, e.pages);
        }
    }
}
