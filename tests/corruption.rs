//! Claim: a flipped bit in any block, a zeroed block, two swapped blocks, or
//! the file truncated at any length gives a typed error or the right answer,
//! never a panic and never a wrong answer; and `check` notices the damage.

mod common;

use std::sync::Arc;

use common::grid_scene;
use mktree::build::{BuildParams, LeafRule};
use mktree::db::{CreateOptions, Database, check};
use mktree::geom::Aabb;
use mktree::store::BlockDevice;
use mktree::store::device::MemDevice;

const BS: usize = 1024;

fn queries() -> Vec<Aabb> {
    vec![
        Aabb::from_array([0.0, 0.0, 0.0, 1e4, 1e4, 1e4]),
        Aabb::from_array([0.0, 0.0, 0.0, 150.0, 150.0, 150.0]),
        Aabb::from_array([210.0, 20.0, 0.0, 260.0, 400.0, 90.0]),
    ]
}

fn image() -> Vec<u8> {
    let params = BuildParams { leaf: LeafRule::Objects(5), ..BuildParams::default() };
    common::image(&grid_scene(90), &params, CreateOptions { block_size: BS as u32, lod_levels: 2 })
}

/// Opens `bytes` and runs the queries: each answer must be the undamaged one
/// (or, when a commit slot was hit, the previous commit's: an empty tree) or a
/// typed corruption error. Returns true when everything opened and answered
/// and `check` found nothing: only acceptable for damage that was repaired.
fn probe(bytes: Vec<u8>, good: &[Vec<u32>], what: &str) -> bool {
    let db = match Database::open_on(Arc::new(MemDevice::from_bytes(bytes)) as Arc<dyn BlockDevice>) {
        Ok(db) => db,
        Err(e) => {
            assert!(e.is_corruption(), "{what}: open failed with a non-corruption error: {e}");
            return false;
        }
    };
    let r = db.begin_read().unwrap();
    let mut all_ok = true;
    for (q, want) in queries().iter().zip(good) {
        match r.query_box(q) {
            Ok(res) => {
                let got: Vec<u32> = res.objects.iter().map(|o| o.0).collect();
                assert!(got == *want || (r.info().is_none() && got.is_empty()), "{what}: wrong answer");
            }
            Err(e) => {
                assert!(e.is_corruption(), "{what}: query failed with a non-corruption error: {e}");
                all_ok = false;
            }
        }
    }
    all_ok && check(&db).map(|r| r.ok()).unwrap_or(false)
}

#[test]
fn damage_anywhere_is_an_error_or_the_right_answer() {
    let img = image();
    let good: Vec<Vec<u32>> = {
        let db =
            Database::open_on(Arc::new(MemDevice::from_bytes(img.clone())) as Arc<dyn BlockDevice>).unwrap();
        let r = db.begin_read().unwrap();
        queries().iter().map(|q| r.query_box(q).unwrap().objects.iter().map(|o| o.0).collect()).collect()
    };
    let blocks = img.len() / BS;
    assert!(blocks > 10);
    for b in 0..blocks {
        for offset in [0usize, 5, 17, 33, 100, 600, 513, 777, BS - 1] {
            let mut bytes = img.clone();
            bytes[b * BS + offset] ^= 1 << (offset % 8);
            let clean = probe(bytes, &good, &format!("bit flip in block {b} at {offset}"));
            // Only a flip in a commit slot can be repaired (the slot is discarded).
            assert!(
                !clean || (b == 0 && (512..1024).contains(&offset)),
                "block {b} offset {offset}: damage went unnoticed"
            );
        }
        let mut zeroed = img.clone();
        zeroed[b * BS..(b + 1) * BS].fill(0);
        assert!(!probe(zeroed, &good, &format!("zeroed block {b}")), "zeroed block {b} went unnoticed");
        if b + 1 < blocks {
            let mut swapped = img.clone();
            let (x, y) = swapped.split_at_mut((b + 1) * BS);
            x[b * BS..].swap_with_slice(&mut y[..BS]);
            if swapped != img {
                assert!(
                    !probe(swapped, &good, &format!("swapped blocks {b} and {}", b + 1)),
                    "swap {b} went unnoticed"
                );
            }
        }
    }
}

#[test]
fn a_truncated_file_is_refused() {
    let img = image();
    let mut lengths: Vec<usize> =
        (0..img.len()).step_by(BS).flat_map(|l| [l, l + 1, l + BS / 2]).filter(|&l| l < img.len()).collect();
    lengths.push(img.len() - 1);
    for len in lengths {
        let err =
            Database::open_on(Arc::new(MemDevice::from_bytes(img[..len].to_vec())) as Arc<dyn BlockDevice>)
                .expect_err("a truncated file must not open");
        assert!(err.is_corruption(), "length {len}: {err}");
    }
}

#[test]
fn a_child_link_that_loops_is_an_error_not_a_hang() {
    use mktree::store::format::frame::{BlockType, seal};
    use mktree::store::format::header::{Commit, SlotRead, SlotState, decode_slots, put_slot};
    // The golden file (format-spec/example.md): one node block holds the
    // root record (offset 24) and its two leaves; slot 1 holds the commit.
    let mut f = std::fs::read(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/golden/tiny-v4.mkt")).unwrap();
    let block = |i: usize| i * 1024..(i + 1) * 1024;
    let of_type = |f: &[u8], t: BlockType| (1..f.len() / 1024).find(|&i| f[i * 1024 + 4] == t as u8).unwrap();
    let (node, meta) = (of_type(&f, BlockType::Node), of_type(&f, BlockType::Meta));
    let txn = 2;
    // The root is an internal record (kind 1) at offset 24; its first child
    // entry starts at 20 in the record and names its record by `offset` at
    // 20 in the entry, with `block` 0 (this block): point it at the root.
    let root = node * 1024 + 24;
    assert_eq!(f[root], 1, "the root is an internal record");
    let entry = root + 20;
    assert_eq!(&f[entry + 12..entry + 16], &[0; 4], "the first child lives in the root's block");
    f[entry + 20..entry + 24].copy_from_slice(&24u32.to_le_bytes());
    let root_sum = seal(node as u32, &mut f[block(node)], BlockType::Node, txn);
    // The meta block holds the root block's checksum at offset 20; the slot holds the meta's.
    f[meta * 1024 + 20..meta * 1024 + 24].copy_from_slice(&root_sum.to_le_bytes());
    let meta_sum = seal(meta as u32, &mut f[block(meta)], BlockType::Meta, txn);
    let SlotRead::Committed(c) = decode_slots(&f)[1].value() else { panic!("slot 1") };
    let c = Commit { meta_checksum: meta_sum, ..c };
    put_slot(&mut f, 1, SlotState::Committed, &c);
    let db = Database::open_on(Arc::new(MemDevice::from_bytes(f)) as Arc<dyn BlockDevice>).unwrap();
    let err =
        db.begin_read().unwrap().query_box(&Aabb::from_array([-1e9, -1e9, -1e9, 1e9, 1e9, 1e9])).unwrap_err();
    // The checksums match again, so what is caught is the loop itself.
    assert!(err.is_corruption() && err.to_string().contains("loop"), "{err}");
    assert!(check(&db).is_err() || !check(&db).unwrap().ok());
}
