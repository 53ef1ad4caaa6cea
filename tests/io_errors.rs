//! Claim: an I/O error at any read, write or sync gives a typed error, never
//! a panic, and the file then reopens cleanly at a committed state.

mod common;

use std::sync::Arc;

use common::grid_scene;
use mktree::bulk::{BuildParams, LeafRule};
use mktree::db::{CreateOptions, Database, check};
use mktree::geom::Aabb;
use mktree::store::BlockDevice;
use mktree::store::device::{CountingDevice, FaultDevice, FaultOp, MemDevice};

fn base_image() -> Vec<u8> {
    let params = BuildParams { leaf: LeafRule::Objects(4), ..BuildParams::paper() };
    common::image(&grid_scene(40), &params, CreateOptions { block_size: 1024, lod_levels: 1 })
}

/// Opens, replaces the tree, and queries; any step may fail.
fn session(dev: Arc<dyn BlockDevice>) -> Result<usize, mktree::Error> {
    let db = Database::open_on(dev)?;
    let mut w = db.begin_write()?;
    w.bulk_load(
        &grid_scene(60),
        &BuildParams { leaf: LeafRule::Objects(4), ..BuildParams::paper() },
        &|_| {},
    )?;
    w.commit()?;
    Ok(db.begin_read()?.query_box(&Aabb::from_array([0.0, 0.0, 0.0, 1e4, 1e4, 1e4]))?.objects.len())
}

#[test]
fn every_failed_operation_is_a_typed_error_and_the_file_reopens() {
    let img = base_image();
    // How many operations of each kind a clean session does.
    let counting = Arc::new(CountingDevice::new(MemDevice::from_bytes(img.clone())));
    assert_eq!(session(counting.clone()).unwrap(), 60);
    let c = counting.counts();
    for (op, n) in [(FaultOp::Read, c.reads), (FaultOp::Write, c.writes), (FaultOp::Sync, c.syncs)] {
        for nth in 0..n {
            let mem = Arc::new(MemDevice::from_bytes(img.clone()));
            let faulty = Arc::new(FaultDevice::new(mem.clone(), op, nth));
            match session(faulty) {
                Err(e) => assert!(!e.to_string().is_empty()),
                Ok(n) => assert_eq!(n, 60),
            }
            let db = Database::open_on(mem as Arc<dyn BlockDevice>)
                .unwrap_or_else(|e| panic!("{op:?} {nth}: reopen: {e}"));
            let objects = db.begin_read().unwrap().info().map(|i| i.objects);
            assert!(objects == Some(40) || objects == Some(60), "{op:?} {nth}: {objects:?}");
            assert!(check(&db).unwrap().ok(), "{op:?} {nth}: check failed after reopen");
        }
    }
}
