//! An equipment register kept in one redb file: the application's own
//! table of records (row id to tag and position) and their spatial index,
//! an MKtree in a table of the same database, committed together. A move
//! updates the record and the index in one transaction; a transaction the
//! application abandons leaves both as they were; a read transaction
//! answers a box query and looks the hits' records up in the same
//! snapshot. The index's block reads are mktree's count; what they cost
//! redb underneath is counted by a storage backend under the database.
//!
//! ```sh
//! cargo run --example redb_app --features redb   # writes register.redb in a temporary directory
//! ```

use std::error::Error;

use mktree::redb::{BackendCounter, CountingBackend, TreeDefinition};
use mktree::scene::generate::{GenOptions, Preset, generate_scene};
use mktree::{Aabb, BuildParams, Key, Mesh, Object, Scene};
use redb::{ReadableDatabase, TableDefinition};

type Result<T> = std::result::Result<T, Box<dyn Error>>;

/// The application's records: row id to "tag at x,y,z".
const RECORDS: TableDefinition<u64, &str> = TableDefinition::new("equipment");
/// Their index, keyed by the same row ids.
const INDEX: TreeDefinition = TreeDefinition::new("equipment-index");

fn record(o: &Object) -> String {
    let b = o.mesh.aabb().to_array();
    format!("{} at {:.0},{:.0},{:.0}", o.name, b[0], b[1], b[2])
}

/// The database at `path`, over a backend that counts redb's reads; with
/// `cache: false` redb keeps no page cache, so a query's pages are all read.
fn open(path: &std::path::Path, cache: bool) -> Result<(redb::Database, BackendCounter)> {
    let file = std::fs::OpenOptions::new().read(true).write(true).create(true).truncate(false).open(path)?;
    let backend = CountingBackend::new(redb::backends::FileBackend::new(file)?);
    let counter = backend.counter();
    Ok((
        redb::Builder::new().set_cache_size(if cache { 1 << 30 } else { 0 }).create_with_backend(backend)?,
        counter,
    ))
}

fn main() -> Result<()> {
    let dir = tempfile::tempdir()?;
    let path = dir.path().join("register.redb");
    let (db, _) = open(&path, true)?;

    // 1. The register and its index, in one transaction.
    let scene = generate_scene(&GenOptions { preset: Preset::Ship, objects: Some(3000), seed: 7 })?;
    let scene = Scene::new(
        scene.objects().iter().enumerate().map(|(row, o)| o.clone().with_key(row as u64)).collect(),
    );
    let txn = db.begin_write()?;
    {
        let mut records = txn.open_table(RECORDS)?;
        for (row, o) in scene.objects().iter().enumerate() {
            records.insert(row as u64, record(o).as_str())?;
        }
    }
    INDEX.write(&txn, |w| w.bulk_load(&scene, &BuildParams::default(), &|_| {}).map(|_| ()))?;
    txn.commit()?;
    println!("{} records and their index committed together", scene.len());

    // 2. Row 42 moves 2 m along x: its record and its index entry, one commit.
    let moved = {
        let o = &scene.objects()[42];
        let b = o.mesh.aabb().to_array();
        let to = Aabb::from_array([b[0] + 2000.0, b[1], b[2], b[3] + 2000.0, b[4], b[5]]);
        Object::new(o.name.clone(), Mesh::of_box(&to).ok_or("a box of no extent")?).with_key(42u64)
    };
    let txn = db.begin_write()?;
    txn.open_table(RECORDS)?.insert(42, record(&moved).as_str())?;
    INDEX.write(&txn, |w| w.update(moved.clone()).map(|_| ()))?;
    txn.commit()?;

    // 3. An application check fails halfway: the transaction is abandoned,
    //    and neither the new record nor its index entry is kept.
    let txn = db.begin_write()?;
    txn.open_table(RECORDS)?.insert(9999, "valve V-9 at 0,0,0")?;
    let valve = Object::new(
        "valve V-9",
        Mesh::of_box(&Aabb::from_array([0.0, 0.0, 0.0, 300.0, 300.0, 300.0])).ok_or("no box")?,
    )
    .with_key(9999u64);
    INDEX.write(&txn, |w| w.insert(valve).map(|_| ()))?;
    txn.abort()?;

    // 4. Reopened without redb's page cache: one snapshot, a box query on
    //    the index, the hits' records from the table.
    drop(db);
    let (db, counter) = open(&path, false)?;
    let snapshot = db.begin_read()?;
    let index = INDEX.read(&snapshot)?;
    let records = snapshot.open_table(RECORDS)?;
    let before = counter.get();
    let hits = index.query_box(&moved.mesh.aabb().grown(1500.0))?;
    let under = counter.get();
    let mut found_moved = false;
    for key in &hits.keys {
        let Key::Int(row) = key else { return Err("the index holds row ids only".into()) };
        let rec = records.get(*row)?.ok_or("an index entry without its record")?;
        found_moved |= *row == 42;
        if *row == 42 {
            println!("  row {row}: {}", rec.value());
        }
    }
    println!(
        "{} hits around it: {} mktree block reads ({} node, {} geometry), redb read {} times, {} bytes underneath",
        hits.objects.len(),
        hits.stats.reads.total(),
        hits.stats.reads.node,
        hits.stats.reads.geometry,
        under.reads - before.reads,
        under.bytes_read - before.bytes_read,
    );
    if !found_moved || records.get(9999)?.is_some() || index.get(&Key::Int(9999))?.is_some() {
        return Err("row 42 is not where its record says, or the abandoned valve was kept".into());
    }
    drop((records, index, snapshot, db));
    println!("register.redb: {} bytes, records and index in one file", std::fs::metadata(&path)?.len());
    Ok(())
}
