//! A committed file served by nginx over plain HTTP range requests answers
//! as the local file does, block for block; the device counts the requests
//! the server logs, and fetches the blocks a query will read ahead, in
//! fewer round trips than reads; and a file replaced under a reader fails
//! with `ObjectChanged`, never with a mixture (issue 36,
//! format-spec/remote.md).
#![cfg(feature = "object-store")]

mod common;

use common::remote::{assert_same_answers, boxes, build_file};
use common::servers::{nginx, replace_file};
use mktree::db::Database;
use mktree::scene::generate::Preset;
use mktree::store::StorageError;
use mktree::store::device::RemoteOptions;

#[test]
fn a_served_file_answers_as_the_local_file_and_counts_what_the_server_logs() {
    let Some(server) = nginx() else { return };
    let path = server.dir.path().join("www/t2.mkt");
    let scene = build_file(&path, Preset::Tanker2);
    let url = format!("http://127.0.0.1:{}/t2.mkt", server.port);
    let remote = Database::open_url(&url, &RemoteOptions::default()).expect("open over HTTP");
    let opened = remote.transfer_counts().expect("a remote device counts");
    assert!(opened.requests <= 3, "{} requests to open", opened.requests);
    let local = Database::open_read_only(&path).expect("local");
    assert!(local.transfer_counts().is_none());
    let reads = assert_same_answers(&local, &remote, &boxes(&scene));
    let fetched = remote.transfer_counts().expect("counts");
    assert_eq!(
        fetched.requests as usize,
        server.logged_requests_once(fetched.requests as usize).len(),
        "{fetched:?}"
    );
    assert!(fetched.round_trips <= fetched.requests);
    assert!(reads > 0);
    assert!(fetched.bytes <= std::fs::metadata(&path).expect("size").len());
}

#[test]
fn a_query_fetches_the_blocks_it_will_read_ahead_in_fewer_round_trips() {
    let Some(server) = nginx() else { return };
    let path = server.dir.path().join("www/t2.mkt");
    let scene = build_file(&path, Preset::Tanker2);
    let url = format!("http://127.0.0.1:{}/t2.mkt", server.port);
    let local = Database::open_read_only(&path).expect("local");
    let (mut reads, mut waits) = (0, 0);
    // Each box from a cold reader: a wait per read, but for fetching ahead.
    for b in boxes(&scene) {
        let remote = Database::open_url(&url, &RemoteOptions::default()).expect("open");
        let opened = remote.transfer_counts().expect("counts");
        reads += assert_same_answers(&local, &remote, &[b]);
        waits += remote.transfer_counts().expect("counts").round_trips - opened.round_trips;
    }
    assert!(waits < reads, "{waits} round trips for {reads} block reads");
}

#[test]
fn a_file_replaced_under_a_reader_fails_with_object_changed() {
    let Some(server) = nginx() else { return };
    let path = server.dir.path().join("www/t2.mkt");
    let scene = build_file(&path, Preset::Tanker2);
    let url = format!("http://127.0.0.1:{}/t2.mkt", server.port);
    // No cache: every block read after the replacement goes to the server.
    let options = RemoteOptions { cache_bytes: 0, ..RemoteOptions::default() };
    let remote = Database::open_url(&url, &options).expect("open over HTTP");
    let other = server.dir.path().join("other.mkt");
    build_file(&other, Preset::Tanker1);
    replace_file(&path, &std::fs::read(&other).expect("other file"));
    let r = remote.begin_read().expect("the snapshot's header was read at open");
    match r.query_box(&scene.aabb()) {
        Err(mktree::query::QueryError::Storage(StorageError::ObjectChanged { url: u })) => assert_eq!(u, url),
        other => panic!("expected ObjectChanged, got {other:?}"),
    }
    // Opened again, it reads the new file.
    let again = Database::open_url(&url, &options).expect("open the new file");
    assert_same_answers(&Database::open_read_only(&path).expect("local"), &again, &boxes(&scene));
}

#[test]
fn a_missing_object_or_a_bad_url_is_a_clear_error() {
    let Some(server) = nginx() else { return };
    let url = format!("http://127.0.0.1:{}/none.mkt", server.port);
    match Database::open_url(&url, &RemoteOptions::default()) {
        Err(StorageError::Remote { url: u, detail }) => assert!(u == url && !detail.is_empty()),
        other => panic!("expected a Remote error, got {other:?}"),
    }
    std::fs::write(server.dir.path().join("www/text.mkt"), b"not an mktree file at all").expect("write");
    let url = format!("http://127.0.0.1:{}/text.mkt", server.port);
    assert!(matches!(
        Database::open_url(&url, &RemoteOptions::default()),
        Err(StorageError::Truncated { .. })
    ));
    assert!(matches!(
        Database::open_url("s3:/no-bucket", &RemoteOptions::default()),
        Err(StorageError::Remote { .. })
    ));
}
