//! Claim: every input in the checked-in fuzz corpus (`fuzz/corpus/`) runs
//! through the fuzz targets' bodies (`mktree_fuzz`, `fuzz-bodies/`) without a panic,
//! and without an allocation above the fuzz targets' limit (this binary
//! refuses one, as the targets do: `fuzz/alloc_limit.rs`);
//! and the version 3 seeds are what their names say, so that replaying and
//! mutating them reaches version 3 code: the files open and `check` clean
//! (the traversal, inline bounds and geometry are read), the node blocks
//! validate and hold inline bounds, the blobs decode. The old seeds stay
//! beside them. Set MKTREE_BLESS=1 to rewrite the v10 seeds from the writer.

mod common;

#[path = "../fuzz/alloc_limit.rs"]
mod alloc_limit;

#[global_allocator]
static ALLOC: alloc_limit::Limited = alloc_limit::Limited;

use std::path::{Path, PathBuf};
use std::sync::mpsc::{self, RecvTimeoutError};
use std::sync::{Arc, OnceLock};
use std::time::Duration;

use common::forge;
use mktree::bulk::{BuildParams, LeafRule, Method};
use mktree::db::{CreateOptions, Database, check};
use mktree::geom::{Aabb, Point};
use mktree::lod::{Lattice, LodParams, Voxels, aligned_grid, decode, encode};
use mktree::scene::Scene;
use mktree::store::BlockDevice;
use mktree::store::device::MemDevice;
use mktree::store::format::frame::BlockType;
use mktree::store::format::node::{Limits, NodeView, validate_block};
use mktree_fuzz::forge::{Image, Record};
use proptest::prelude::*;

const BS: usize = 1024;

fn corpus(target: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz/corpus").join(target)
}

fn replay(target: &str, body: fn(&[u8])) -> usize {
    let dir = corpus(target);
    let mut n = 0;
    for entry in std::fs::read_dir(&dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display())) {
        let path = entry.unwrap().path();
        body(&std::fs::read(&path).unwrap());
        n += 1;
    }
    n
}

/// A fuzz target's body.
type Body = fn(&[u8]);

/// Every fuzz target with its body.
const TARGETS: [(&str, Body); 11] = [
    ("decode_block", mktree_fuzz::decode_block),
    ("open_and_query", mktree_fuzz::open_and_query),
    ("forge_header", mktree_fuzz::forge_header),
    ("forge_node", mktree_fuzz::forge_node),
    ("forge_geometry", mktree_fuzz::forge_geometry),
    ("forge_lod", mktree_fuzz::forge_lod),
    ("forge_free_list", mktree_fuzz::forge_free_list),
    ("forge_keys", mktree_fuzz::forge_keys),
    ("api_sequence", mktree_fuzz::api_sequence),
    ("clash_store", mktree_fuzz::clash_store),
    ("catalog", mktree_fuzz::catalog),
];

#[test]
fn the_corpus_replays_without_a_panic() {
    for (target, body) in TARGETS {
        assert!(replay(target, body) > 0, "{target} has a corpus");
    }
}

/// 24 slanted triangles in 1 KiB blocks with every bound stored (M = 4):
/// several node blocks, leaves with inline bounds of levels 2 and 3.
fn store_all_file() -> Vec<u8> {
    let scene = Scene::new(common::slanted_triangles(24));
    let dev = Arc::new(MemDevice::new());
    let db = Database::create_on(
        dev.clone() as Arc<dyn BlockDevice>,
        CreateOptions { block_size: BS as u32, lod_levels: 4 },
    )
    .unwrap();
    let mut w = db.begin_write().unwrap();
    w.set_lod_params(LodParams { store_all: true, ..LodParams::default() });
    let params = BuildParams { method: Method::Moa, leaf: LeafRule::Objects(3), ..BuildParams::paper() };
    w.bulk_load(&scene, &params, &|_| {}).unwrap();
    w.commit().unwrap();
    drop(db);
    dev.to_bytes()
}

/// The first node block of `file` holding a record with inline bounds.
fn node_block_with_bounds(file: &[u8], m: u8) -> &[u8] {
    (1..file.len() / BS)
        .map(|i| &file[i * BS..(i + 1) * BS])
        .filter(|b| b[4] == BlockType::Node as u8)
        .find(|b| bound_count(b, m) > 0)
        .expect("a node block with inline bounds")
}

/// The first group-bound block of `file` (format-spec/group.md).
fn group_block(file: &[u8]) -> &[u8] {
    (1..file.len() / BS)
        .map(|i| &file[i * BS..(i + 1) * BS])
        .find(|b| b[4] == BlockType::Group as u8)
        .expect("a group-bound block")
}

