//! Claim: a flipped bit in any block, a zeroed block, two swapped blocks, or
//! the file truncated at any length gives a typed error or the right answer,
//! never a panic and never a wrong answer; and `check` notices the damage.

mod common;

use std::sync::Arc;

use common::grid_scene;
use mktree::bulk::{BuildParams, LeafRule};
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
    let params = BuildParams { leaf: LeafRule::Objects(5), ..BuildParams::paper() };
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
    let f = common::forge::golden_with_looping_root(None);
    let db = Database::open_on(Arc::new(MemDevice::from_bytes(f)) as Arc<dyn BlockDevice>).unwrap();
    let err =
        db.begin_read().unwrap().query_box(&Aabb::from_array([-1e9, -1e9, -1e9, 1e9, 1e9, 1e9])).unwrap_err();
    // The checksums match again, so what is caught is the loop itself.
    assert!(err.is_corruption() && err.to_string().contains("loop"), "{err}");
    assert!(check(&db).is_err() || !check(&db).unwrap().ok());
}
