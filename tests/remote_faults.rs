//! A server that fails, cuts its answers short or changes their bytes in
//! the middle of a query gives the reader a typed error, never a wrong
//! answer (issue 36): a server error or a short answer is
//! `StorageError::Remote` once the retries are spent, changed bytes fail
//! their block's checksum (`StorageError::Corruption`).
#![cfg(feature = "object-store")]

mod common;

use std::time::Duration;

use common::remote::{boxes, build_file};
use common::servers::{Fault, faulty};
use mktree::db::Database;
use mktree::query::QueryError;
use mktree::scene::generate::Preset;
use mktree::store::StorageError;
use mktree::store::device::RemoteOptions;

/// Every box's answer over a server that fails as `fault` says once the
/// open is done: equal to the local answer, or the error `expected` allows.
fn answers_or_typed_errors(fault: Fault, expected: fn(&StorageError) -> bool) {
    let dir = tempfile::tempdir().expect("folder");
    let path = dir.path().join("t2.mkt");
    let scene = build_file(&path, Preset::Tanker2);
    let local = Database::open_read_only(&path).expect("local");
    // A bulk-loaded file opens in one request (format-spec/remote.md); faults follow.
    let port = faulty(std::fs::read(&path).expect("file"), 1, fault);
    let options =
        RemoteOptions { retries: 1, retry_timeout: Duration::from_secs(5), ..RemoteOptions::default() };
    let remote = Database::open_url(&format!("http://127.0.0.1:{port}/t2.mkt"), &options).expect("open");
    let (l, r) = (local.begin_read().expect("read"), remote.begin_read().expect("read"));
    let mut errors = 0;
    for b in boxes(&scene) {
        match r.query_box(&b) {
            Ok(answer) => assert_eq!(answer.objects, l.query_box(&b).expect("local").objects, "{fault:?}"),
            Err(QueryError::Storage(e)) if expected(&e) => errors += 1,
            Err(e) => panic!("{fault:?}: an unexpected error {e:?}"),
        }
    }
    assert!(errors > 0, "{fault:?}: no query met the fault");
}

#[test]
fn a_server_error_is_a_remote_error() {
    answers_or_typed_errors(Fault::ServerError, |e| matches!(e, StorageError::Remote { .. }));
}

#[test]
fn a_short_answer_is_a_remote_error() {
    answers_or_typed_errors(Fault::Truncate, |e| matches!(e, StorageError::Remote { .. }));
}

#[test]
fn changed_bytes_fail_their_checksum() {
    answers_or_typed_errors(Fault::Flip, StorageError::is_corruption);
}
