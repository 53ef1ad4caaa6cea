//! Claim: a file is owned by one opener at a time (an exclusive lock), so a
//! second process cannot write under a running one; the lock goes with the
//! database.

mod common;

use mktree::build::BuildParams;
use mktree::db::{CreateOptions, Database};
use mktree::store::StorageError;

#[test]
fn a_second_open_is_refused_until_the_first_is_dropped() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("t.mkt");
    let db = Database::create(&path, CreateOptions::default()).unwrap();
    let mut w = db.begin_write().unwrap();
    w.bulk_load(&common::grid_scene(30), &BuildParams::default(), &|_| {}).unwrap();
    w.commit().unwrap();
    assert!(matches!(Database::open(&path), Err(StorageError::Locked)));
    drop(db);
    let again = Database::open(&path).unwrap();
    assert_eq!(again.begin_read().unwrap().info().unwrap().objects, 30);
    assert!(Database::create(&path, CreateOptions::default()).is_err(), "create never overwrites a file");
}