/// Inline bounds in the records of a node block that validates (only leaf
/// records hold bounds).
fn bound_count(block: &[u8], m: u8) -> usize {
    let limits = Limits { block_size: BS as u32, lod_levels: m, object_count: 1 << 20 };
    let offsets = validate_block(7, block, &limits).expect("the node block validates");
    offsets
        .iter()
        .map(|&o| match NodeView::at(block, o).unwrap() {
            NodeView::Internal(_) => 0,
            NodeView::Leaf(l) => l.bounds().count(),
        })
        .sum()
}

/// The box `mktree_fuzz::decode_block` decodes its input's blob over,
/// on a unit lattice at the origin: the blob seeds' grids are over it.
const BLOB_FRAME: [f64; 6] = [0.0, 0.0, 0.0, 40.0, 30.0, 20.0];

fn unit_lattice() -> Lattice {
    Lattice { origin: Point::origin(), cell: 1.0 }
}

/// A blob over [`BLOB_FRAME`]: a dense set (a bitmap, at lattice level 1:
/// 20 x 15 x 10 cells) or a sparse one (boxes with u8 corners, level 0).
fn blob(dense: bool) -> Vec<u8> {
    let level = if dense { 1 } else { 0 };
    let g = aligned_grid(&unit_lattice(), level, &Aabb::from_array(BLOB_FRAME)).unwrap();
    let mut v = Voxels::empty(g.clone());
    let d = g.dims();
    for x in 0..d[0] {
        for y in 0..d[1] {
            for z in 0..d[2] {
                let keep = if dense { (x + y + z) % 3 != 0 } else { x % 13 == 0 && y % 5 == 0 && z % 7 == 0 };
                if keep {
                    v.set_cell([x, y, z]);
                }
            }
        }
    }
    encode(&v)
}

