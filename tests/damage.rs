//! Claim (issue 12): damage never turns into a wrong or older answer. For
//! every bit of both commit slots flipped, every block swapped with the same
//! block of a sibling file (the same scene scaled by 0.999, written by the
//! same commits), and every block a commit wrote reverted to its previous
//! contents (a lost write), the damaged file gives the newest tree's answers
//! or a typed error; reading it never writes a byte; and `check` reports
//! the damage unless the damaged block is free (and so read by nobody).

mod common;

use std::collections::BTreeSet;
use std::sync::Arc;

use common::box_mesh;
use mktree::bulk::{BuildParams, LeafRule, Method};
use mktree::db::{CreateOptions, Database, Warning, check};
use mktree::geom::Aabb;
use mktree::query::{ClashOptions, clash};
use mktree::scene::{Object, Scene};
use mktree::store::BlockDevice;
use mktree::store::device::MemDevice;
use mktree::store::format::freelist::FreeListBlock;
use mktree::store::format::header::{
    Commit, MAX_TXN, SLOT_LEN, Slot, SlotRead, SlotState, decode_slots, slot_offset,
};

const BS: usize = 1024;

/// Overlapping boxes (so `clash` has pairs) with long names (so the names
/// run has continuation blocks), scaled by `scale`.
fn scene(n: usize, scale: f64) -> Scene {
    Scene::new(
        (0..n)
            .map(|i| {
                let (x, y, z) = ((i % 5) as f64, ((i / 5) % 5) as f64, (i / 25) as f64);
                let lo = [x * 90.0 + (i % 3) as f64 * 20.0, y * 90.0, z * 90.0];
                let hi = [lo[0] + 70.0, lo[1] + 50.0 + (i % 4) as f64 * 10.0, lo[2] + 60.0];
                let name = format!("object {i} of the damage test, with a name long enough to fill blocks");
                Object::new(name, box_mesh(lo.map(|v| v * scale), hi.map(|v| v * scale)))
            })
            .collect(),
    )
}

/// The file after each of its commits: three trees of one scene (MOA,
/// median, MOA), so that the last commit reuses blocks and the file has free
/// blocks and a free list. `shift` empty commits first shift every
/// transaction id, so every block of a sibling differs from the original's.
fn images(scale: f64, shift: usize) -> [Vec<u8>; 3] {
    let dev = Arc::new(MemDevice::new());
    let db = Database::create_on(
        dev.clone() as Arc<dyn BlockDevice>,
        CreateOptions { block_size: BS as u32, lod_levels: 3 },
    )
    .unwrap();
    for _ in 0..shift {
        db.begin_write().unwrap().commit().unwrap();
    }
    let s = scene(60, scale);
    let mut out = Vec::new();
    for method in [Method::Moa, Method::Median, Method::Moa] {
        let mut w = db.begin_write().unwrap();
        let params = BuildParams { method, leaf: LeafRule::Objects(4), ..BuildParams::paper() };
        w.bulk_load(&s, &params, &|_| {}).unwrap();
        w.commit().unwrap();
        out.push(dev.to_bytes());
    }
    out.try_into().unwrap()
}

/// What a reader can learn: names, box queries at every level, clash.
type Answers = (Vec<String>, Vec<Vec<u32>>, Vec<(u32, u32)>);

fn answers(db: &Database) -> Result<Answers, Box<dyn std::error::Error>> {
    let r = db.begin_read()?;
    let names = r.names()?;
    let mut boxes = Vec::new();
    for b in [
        [0.0, 0.0, 0.0, 1e4, 1e4, 1e4],
        [100.0, 50.0, 0.0, 200.0, 150.0, 95.0],
        [310.0, 0.0, 0.0, 330.0, 500.0, 40.0],
    ] {
        boxes.push(r.query_box(&Aabb::from_array(b))?.objects.iter().map(|o| o.0).collect());
    }
    let pairs = clash(&r, &ClashOptions::default(), None)?.pairs.iter().map(|(a, b)| (a.0, b.0)).collect();
    Ok((names, boxes, pairs))
}

