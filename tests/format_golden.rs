//! Claim: the writer produces the spec's example file byte for byte
//! (`tests/golden/tiny-v10.mkt`, whose dump `format-spec/example.md` shows),
//! and a reader opens it; the golden files of versions 1 to 9 are refused
//! with `UnsupportedVersion`, not misread. Set MKTREE_BLESS=1 to rewrite the
//! golden file and the example's dump after a deliberate format change
//! (with a new version: format-spec/versions.md).

mod common;

use std::sync::Arc;

use common::{box_mesh, triangle};
use mktree::bulk::{BuildParams, LeafRule, Method, build};
use mktree::db::{CreateOptions, Database, check};
use mktree::geom::Vector;
use mktree::lod::LodParams;
use mktree::scene::{Key, Object, Scene};
use mktree::store::device::MemDevice;
use mktree::store::{BlockDevice, StorageError};

const GOLDEN: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/golden/tiny-v10.mkt");
const GOLDEN_MOVED: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/golden/tiny-v10-moved.mkt");
const GOLDEN_V9: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/golden/tiny-v9.mkt");
const GOLDEN_V8: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/golden/tiny-v8.mkt");
const GOLDEN_V7: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/golden/tiny-v7.mkt");
const GOLDEN_V6: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/golden/tiny-v6.mkt");
const GOLDEN_V5: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/golden/tiny-v5.mkt");
const GOLDEN_V1: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/golden/tiny-v1.mkt");
const GOLDEN_V2: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/golden/tiny-v2.mkt");
const GOLDEN_V3: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/golden/tiny-v3.mkt");
const GOLDEN_V4: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/golden/tiny-v4.mkt");
const EXAMPLE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/format-spec/example.md");

/// Three objects, two leaves, 1,024-byte blocks, M = 3 (box, cuberille,
/// exact), every object's cuberille stored.
fn tiny() -> Vec<u8> {
    let scene = Scene::new(vec![
        Object::new("plate", triangle([0.0, 0.0, 0.0], [100.0, 0.0, 0.0], [0.0, 50.0, 0.0])),
        Object::new("box", box_mesh([10.0, 10.0, 10.0], [20.0, 30.0, 40.0])),
        Object::new("far", triangle([500.0, 0.0, 0.0], [600.0, 0.0, 0.0], [500.0, 10.0, 5.0])),
    ]);
    let params =
        BuildParams { method: Method::Moa, rate: 0.2, leaf: LeafRule::Objects(2), ..BuildParams::paper() };
    let tree = build(&scene.object_boxes(), None, &params, &|_| {}).unwrap();
    let dev = Arc::new(MemDevice::new());
    let db = Database::create_on(
        dev.clone() as Arc<dyn BlockDevice>,
        CreateOptions { block_size: 1024, lod_levels: 3 },
    )
    .unwrap();
    let mut w = db.begin_write().unwrap();
    // Every bound stored, so the example shows bound entries whatever the
    // policy judges them worth.
    w.set_lod_params(LodParams { store_all: true, ..LodParams::default() });
    w.write_tree(&scene, &tree, &params, 0.0).unwrap();
    w.commit().unwrap();
    assert!(check(&db).unwrap().ok());
    drop(db);
    dev.to_bytes()
}

/// The tiny file after one change commit: `far` moved 10 mm along x.
fn moved() -> Vec<u8> {
    let dev = Arc::new(MemDevice::from_bytes(tiny()));
    let db = Database::open_on(dev.clone() as Arc<dyn BlockDevice>).unwrap();
    let mut w = db.begin_write().unwrap();
    assert!(w.move_by(&Key::Int(2), Vector::new(10.0, 0.0, 0.0)).unwrap());
    let stats = w.commit_with_stats().unwrap();
    assert!(stats.in_place && stats.syncs == 1, "{stats:?}");
    assert!(check(&db).unwrap().ok());
    drop(db);
    dev.to_bytes()
}

/// `xxd`-style lines of 16 bytes; runs of all-zero lines collapse to `*`.
fn hexdump(bytes: &[u8]) -> String {
    let mut out = String::new();
    let mut in_zero_run = false;
    for (i, line) in bytes.chunks(16).enumerate() {
        let zero = line.iter().all(|&b| b == 0);
        let last = (i + 1) * 16 >= bytes.len();
        if zero && !last && i > 0 && bytes[(i - 1) * 16..i * 16].iter().all(|&b| b == 0) {
            if !in_zero_run {
                out.push_str("*\n");
                in_zero_run = true;
            }
            continue;
        }
        in_zero_run = false;
        let hex: Vec<String> =
            line.chunks(2).map(|p| p.iter().map(|b| format!("{b:02x}")).collect()).collect();
        out.push_str(&format!("{:08x}: {}\n", i * 16, hex.join(" ")));
    }
    out
}

