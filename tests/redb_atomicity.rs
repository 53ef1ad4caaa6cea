//! Claim: the application's own row and the MKtree written in one redb
//! transaction commit both or neither. A crash or I/O failure at any write
//! or sync of redb's commit (with what was written since the last sync lost
//! or kept) reopens with the old row and the old tree, or the new row and
//! the new tree; an aborted transaction keeps the old of both; a failed
//! tree write inside a committed transaction leaves the tree as it was and
//! the table holding exactly the tree's blocks.

mod common;

use std::sync::atomic::{AtomicI64, Ordering};
use std::sync::{Arc, Mutex};

use common::grid_scene;
use mktree::bulk::{BuildParams, LeafRule};
use mktree::db::CreateOptions;
use mktree::redb::TreeDefinition;
use mktree::{Aabb, Error, Key, Scene};
use redb::{ReadableDatabase, ReadableTableMetadata, StorageBackend, TableDefinition};

const ROWS: TableDefinition<u64, &str> = TableDefinition::new("rows");
/// Small blocks, so a commit writes many of them.
const INDEX: TreeDefinition =
    TreeDefinition::new("index").with_options(CreateOptions { block_size: 1024, lod_levels: 2 });
const BLOCKS: TableDefinition<u32, &[u8]> = TableDefinition::new("index");

fn params() -> BuildParams {
    BuildParams { leaf: LeafRule::Objects(4), ..BuildParams::paper() }
}

/// Bytes in memory as a disk holds them: `durable` is what survives a crash
/// that loses everything since the last sync. After `ops_left` writes,
/// resizes and syncs, every one fails (the disk is gone).
#[derive(Debug, Clone, Default)]
struct Disk {
    current: Arc<Mutex<Vec<u8>>>,
    durable: Arc<Mutex<Vec<u8>>>,
    ops_left: Arc<AtomicI64>,
}

impl Disk {
    fn from_image(bytes: Vec<u8>) -> Disk {
        Disk {
            current: Arc::new(Mutex::new(bytes.clone())),
            durable: Arc::new(Mutex::new(bytes)),
            ops_left: Arc::new(AtomicI64::new(i64::MAX)),
        }
    }

    fn tick(&self) -> std::io::Result<()> {
        if self.ops_left.fetch_sub(1, Ordering::SeqCst) <= 0 {
            return Err(std::io::Error::other("the disk failed"));
        }
        Ok(())
    }

    fn current(&self) -> Vec<u8> {
        self.current.lock().unwrap().clone()
    }

    fn durable(&self) -> Vec<u8> {
        self.durable.lock().unwrap().clone()
    }
}

impl StorageBackend for Disk {
    fn len(&self) -> std::io::Result<u64> {
        Ok(self.current.lock().unwrap().len() as u64)
    }
    fn read(&self, offset: u64, out: &mut [u8]) -> std::io::Result<()> {
        let data = self.current.lock().unwrap();
        let src = data
            .get(offset as usize..offset as usize + out.len())
            .ok_or_else(|| std::io::Error::from(std::io::ErrorKind::UnexpectedEof))?;
        out.copy_from_slice(src);
        Ok(())
    }
    fn set_len(&self, len: u64) -> std::io::Result<()> {
        self.tick()?;
        self.current.lock().unwrap().resize(len as usize, 0);
        Ok(())
    }
    fn sync_data(&self) -> std::io::Result<()> {
        self.tick()?;
        *self.durable.lock().unwrap() = self.current();
        Ok(())
    }
    fn write(&self, offset: u64, data: &[u8]) -> std::io::Result<()> {
        self.tick()?;
        let mut d = self.current.lock().unwrap();
        let end = offset as usize + data.len();
        if d.len() < end {
            d.resize(end, 0);
        }
        d[offset as usize..end].copy_from_slice(data);
        Ok(())
    }
}

fn open(disk: &Disk) -> redb::Database {
    redb::Builder::new().create_with_backend(disk.clone()).expect("reopen")
}

/// The application's row `id` and the tree's objects' names, as a reader sees them.
fn seen(db: &redb::Database, id: u64) -> (Option<String>, Option<Vec<String>>) {
    let txn = db.begin_read().unwrap();
    let row = txn.open_table(ROWS).unwrap().get(id).unwrap().map(|v| v.value().to_string());
    let r = INDEX.read(&txn).unwrap();
    let names = r.info().map(|_| r.names().unwrap());
    (row, names)
}

/// Every object of `scene` reads back from the tree (its geometry blocks),
/// and the table holds the tree's blocks and nothing else.
fn assert_sound(db: &redb::Database, scene: &Scene) {
    let txn = db.begin_read().unwrap();
    let r = INDEX.read(&txn).unwrap();
    for (i, o) in scene.objects().iter().enumerate() {
        assert_eq!(r.mesh(&Key::Int(i as u64)).unwrap().as_ref(), Some(&o.mesh), "object {i}");
    }
    let all = r.query_box(&scene.aabb()).unwrap();
    assert_eq!(all.objects.len(), scene.len());
    let info = r.info().unwrap();
    let values = txn.open_table(BLOCKS).unwrap().len().unwrap();
    assert_eq!(
        values,
        u64::from(info.file_blocks - info.free_blocks),
        "the state record and the tree's blocks"
    );
}

fn names(scene: &Scene) -> Vec<String> {
    scene.objects().iter().map(|o| o.name.clone()).collect()
}