/// Blocks free in the newest commit of `image`.
fn free_blocks(image: &[u8]) -> BTreeSet<usize> {
    let c = decode_slots(image)
        .iter()
        .filter_map(|p| match p.value() {
            SlotRead::Committed(c) => Some(c),
            _ => None,
        })
        .max_by_key(|c| c.txn)
        .unwrap();
    let mut free = BTreeSet::new();
    let mut next = c.freelist_block as usize;
    while next != 0 {
        free.insert(next);
        let fl = FreeListBlock::decode(next as u32, &image[next * BS..(next + 1) * BS]).unwrap();
        for r in fl.ranges {
            free.extend(r.first as usize..(r.first + r.count) as usize);
        }
        next = fl.next_block as usize;
    }
    free.remove(&(c.freelist_block as usize));
    free
}

/// Opens `damaged`, reads everything, checks it. Returns whether `check`
/// reported the damage; panics on a wrong answer or a written byte.
fn examine(damaged: Vec<u8>, newest: &Answers, what: &str) -> bool {
    let dev = Arc::new(MemDevice::from_bytes(damaged.clone()));
    let db = match Database::open_on(dev.clone() as Arc<dyn BlockDevice>) {
        Ok(db) => db,
        Err(e) => {
            assert!(e.is_corruption(), "{what}: open failed with a non-corruption error: {e}");
            return true;
        }
    };
    if let Ok(got) = answers(&db) {
        assert!(&got == newest, "{what}: the answers are not the newest tree's");
    }
    let reported = match check(&db) {
        Err(_) => true,
        Ok(r) => !r.ok() || !r.warnings.is_empty(),
    };
    drop(db);
    assert!(dev.to_bytes() == damaged, "{what}: reading the file wrote to it");
    reported
}

#[test]
fn every_bit_of_both_slots_flipped_gives_the_newest_tree_and_a_report() {
    let [.., image] = images(1.0, 0);
    let db =
        Database::open_on(Arc::new(MemDevice::from_bytes(image.clone())) as Arc<dyn BlockDevice>).unwrap();
    let newest = answers(&db).unwrap();
    assert!(check(&db).unwrap().ok());
    let mut warned = 0;
    for slot in 0..2 {
        for copy in 0..2 {
            for bit in 0..SLOT_LEN * 8 {
                let mut damaged = image.clone();
                damaged[slot_offset(slot, copy) + bit / 8] ^= 1 << (bit % 8);
                let db = Database::open_on(
                    Arc::new(MemDevice::from_bytes(damaged.clone())) as Arc<dyn BlockDevice>
                )
                .unwrap_or_else(|e| {
                    panic!("slot {slot} copy {copy} bit {bit}: one damaged copy loses nothing: {e}")
                });
                assert_eq!(db.warnings(), &[Warning::DamagedSlotCopy { slot: slot as u8, copy: copy as u8 }]);
                drop(db);
                assert!(examine(damaged, &newest, &format!("slot {slot} copy {copy} bit {bit}")));
                warned += 1;
            }
        }
    }
    assert_eq!(warned, 4 * SLOT_LEN * 8);
}

#[test]
fn both_copies_of_the_newest_slot_damaged_is_an_error_not_an_older_tree() {
    let [.., image] = images(1.0, 0);
    let newest_slot = (0..2)
        .find(|&s| matches!(decode_slots(&image)[s].value(), SlotRead::Committed(c) if c.txn == 4))
        .unwrap();
    let mut damaged = image.clone();
    for copy in 0..2 {
        damaged[slot_offset(newest_slot, copy)] ^= 0x10;
    }
    let err =
        Database::open_on(Arc::new(MemDevice::from_bytes(damaged)) as Arc<dyn BlockDevice>).unwrap_err();
    assert!(err.is_corruption() && err.to_string().contains("both copies"), "{err}");
}

#[test]
fn a_file_at_the_largest_transaction_id_reads_and_refuses_a_writer() {
    let [.., image] = images(1.0, 0);
    let slots = decode_slots(&image);
    let newest = (0..2).find(|&s| matches!(slots[s].value(), SlotRead::Committed(c) if c.txn == 4)).unwrap();
    let SlotRead::Committed(c) = slots[newest].value() else { unreachable!() };
    let mut last = image.clone();
    for copy in 0..2 {
        let at = slot_offset(newest, copy);
        let sealed = Slot::encode(newest, copy, SlotState::Committed, &Commit { txn: MAX_TXN, ..c });
        last[at..at + SLOT_LEN].copy_from_slice(&sealed);
    }
    let dev = Arc::new(MemDevice::from_bytes(last.clone()));
    let db = Database::open_on(dev.clone() as Arc<dyn BlockDevice>).unwrap();
    answers(&db).unwrap();
    // The next id would name no reader lock byte (and wrap at 2^64).
    let err = db.begin_write().err().expect("the writer is refused");
    assert!(err.to_string().contains("exhausted"), "{err}");
    assert_eq!(dev.to_bytes(), last, "nothing is written");
}