fn fenced_dump(md: &str) -> Option<&str> {
    let start = md.find("```text\n")? + "```text\n".len();
    let end = start + md[start..].find("```")?;
    Some(&md[start..end])
}

#[test]
fn the_writer_reproduces_the_golden_file_and_the_spec_shows_it() {
    let bytes = tiny();
    if std::env::var_os("MKTREE_BLESS").is_some() {
        std::fs::write(GOLDEN, &bytes).unwrap();
        let md = std::fs::read_to_string(EXAMPLE).unwrap();
        let start = md.find("```text\n").expect("a ```text block") + "```text\n".len();
        let end = start + md[start..].find("```").expect("its end");
        std::fs::write(EXAMPLE, format!("{}{}{}", &md[..start], hexdump(&bytes), &md[end..])).unwrap();
    }
    let golden = std::fs::read(GOLDEN).expect("tests/golden/tiny-v10.mkt");
    assert!(bytes == golden, "the writer no longer produces the golden file byte for byte");
    let md = std::fs::read_to_string(EXAMPLE).unwrap();
    assert_eq!(
        fenced_dump(&md).expect("a ```text block in example.md"),
        hexdump(&golden),
        "example.md's dump differs from the golden file"
    );
    let db = Database::open_on(Arc::new(MemDevice::from_bytes(golden)) as Arc<dyn BlockDevice>).unwrap();
    let r = db.begin_read().unwrap();
    assert_eq!(r.info().unwrap().objects, 3);
    assert_eq!(r.names().unwrap(), vec!["plate", "box", "far"]);
}

#[test]
fn a_change_commit_synced_once_is_written_as_the_spec_says() {
    let bytes = moved();
    if std::env::var_os("MKTREE_BLESS").is_some() {
        std::fs::write(GOLDEN_MOVED, &bytes).unwrap();
    }
    let golden = std::fs::read(GOLDEN_MOVED).expect("tests/golden/tiny-v10-moved.mkt");
    assert!(bytes == golden, "the writer no longer produces the moved golden file byte for byte");
    // Transaction 3 went to slot 0 (offsets 0x200 and 0x300), state 3:
    // committed with one sync, its meta block listing what it wrote.
    for copy in [0x200, 0x300] {
        assert_eq!(golden[copy], 3, "txn");
        assert_eq!(golden[copy + 8], 3, "state");
    }
    let db = Database::open_on(Arc::new(MemDevice::from_bytes(golden)) as Arc<dyn BlockDevice>).unwrap();
    assert!(db.warnings().is_empty(), "{:?}", db.warnings());
    let r = db.begin_read().unwrap();
    let far = r.get(&Key::Int(2)).unwrap().unwrap();
    assert_eq!(far.aabb.min.x, 510.0);
}

#[test]
fn an_unknown_version_is_refused_not_guessed() {
    let mut bytes = std::fs::read(GOLDEN).unwrap();
    bytes[8] = 11;
    let err = Database::open_on(Arc::new(MemDevice::from_bytes(bytes)) as Arc<dyn BlockDevice>).unwrap_err();
    assert!(matches!(err, StorageError::UnsupportedVersion { found: 11, supported: 10 }), "{err}");
    assert!(err.to_string().contains("unsupported format version 11"), "{err}");
}

#[test]
fn version_1_to_9_files_are_refused_with_their_version() {
    for (path, found) in [
        (GOLDEN_V1, 1),
        (GOLDEN_V2, 2),
        (GOLDEN_V3, 3),
        (GOLDEN_V4, 4),
        (GOLDEN_V5, 5),
        (GOLDEN_V6, 6),
        (GOLDEN_V7, 7),
        (GOLDEN_V8, 8),
        (GOLDEN_V9, 9),
    ] {
        let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{path}: {e}"));
        assert_eq!(bytes[8], found as u8, "{path} is a version {found} file");
        let err =
            Database::open_on(Arc::new(MemDevice::from_bytes(bytes)) as Arc<dyn BlockDevice>).unwrap_err();
        assert!(
            matches!(err, StorageError::UnsupportedVersion { found: f, supported: 10 } if f == found),
            "{err}"
        );
        assert!(
            err.to_string()
                .contains(&format!("unsupported format version {found} (this build reads version 10)")),
            "{err}"
        );
    }
}