/// The v10 seeds: (target, file name, bytes).
fn v10_seeds() -> Vec<(&'static str, &'static str, Vec<u8>)> {
    let golden = std::fs::read(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/golden/tiny-v10.mkt")).unwrap();
    let moved =
        std::fs::read(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/golden/tiny-v10-moved.mkt")).unwrap();
    let all = store_all_file();
    // decode_block's first byte chooses M (its value mod 16, plus 1).
    let with_m = |m: u8, bytes: &[u8]| [&[m - 1], bytes].concat();
    vec![
        ("decode_block", "v10-node-block-store-all", with_m(4, node_block_with_bounds(&all, 4))),
        ("decode_block", "v10-node-block-golden", with_m(3, node_block_with_bounds(&golden, 3))),
        ("decode_block", "v10-group-block", with_m(4, group_block(&all))),
        ("decode_block", "v10-blob-bitmap", with_m(1, &blob(true))),
        ("decode_block", "v10-blob-boxes", with_m(1, &blob(false))),
        ("open_and_query", "tiny-v10", golden),
        ("open_and_query", "v10-store-all", all),
        // A change commit synced once: its meta block lists what it wrote.
        ("open_and_query", "tiny-v10-moved", moved),
    ]
}

#[test]
fn the_v10_seeds_are_current_files_blocks_and_blobs() {
    let bless = std::env::var_os("MKTREE_BLESS").is_some();
    for (target, name, bytes) in v10_seeds() {
        let path = corpus(target).join(name);
        if bless {
            std::fs::write(&path, &bytes).unwrap();
        }
        let seed = std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        match (target, name) {
            ("open_and_query", _) => {
                let db = Database::open_on(Arc::new(MemDevice::from_bytes(seed)) as Arc<dyn BlockDevice>)
                    .unwrap_or_else(|e| panic!("{name}: {e}"));
                let report = check(&db).unwrap();
                assert!(report.ok(), "{name}: {:?}", report.faults);
                let info = db.begin_read().unwrap().lod_info().unwrap();
                assert!(
                    info.stored[1..usize::from(info.levels) - 1].iter().sum::<u64>() > 0,
                    "{name} has bounds"
                );
                if name == "v10-store-all" {
                    let img = forge::Image { bytes: std::fs::read(&path).unwrap(), bs: BS };
                    assert!(img.blocks_of(BlockType::Node).len() > 1, "{name} has several node blocks");
                    assert!(info.stored[1] > 0 && info.stored[2] > 0, "{name} has bounds of levels 2 and 3");
                }
            }
            (_, "v10-group-block") => {
                let entries = mktree::store::format::group::validate(7, &seed[1..], seed[0] % 16 + 1)
                    .unwrap_or_else(|e| panic!("{name}: {e}"));
                assert!(entries.len() > 1, "{name} holds several group bounds");
            }
            (_, n) if n.starts_with("v10-node-block") => {
                let m = seed[0] % 16 + 1;
                assert_eq!(seed.len(), 1 + BS, "{name}: a selector byte and a block");
                assert!(bound_count(&seed[1..], m) > 0, "{name} holds inline bounds");
            }
            _ => {
                let frame = Aabb::from_array(BLOB_FRAME);
                let v = decode(&seed[1..], &unit_lattice(), &frame).unwrap_or_else(|e| panic!("{name}: {e}"));
                let form = if name.ends_with("bitmap") { 1 } else { 2 };
                assert_eq!(seed[2], form, "{name} is in form {form}");
                assert!(!v.is_empty());
            }
        }
    }
}

/// The v10 seeds as checked in: (target, name, bytes). While blessing, the
/// seeds as written (another test is rewriting the files).
fn checked_in_v10_seeds() -> &'static [(&'static str, &'static str, Vec<u8>)] {
    static SEEDS: OnceLock<Vec<(&'static str, &'static str, Vec<u8>)>> = OnceLock::new();
    SEEDS.get_or_init(|| {
        let bless = std::env::var_os("MKTREE_BLESS").is_some();
        v10_seeds()
            .into_iter()
            .map(|(target, name, bytes)| {
                let bytes = if bless { bytes } else { std::fs::read(corpus(target).join(name)).unwrap() };
                (target, name, bytes)
            })
            .collect()
    })
}

/// The checked-in v10 seed `name`.
fn seed(name: &str) -> Vec<u8> {
    checked_in_v10_seeds().iter().find(|s| s.1 == name).expect("a v10 seed").2.clone()
}

/// Runs `f` on its own thread for at most `secs` seconds: a hang fails the
/// test instead of blocking the suite (the stuck thread is left behind), a
/// panic fails it as a panic.
fn finishes_within(secs: u64, f: impl FnOnce() + Send + 'static) -> Result<(), String> {
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        f();
        let _ = tx.send(());
    });
    match rx.recv_timeout(Duration::from_secs(secs)) {
        Ok(()) => Ok(()),
        Err(RecvTimeoutError::Timeout) => Err(format!("still running after {secs} s: a hang")),
        Err(RecvTimeoutError::Disconnected) => Err("panicked".into()),
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 96, max_shrink_iters: 0, ..ProptestConfig::default() })]

    /// Damaged v10 seeds (bytes flipped, a tail cut) go through the targets'
    /// bodies without a panic, as libFuzzer's first mutations would.
    #[test]
    fn mutated_v10_seeds_run_without_a_panic(
        pick in any::<prop::sample::Index>(),
        flips in prop::collection::vec((any::<prop::sample::Index>(), 1u8..=255), 1..6),
        cut in prop::option::of(any::<prop::sample::Index>()),
    ) {
        let all = checked_in_v10_seeds();
        let (target, _, bytes) = &all[pick.index(all.len())];
        let (is_file, mut bytes) = (*target == "open_and_query", bytes.clone());
        for (i, x) in flips {
            let i = i.index(bytes.len());
            bytes[i] ^= x;
        }
        if let Some(c) = cut {
            bytes.truncate(c.index(bytes.len() + 1));
        }
        let body = if is_file { mktree_fuzz::open_and_query } else { mktree_fuzz::decode_block };
        let run = finishes_within(10, move || body(&bytes));
        prop_assert!(run.is_ok(), "{:?}", run);
    }

    /// A v10 file with bytes of one node, geometry, names or meta block
    /// changed and every checksum up the chain made to match again (so the
    /// reader gets past the checksums to the forged content) opens, queries,
    /// walks and checks without a panic or a hang.
    #[test]
    fn forged_blocks_with_matching_checksums_run_without_a_panic(
        file in any::<bool>(),
        pick in any::<prop::sample::Index>(),
        flips in prop::collection::vec((any::<prop::sample::Index>(), 1u8..=255), 1..4),
    ) {
        let name = if file { "v10-store-all" } else { "tiny-v10" };
        let mut img = forge::Image { bytes: seed(name), bs: BS };
        let blocks: Vec<(usize, BlockType)> = (1..img.bytes.len() / BS)
            .map(|b| (b, BlockType::from_code(img.bytes[b * BS + 4]).unwrap()))
            .collect();
        let (b, t) = blocks[pick.index(blocks.len())];
        // Payload bytes only: a changed frame is the checksum's business.
        for (i, x) in flips {
            img.bytes[b * BS + 16 + i.index(BS - 16)] ^= x;
        }
        img.reseal(b, t);
        let run = finishes_within(10, move || mktree_fuzz::open_and_query(&img.bytes));
        prop_assert!(run.is_ok(), "block {} ({:?}) of {}: {:?}", b, t, name, run);
    }
}

