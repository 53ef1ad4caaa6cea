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
use mktree::geom::Aabb;
use mktree::scene::generate::{GenOptions, Preset, generate_scene};
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
    // Header, meta block and the top node blocks lie in the first range.
    assert_eq!((opened.requests, opened.round_trips), (1, 1), "a bulk-loaded file opens in one request");
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

/// A file whose last commit was one change synced once: the open reads
/// the meta block and the free list together, then every block the commit
/// lists together, so it waits three times, not once per listed block.
#[test]
fn a_file_after_a_change_commit_opens_in_three_round_trips() {
    let Some(server) = nginx() else { return };
    let path = server.dir.path().join("www/t2.mkt");
    let scene = build_file(&path, Preset::Tanker2);
    let db = Database::open(&path).expect("open to write");
    let mut w = db.begin_write().expect("write");
    // Generated objects have no keys: each has its id as an integer key.
    assert!(w.move_by(&mktree::scene::Key::Int(7), mktree::geom::Vector::new(10.0, 0.0, 0.0)).expect("move"));
    let stats = w.commit_with_stats().expect("commit");
    assert!(stats.in_place && stats.syncs == 1 && stats.blocks_written > 3, "{stats:?}");
    drop(db);
    let url = format!("http://127.0.0.1:{}/t2.mkt", server.port);
    let remote = Database::open_url(&url, &RemoteOptions::default()).expect("open over HTTP");
    let opened = remote.transfer_counts().expect("counts");
    assert!(opened.round_trips <= 3, "{opened:?}");
    let local = Database::open_read_only(&path).expect("local");
    assert_same_answers(&local, &remote, &boxes(&scene));
}

#[test]
fn a_query_fetches_the_blocks_it_will_read_ahead_in_fewer_round_trips() {
    let Some(server) = nginx() else { return };
    let path = server.dir.path().join("www/t2.mkt");
    let scene = build_file(&path, Preset::Tanker2);
    let url = format!("http://127.0.0.1:{}/t2.mkt", server.port);
    let local = Database::open_read_only(&path).expect("local");
    let (mut reads, mut waits, mut bytes) = (0, 0, 0);
    // Each box from a cold reader: a wait per read, but for fetching ahead.
    for b in boxes(&scene) {
        let remote = Database::open_url(&url, &RemoteOptions::default()).expect("open");
        let opened = remote.transfer_counts().expect("counts");
        reads += assert_same_answers(&local, &remote, &[b]);
        let query = remote.transfer_counts().expect("counts").since(&opened);
        (waits, bytes) = (waits + query.round_trips, bytes + query.bytes);
    }
    assert!(waits < reads, "{waits} round trips for {reads} block reads");
    // Requests joined across gaps fetch at most half again the blocks read.
    let block_size = u64::from(local.block_size());
    assert!(bytes * 2 <= reads * block_size * 3, "{bytes} bytes fetched for {reads} block reads");
}

/// Issue 36's bound: a small box from a cold reader waits for the network
/// at most once per node block on its deepest path below the root's (the
/// open fetched the root's block), plus once for the geometry of every
/// undecided object its leaves hold, fetched together.
#[test]
fn a_small_box_waits_no_more_than_the_node_block_depth() {
    let Some(server) = nginx() else { return };
    let path = server.dir.path().join("www/ship.mkt");
    let scene =
        generate_scene(&GenOptions { preset: Preset::Ship, objects: Some(20_000), seed: 3 }).expect("ship");
    // 4 KiB blocks: at 16 KiB the tree is 2 node blocks deep.
    let db = Database::create(&path, mktree::db::CreateOptions { block_size: 4096, ..Default::default() })
        .expect("create");
    let mut w = db.begin_write().expect("write");
    w.bulk_load(&scene, &mktree::BuildParams::default(), &|_| {}).expect("bulk load");
    w.commit().expect("commit");
    let depth =
        db.begin_read().expect("read").layout_drift().expect("layout").expect("a tree").node_block_depth;
    assert!(depth >= 3, "a tree {depth} node blocks deep tests little");
    let url = format!("http://127.0.0.1:{}/ship.mkt", server.port);
    let b = scene.aabb();
    let side = (b.max - b.min) * 0.01;
    let (mut waits, mut geometry) = (Vec::new(), 0);
    for o in scene.objects().iter().step_by(997) {
        let c = o.aabb().center();
        let q = Aabb::from_array([
            c.x - side.x / 2.0,
            c.y - side.y / 2.0,
            c.z - side.z / 2.0,
            c.x + side.x / 2.0,
            c.y + side.y / 2.0,
            c.z + side.z / 2.0,
        ]);
        let remote = Database::open_url(&url, &RemoteOptions::default()).expect("open");
        let opened = remote.transfer_counts().expect("counts");
        let answer = remote.begin_read().expect("read").query_box(&q).expect("query");
        geometry += answer.stats.reads.geometry;
        let wait = remote.transfer_counts().expect("counts").since(&opened).round_trips;
        assert!(wait <= u64::from(depth), "{wait} round trips, {depth} node blocks deep, for {q:?}");
        waits.push(wait);
    }
    assert!(geometry > waits.len() as u64, "the boxes read geometry: {geometry}");
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
        Err(StorageError::Remote { url: u, detail }) => {
            assert!(u == url && !detail.is_empty() && !detail.contains('\n'))
        }
        other => panic!("expected a Remote error, got {other:?}"),
    }
    std::fs::write(server.dir.path().join("www/empty.mkt"), b"").expect("write");
    let url = format!("http://127.0.0.1:{}/empty.mkt", server.port);
    assert!(matches!(Database::open_url(&url, &RemoteOptions::default()), Err(StorageError::NotMktree)));
    let empty = server.dir.path().join("www/empty.mkt");
    let local = format!("file://{}", empty.display());
    assert!(matches!(Database::open_url(&local, &RemoteOptions::default()), Err(StorageError::NotMktree)));
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
