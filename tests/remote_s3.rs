//! A committed file in an S3 bucket (moto's S3 server on 127.0.0.1, the S3
//! protocol over HTTP) answers as the local file does, block for block. A
//! reader stays on the object it opened: in a versioned bucket it goes on
//! answering from its version after the object is replaced; in a bucket
//! without versions it fails with `ObjectChanged` (issue 36,
//! format-spec/remote.md).
#![cfg(feature = "object-store")]

mod common;

use common::remote::{assert_same_answers, boxes, build_file};
use common::servers::{Server, http, moto, s3_options, s3_put};
use mktree::db::Database;
use mktree::scene::generate::Preset;
use mktree::store::StorageError;
use mktree::store::device::RemoteOptions;

fn options(server: &Server, cache_bytes: u64) -> RemoteOptions {
    RemoteOptions { cache_bytes, store_options: s3_options(server.port), ..RemoteOptions::default() }
}

/// Creates `bucket`, with versions kept when `versioned`.
fn bucket(server: &Server, bucket: &str, versioned: bool) {
    assert_eq!(http(server.port, "PUT", &format!("/{bucket}"), b""), 200);
    if versioned {
        let body = b"<VersioningConfiguration><Status>Enabled</Status></VersioningConfiguration>";
        assert_eq!(http(server.port, "PUT", &format!("/{bucket}?versioning"), body), 200);
    }
}

fn upload(server: &Server, bucket: &str, key: &str, bytes: &[u8]) {
    s3_put(server.port, bucket, key, bytes);
}

#[test]
fn a_file_in_a_bucket_answers_as_the_local_file() {
    let Some(server) = moto() else { return };
    let path = server.dir.path().join("t2.mkt");
    let scene = build_file(&path, Preset::Tanker2);
    bucket(&server, "models", false);
    upload(&server, "models", "ships/t2.mkt", &std::fs::read(&path).expect("file"));
    let remote = Database::open_url("s3://models/ships/t2.mkt", &options(&server, 64 << 20)).expect("open");
    let opened = remote.transfer_counts().expect("counts");
    assert!(opened.requests <= 3, "{opened:?}");
    assert_same_answers(&Database::open_read_only(&path).expect("local"), &remote, &boxes(&scene));
    let fetched = remote.transfer_counts().expect("counts");
    assert!(fetched.bytes <= std::fs::metadata(&path).expect("size").len(), "{fetched:?}");
}

#[test]
fn a_reader_keeps_its_version_or_fails_with_object_changed() {
    let Some(server) = moto() else { return };
    let (old, new) = (server.dir.path().join("t2.mkt"), server.dir.path().join("t1.mkt"));
    let scene = build_file(&old, Preset::Tanker2);
    build_file(&new, Preset::Tanker1);
    let (old_bytes, new_bytes) = (std::fs::read(&old).expect("old"), std::fs::read(&new).expect("new"));
    let local = Database::open_read_only(&old).expect("local");

    bucket(&server, "kept", true);
    upload(&server, "kept", "t.mkt", &old_bytes);
    let reader = Database::open_url("s3://kept/t.mkt", &options(&server, 0)).expect("open");
    upload(&server, "kept", "t.mkt", &new_bytes);
    assert_same_answers(&local, &reader, &boxes(&scene));

    bucket(&server, "plain", false);
    upload(&server, "plain", "t.mkt", &old_bytes);
    let reader = Database::open_url("s3://plain/t.mkt", &options(&server, 0)).expect("open");
    upload(&server, "plain", "t.mkt", &new_bytes);
    let r = reader.begin_read().expect("read");
    match r.query_box(&scene.aabb()) {
        Err(mktree::query::QueryError::Storage(StorageError::ObjectChanged { url })) => {
            assert_eq!(url, "s3://plain/t.mkt")
        }
        other => panic!("expected ObjectChanged, got {other:?}"),
    }
}