#[test]
fn every_block_swapped_with_a_siblings_is_caught_or_harmless() {
    let [.., image] = images(1.0, 0);
    let [.., sibling] = images(0.999, 1);
    assert_eq!(image.len(), sibling.len(), "the sibling has the same layout");
    let db =
        Database::open_on(Arc::new(MemDevice::from_bytes(image.clone())) as Arc<dyn BlockDevice>).unwrap();
    let newest = answers(&db).unwrap();
    let free = free_blocks(&image);
    let mut types = BTreeSet::new();
    for b in 1..image.len() / BS {
        let block = b * BS..(b + 1) * BS;
        if image[block.clone()] == sibling[block.clone()] {
            continue;
        }
        types.insert(image[b * BS + 4]);
        let mut damaged = image.clone();
        damaged[block.clone()].copy_from_slice(&sibling[block]);
        let reported = examine(damaged, &newest, &format!("block {b} swapped"));
        assert!(
            reported || free.contains(&b),
            "block {b} (type {}) swapped, and check says ok",
            image[b * BS + 4]
        );
    }
    // Meta, node, geometry, free list, key leaf and branch: every type a tree has.
    assert!(types.is_superset(&BTreeSet::from([1, 2, 3, 5, 8, 9])), "types swapped: {types:?}");
}

#[test]
fn every_lost_write_of_the_last_commit_is_caught_or_harmless() {
    let [_, before, after] = images(1.0, 0);
    let db =
        Database::open_on(Arc::new(MemDevice::from_bytes(after.clone())) as Arc<dyn BlockDevice>).unwrap();
    let newest = answers(&db).unwrap();
    let free = free_blocks(&after);
    let mut lost = 0;
    for b in 1..before.len() / BS {
        let block = b * BS..(b + 1) * BS;
        if before[block.clone()] == after[block.clone()] {
            continue;
        }
        let mut damaged = after.clone();
        damaged[block.clone()].copy_from_slice(&before[block]);
        let reported = examine(damaged, &newest, &format!("write of block {b} lost"));
        assert!(reported || free.contains(&b), "the write of block {b} was lost, and check says ok");
        lost += 1;
    }
    assert!(lost > 0);
}

/// A damaged slot copy on a device another process may write is read again
/// (it may be a write in progress); on one whose writes are atomic it is
/// read once, so opening a damaged in-memory image does not pause.
#[test]
fn a_damaged_slot_copy_is_read_again_only_where_a_write_may_be_in_progress() {
    struct Header {
        bytes: MemDevice,
        atomic: bool,
        header_reads: std::sync::atomic::AtomicUsize,
    }
    impl BlockDevice for Header {
        fn read_at(&self, offset: u64, buf: &mut [u8]) -> std::io::Result<()> {
            if offset == 0 {
                self.header_reads.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            }
            self.bytes.read_at(offset, buf)
        }
        fn write_at(&self, offset: u64, data: &[u8]) -> std::io::Result<()> {
            self.bytes.write_at(offset, data)
        }
        fn sync(&self) -> std::io::Result<()> {
            Ok(())
        }
        fn len(&self) -> std::io::Result<u64> {
            self.bytes.len()
        }
        fn set_len(&self, len: u64) -> std::io::Result<()> {
            self.bytes.set_len(len)
        }
        fn writes_are_atomic(&self) -> bool {
            self.atomic
        }
    }
    let [.., image] = images(1.0, 0);
    let mut damaged = image;
    damaged[slot_offset(0, 1)] ^= 1;
    let mut reads = Vec::new();
    for atomic in [true, false] {
        let dev = Arc::new(Header {
            bytes: MemDevice::from_bytes(damaged.clone()),
            atomic,
            header_reads: Default::default(),
        });
        let db = Database::open_on(dev.clone() as Arc<dyn BlockDevice>).unwrap();
        assert_eq!(db.warnings(), &[Warning::DamagedSlotCopy { slot: 0, copy: 1 }]);
        reads.push(dev.header_reads.load(std::sync::atomic::Ordering::Relaxed));
    }
    assert!(reads[0] >= 1 && reads[1] == reads[0] + 2, "header reads: {reads:?}");
}
