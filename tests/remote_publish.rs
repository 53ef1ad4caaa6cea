//! `Database::publish` uploads the file at one commit as one object: after
//! a change commit and a second publish, a reader of the first upload
//! keeps answering as the old file (a versioned bucket), a new reader as
//! the changed file, both block for block; and a publish waits for no
//! half-written state, holding the writer's lock (issue 36 item 3,
//! format-spec/remote.md "Publishing"). Over moto's S3 server.
#![cfg(feature = "object-store")]

mod common;

use common::remote::{assert_same_answers, boxes, build_file};
use common::servers::{http, moto, s3_options};
use mktree::db::Database;
use mktree::scene::Key;
use mktree::scene::generate::Preset;
use mktree::store::device::RemoteOptions;

#[test]
fn a_publish_is_one_commit_and_readers_keep_the_upload_they_opened() {
    let Some(server) = moto() else { return };
    assert_eq!(http(server.port, "PUT", "/models", b""), 200);
    let body = b"<VersioningConfiguration><Status>Enabled</Status></VersioningConfiguration>";
    assert_eq!(http(server.port, "PUT", "/models?versioning", body), 200);
    let options =
        RemoteOptions { store_options: s3_options(server.port), cache_bytes: 0, ..RemoteOptions::default() };
    let url = "s3://models/ships/t2.mkt";

    let path = server.dir.path().join("t2.mkt");
    let scene = build_file(&path, Preset::Tanker2);
    let before = server.dir.path().join("t2-before.mkt");
    std::fs::copy(&path, &before).expect("a copy of the first commit");
    let db = Database::open(&path).expect("open to write");
    let first = db.publish(url, &options).expect("publish");
    assert_eq!(first.bytes, std::fs::metadata(&path).expect("size").len());
    assert!(first.version.is_some(), "a versioned bucket names the version: {first:?}");
    let old_reader = Database::open_url(url, &options).expect("open the first upload");

    let mut w = db.begin_write().expect("write");
    for id in 0..50u64 {
        w.remove(&Key::Int(id)).expect("remove");
    }
    w.commit().expect("commit");
    let second = db.publish(url, &options).expect("publish again");
    assert_ne!(second.version, first.version);

    let queries = boxes(&scene);
    let old_local = Database::open_read_only(&before).expect("the first commit");
    assert_same_answers(&old_local, &old_reader, &queries);
    let new_reader = Database::open_url(url, &options).expect("open the second upload");
    let new_local = Database::open_read_only(&path).expect("the second commit");
    assert_same_answers(&new_local, &new_reader, &queries);
    let removed = new_reader.begin_read().expect("read").query_box(&scene.aabb()).expect("everything");
    assert_eq!(removed.objects.len(), scene.len() - 50);
}

#[test]
fn a_publish_to_a_store_that_cannot_take_it_is_a_clear_error() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("t1.mkt");
    build_file(&path, Preset::Tanker1);
    let db = Database::open(&path).expect("open");
    let e = db.publish("http://127.0.0.1:9/none.mkt", &RemoteOptions::default()).expect_err("no PUT server");
    assert!(e.to_string().contains("http://127.0.0.1:9/none.mkt"), "{e}");
    let e = db.publish("not a url", &RemoteOptions::default()).expect_err("not a URL");
    assert!(e.to_string().contains("not a URL"), "{e}");
}

#[test]
fn a_published_object_is_the_file_byte_for_byte() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("t1.mkt");
    build_file(&path, Preset::Tanker1);
    let db = Database::open(&path).expect("open");
    let target = dir.path().join("published/t1.mkt");
    db.publish(&format!("file://{}", target.display()), &RemoteOptions::default()).expect("publish");
    assert_eq!(std::fs::read(&target).expect("published"), std::fs::read(&path).expect("local"));
}
