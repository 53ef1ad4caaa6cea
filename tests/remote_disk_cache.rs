//! A reader's on-disk cache (`RemoteOptions::disk_cache`, issue 36 item 1,
//! format-spec/remote.md): a later reader of the same object version, in
//! any process, answers from the folder with no request but the open's; a
//! damaged page file is fetched again, never read; a new version of the
//! object reads none of the old pages; the folder keeps to its bound.
#![cfg(feature = "object-store")]

mod common;

use std::path::Path;

use common::remote::{assert_same_answers, boxes, build_file};
use common::servers::{nginx, replace_file};
use mktree::db::Database;
use mktree::scene::generate::Preset;
use mktree::store::device::{DiskCacheOptions, RemoteOptions};

fn with_folder(dir: &Path, bytes: u64) -> RemoteOptions {
    RemoteOptions {
        disk_cache: Some(DiskCacheOptions { dir: dir.to_path_buf(), bytes }),
        ..RemoteOptions::default()
    }
}

fn page_files(dir: &Path) -> Vec<std::path::PathBuf> {
    let mut out = Vec::new();
    for object in std::fs::read_dir(dir).expect("folder").flatten() {
        for page in std::fs::read_dir(object.path()).expect("object folder").flatten() {
            if page.path().extension().is_some_and(|x| x == "page") {
                out.push(page.path());
            }
        }
    }
    out
}

#[test]
fn a_later_reader_answers_from_the_folder_without_requests() {
    let Some(server) = nginx() else { return };
    let path = server.dir.path().join("www/t2.mkt");
    let scene = build_file(&path, Preset::Tanker2);
    let url = format!("http://127.0.0.1:{}/t2.mkt", server.port);
    let folder = tempfile::tempdir().expect("tempdir");
    let options = with_folder(folder.path(), 1 << 30);
    let local = Database::open_read_only(&path).expect("local");
    let queries = boxes(&scene);

    let first = Database::open_url(&url, &options).expect("open");
    assert_same_answers(&local, &first, &queries);
    let fetched = first.transfer_counts().expect("counts");
    assert!(fetched.requests > 1);
    assert!(!page_files(folder.path()).is_empty());

    // A new reader, as another process would be: only its open is a request.
    let second = Database::open_url(&url, &options).expect("open again");
    let opened = second.transfer_counts().expect("counts");
    assert_same_answers(&local, &second, &queries);
    assert_eq!(second.transfer_counts().expect("counts").since(&opened).requests, 0);

    // A damaged page file is a miss: fetched again, the answers unchanged.
    for page in page_files(folder.path()) {
        let mut bytes = std::fs::read(&page).expect("page");
        bytes[20] ^= 0x55;
        std::fs::write(&page, bytes).expect("damage");
    }
    let third = Database::open_url(&url, &options).expect("open a third time");
    let opened = third.transfer_counts().expect("counts");
    assert_same_answers(&local, &third, &queries);
    assert!(third.transfer_counts().expect("counts").since(&opened).requests > 0);

    // Another version of the object: none of the old pages is read.
    build_file(&server.dir.path().join("other.mkt"), Preset::Tanker1);
    replace_file(&path, &std::fs::read(server.dir.path().join("other.mkt")).expect("other"));
    let local = Database::open_read_only(&path).expect("the new local file");
    let fourth = Database::open_url(&url, &options).expect("open the new version");
    let opened = fourth.transfer_counts().expect("counts");
    assert_same_answers(&local, &fourth, &queries);
    // It fetches what a reader with no folder fetches.
    let bare = Database::open_url(&url, &RemoteOptions::default()).expect("open without a folder");
    let bare_opened = bare.transfer_counts().expect("counts");
    assert_same_answers(&local, &bare, &queries);
    assert_eq!(
        fourth.transfer_counts().expect("counts").since(&opened),
        bare.transfer_counts().expect("counts").since(&bare_opened)
    );
}

#[test]
fn the_folder_keeps_to_its_bound() {
    let Some(server) = nginx() else { return };
    let path = server.dir.path().join("www/t2.mkt");
    let scene = build_file(&path, Preset::Tanker2);
    let url = format!("http://127.0.0.1:{}/t2.mkt", server.port);
    let folder = tempfile::tempdir().expect("tempdir");
    let bound = 200 << 10;
    let remote = Database::open_url(&url, &with_folder(folder.path(), bound)).expect("open");
    let local = Database::open_read_only(&path).expect("local");
    let reads = assert_same_answers(&local, &remote, &boxes(&scene));
    assert!(reads * 16_384 > 2 * bound, "the queries read more than the bound: {reads} blocks");
    let kept: u64 = page_files(folder.path()).iter().map(|p| std::fs::metadata(p).expect("page").len()).sum();
    assert!(kept <= bound, "{kept} bytes kept, bound {bound}");
    assert!(kept > 0);
}