/// Row 1 and the tree of `scene`, in one transaction.
fn write_both(db: &redb::Database, row: &str, scene: &Scene) -> Result<(), Error> {
    let redb = |e: redb::Error| Error::from(mktree::StorageError::from(e));
    let txn = db.begin_write().map_err(|e| redb(e.into()))?;
    txn.open_table(ROWS).map_err(|e| redb(e.into()))?.insert(1, row).map_err(|e| redb(e.into()))?;
    INDEX.write(&txn, |w| w.bulk_load(scene, &params(), &|_| {}).map(|_| ()))?;
    txn.commit().map_err(|e| redb(e.into()))?;
    Ok(())
}

#[test]
fn a_crash_at_any_write_or_sync_keeps_both_or_neither() {
    let (old, new) = (grid_scene(40), grid_scene(70));
    let base = Disk::from_image(Vec::new());
    write_both(&open(&base), "old", &old).unwrap();
    let image = base.current();
    let mut step = 0;
    loop {
        let disk = Disk::from_image(image.clone());
        let db = open(&disk);
        disk.ops_left.store(step, Ordering::SeqCst);
        let result = write_both(&db, "new", &new);
        drop(db);
        for (lost, bytes) in
            [("unsynced writes lost", disk.durable()), ("unsynced writes kept", disk.current())]
        {
            let reopened = open(&Disk::from_image(bytes));
            let (row, tree) = seen(&reopened, 1);
            match row.as_deref() {
                Some("old") => {
                    assert_eq!(tree, Some(names(&old)), "step {step}, {lost}: the old row, the old tree")
                }
                Some("new") => {
                    assert_eq!(tree, Some(names(&new)), "step {step}, {lost}: the new row, the new tree")
                }
                other => panic!("step {step}, {lost}: row {other:?}"),
            }
            assert_sound(&reopened, if row.as_deref() == Some("old") { &old } else { &new });
            if result.is_ok() {
                assert_eq!(row.as_deref(), Some("new"), "step {step}: a commit that returned is durable");
            }
        }
        if result.is_ok() {
            println!("{step} writes and syncs in the commit, a crash tried before each");
            assert!(step > 10, "the commit wrote the tree's blocks");
            break;
        }
        step += 1;
    }
}

#[test]
fn an_aborted_transaction_discards_the_row_and_the_tree() {
    let (old, new) = (grid_scene(30), grid_scene(50));
    let db = redb::Builder::new().create_with_backend(redb::backends::InMemoryBackend::new()).unwrap();
    write_both(&db, "old", &old).unwrap();
    let txn = db.begin_write().unwrap();
    txn.open_table(ROWS).unwrap().insert(1, "new").unwrap();
    INDEX.write(&txn, |w| w.bulk_load(&new, &params(), &|_| {}).map(|_| ())).unwrap();
    txn.abort().unwrap();
    assert_eq!(seen(&db, 1), (Some("old".into()), Some(names(&old))));
    assert_sound(&db, &old);
}

#[test]
fn a_failed_tree_write_leaves_the_tree_and_no_stray_block() {
    let (old, new) = (grid_scene(30), grid_scene(50));
    let db = redb::Builder::new().create_with_backend(redb::backends::InMemoryBackend::new()).unwrap();
    write_both(&db, "old", &old).unwrap();
    let txn = db.begin_write().unwrap();
    txn.open_table(ROWS).unwrap().insert(1, "new").unwrap();
    let failed = INDEX.write(&txn, |w| {
        w.bulk_load(&new, &params(), &|_| {})?;
        Err::<(), _>(Error::from(mktree::StorageError::Invalid("the application changed its mind".into())))
    });
    assert!(failed.is_err());
    // A tree write refused before it writes: a key repeated.
    let same = |i: usize| old.objects()[i].clone().with_key(Key::Int(7));
    let twice = Scene::new(vec![same(0), same(1)]);
    assert!(INDEX.write(&txn, |w| w.bulk_load(&twice, &params(), &|_| {}).map(|_| ())).is_err());
    txn.commit().unwrap();
    // The application committed its row; the tree is the old one, and its table holds nothing else.
    assert_eq!(seen(&db, 1), (Some("new".into()), Some(names(&old))));
    assert_sound(&db, &old);
}

#[test]
fn two_writes_in_one_transaction_commit_the_last_tree_and_free_the_first() {
    let scenes = [grid_scene(30), grid_scene(60), grid_scene(20)];
    let db = redb::Builder::new().create_with_backend(redb::backends::InMemoryBackend::new()).unwrap();
    write_both(&db, "0", &scenes[0]).unwrap();
    let before = db.begin_read().unwrap();
    let txn = db.begin_write().unwrap();
    for s in &scenes[1..] {
        INDEX.write(&txn, |w| w.bulk_load(s, &params(), &|_| {}).map(|_| ())).unwrap();
    }
    txn.commit().unwrap();
    assert_sound(&db, &scenes[2]);
    // A reader from before still reads the first tree whole.
    let r = INDEX.read(&before).unwrap();
    assert_eq!(r.names().unwrap(), names(&scenes[0]));
    let hits = r.query_box(&Aabb::from_array([0.0, 0.0, 0.0, 1e4, 1e4, 1e4])).unwrap();
    assert_eq!(hits.objects.len(), scenes[0].len());
}
