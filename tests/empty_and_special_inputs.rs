//! Claims (issue 39): a file with no tree, new or emptied by removals,
//! answers every query as a tree of no objects does (no objects, no
//! pairs), never "no tree" from one query and nothing from another; and a
//! FIFO given as a scene is refused with `ImportError::NotAFile` before it
//! is opened, where opening it would wait for a writer for ever.

use mktree::bulk::BuildParams;
use mktree::db::{CreateOptions, Database};
use mktree::geom::{Aabb, Point};
use mktree::query::{ClashOptions, QueryError, clash, object_mesh};
use mktree::scene::{Key, ObjectId};

mod common;

#[test]
fn an_emptied_file_has_no_objects_and_no_pairs_for_every_query() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("t.mkt");
    let db = Database::create(&path, CreateOptions::default()).unwrap();
    let fresh = db.begin_read().unwrap();
    let everything = Aabb::from_array([-1e6, -1e6, -1e6, 1e6, 1e6, 1e6]);
    let opts = ClashOptions { lod: None, clearance: 0.0 };
    assert!(fresh.query_box(&everything).unwrap().objects.is_empty());
    assert!(clash(&fresh, &opts, None).unwrap().pairs.is_empty(), "a new file");
    drop(fresh);

    let mut w = db.begin_write().unwrap();
    w.bulk_load(&common::grid_scene(20), &BuildParams::paper(), &|_| {}).unwrap();
    w.commit().unwrap();
    let mut w = db.begin_write().unwrap();
    for id in 0..20u64 {
        w.remove(&Key::Int(id)).unwrap().unwrap();
    }
    w.commit().unwrap();
    let r = db.begin_read().unwrap();
    assert!(r.query_box(&everything).unwrap().objects.is_empty());
    assert_eq!(r.nearest(Point::origin(), None).unwrap().count(), 0);
    assert!(clash(&r, &opts, None).unwrap().pairs.is_empty(), "an emptied file");
    assert!(matches!(object_mesh(&r, ObjectId(0)), Err(QueryError::NoObject { id: 0, objects: 0 })));
}

#[cfg(unix)]
#[test]
fn a_fifo_as_a_scene_is_refused_before_it_is_opened() {
    use mktree::scene::import::{ImportError, ImportOptions, load};
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("scene.obj");
    assert!(std::process::Command::new("mkfifo").arg(&fifo).status().unwrap().success());
    // Before, this waited for a writer for ever.
    let Err(e) = load(&fifo, &ImportOptions::default()) else { panic!("a FIFO is read as a scene") };
    assert!(matches!(e, ImportError::NotAFile { .. }), "{e}");
    assert!(!mktree::db::is_mktree_file(&fifo));
    assert!(Database::open_read_only(&fifo).is_err());
}