/// The golden file with `forge` applied to its block `b` of type `t`, resealed.
fn forged_golden(b: usize, t: BlockType, forge: impl FnOnce(&mut [u8])) -> Vec<u8> {
    let bytes = std::fs::read(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/golden/tiny-v10.mkt")).unwrap();
    let mut img = forge::Image { bytes, bs: BS };
    // A layout change must move the forgery, not make it test nothing.
    assert!(BlockType::from_code(img.bytes[b * BS + 4]).unwrap() == t, "block {b} is not a {t:?} block");
    forge(&mut img.bytes[b * BS..(b + 1) * BS]);
    img.reseal(b, t);
    img.bytes
}

#[test]
fn a_forged_far_lattice_origin_is_an_error_not_a_hang() {
    // format-spec/example.md: block 1 is the meta block, lattice_origin at 416.
    let f = forged_golden(1, BlockType::Meta, |m| m[416..424].copy_from_slice(&1e300f64.to_le_bytes()));
    let run = finishes_within(10, move || mktree_fuzz::open_and_query(&f));
    assert!(run.is_ok(), "{run:?}");
}

#[test]
fn a_forged_far_vertex_is_a_fault_not_a_panic() {
    // Block 3 is the first geometry block; the plate (which has a bound) has
    // its record at payload 0, vertex 1's x offset at 40 + 12 in it.
    let f = forged_golden(3, BlockType::Geometry, |g| {
        g[16 + 52..16 + 56].copy_from_slice(&(-1e30f32).to_le_bytes())
    });
    let db = Database::open_on(Arc::new(MemDevice::from_bytes(f)) as Arc<dyn BlockDevice>).unwrap();
    let report = check(&db).unwrap();
    assert!(!report.ok(), "a plate vertex moved 1e30 mm away is a fault");
}

/// A forged copy of the store-all file: `edit` gets the image and the
/// offset of its meta block; every checksum is re-sealed after. `None` when
/// opening refuses the forgery as corrupt (what it should do with a count
/// the file's bytes cannot hold).
fn forged_store_all(edit: impl FnOnce(&mut Image, usize)) -> Option<Database> {
    let mut img = Image { bytes: seed("v10-store-all"), bs: BS };
    let meta = img.meta().expect("a meta block");
    edit(&mut img, meta);
    img.reseal();
    match Database::open_on(Arc::new(MemDevice::from_bytes(img.bytes)) as Arc<dyn BlockDevice>) {
        Ok(db) => Some(db),
        Err(e) => {
            assert!(e.is_corruption(), "{e}");
            None
        }
    }
}

// Engine bugs the structure-aware targets found, fixed: each test failed (a
// panic, or an abort for the allocation) before. The targets' inputs that
// found them are in `fuzz/findings/`, replayed by the last one.

#[test]
fn fetch_level_of_a_meta_block_claiming_no_node_blocks_does_not_overflow() {
    let Some(db) = forged_store_all(|img, meta| img.put_u32(meta + 44, 0)) else { return };
    let r = db.begin_read().unwrap();
    let _ = r.fetch_level(0, 2, true, &mut Default::default());
}

#[test]
fn fetch_level_below_child_entries_claiming_no_node_blocks_does_not_overflow() {
    let Some(db) = forged_store_all(|img, _| {
        // Every child entry naming another block claims no node blocks below it.
        for b in img.node_blocks() {
            for rec in img.records(b) {
                if let Record::Internal { at } = rec {
                    for c in 0..2 {
                        let e = at + 20 + 32 * c;
                        if img.u32(e + 12) != 0 {
                            img.put_u32(e + 24, 0);
                        }
                    }
                }
            }
        }
    }) else {
        panic!("child entries are not read at open")
    };
    let r = db.begin_read().unwrap();
    for node in 0..r.info().unwrap().nodes {
        let _ = r.fetch_level(node, 1, true, &mut Default::default());
    }
}

#[test]
fn fetch_level_of_a_meta_block_claiming_2_64_geometry_blocks_does_not_overflow() {
    let Some(db) = forged_store_all(|img, meta| img.put(meta + 48, &u64::MAX.to_le_bytes())) else { return };
    let r = db.begin_read().unwrap();
    let m = r.info().unwrap().lod_levels;
    let _ = r.fetch_level(0, m, true, &mut Default::default());
}

#[test]
fn check_does_not_size_an_allocation_from_the_meta_blocks_object_count() {
    // 2^32 - 1 objects and no names run: nothing else reads the count first.
    let Some(db) = forged_store_all(|img, meta| {
        img.put_u32(meta + 28, u32::MAX);
        img.put_u32(meta + 144, 0);
        img.put_u32(meta + 148, 0);
    }) else {
        return;
    };
    let report = check(&db).unwrap();
    assert!(!report.ok());
}

#[test]
fn the_findings_no_longer_crash() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz/findings");
    for (target, body) in TARGETS {
        if let Ok(entries) = std::fs::read_dir(dir.join(target)) {
            for entry in entries {
                body(&std::fs::read(entry.unwrap().path()).unwrap());
            }
        }
    }
}
