//! Claim: a tree in a redb table is read in the application's snapshot. A
//! reader opened before later commits (a rebuild, inserts, removals) keeps
//! answering its tree with the same block reads, even once the
//! application's read transaction is dropped; and after any sequence of
//! edits, committed or aborted, each snapshot's tree agrees with the
//! application's rows of that snapshot, and the table holds exactly the
//! tree's blocks.

mod common;

use std::collections::BTreeMap;

use common::box_mesh;
use mktree::bulk::{BuildParams, LeafRule};
use mktree::db::CreateOptions;
use mktree::query::{QueryOptions, Region, query_region};
use mktree::redb::TreeDefinition;
use mktree::scene::generate::{GenOptions, Preset, generate_scene};
use mktree::{Aabb, Key, Object, ReadTransaction};
use proptest::prelude::*;
use redb::{ReadableDatabase, ReadableTableMetadata, TableDefinition};

const COUNT: TableDefinition<&str, u64> = TableDefinition::new("count");
const INDEX: TreeDefinition = TreeDefinition::new("index");
const SMALL: TreeDefinition =
    TreeDefinition::new("small").with_options(CreateOptions { block_size: 1024, lod_levels: 2 });
const SMALL_BLOCKS: TableDefinition<u32, &[u8]> = TableDefinition::new("small");

fn mem_redb() -> redb::Database {
    redb::Builder::new().create_with_backend(redb::backends::InMemoryBackend::new()).unwrap()
}

/// Box queries of 1% to 20% of `scene_box` on a grid: (objects, reads) each.
fn answers(r: &ReadTransaction, scene_box: &Aabb) -> Vec<(Vec<u32>, u64)> {
    let s = scene_box.to_array();
    let mut out = Vec::new();
    for share in [0.01, 0.05, 0.2] {
        for i in 0..5 {
            let mut b = [0.0; 6];
            for a in 0..3 {
                let side = (s[a + 3] - s[a]) * share;
                b[a] = s[a] + (s[a + 3] - s[a] - side) * f64::from(i) / 4.0;
                b[a + 3] = b[a] + side;
            }
            let q =
                query_region(r, &Region::Box(Aabb::from_array(b)), &QueryOptions::default(), None).unwrap();
            out.push((q.objects.iter().map(|o| o.0).collect(), q.stats.reads.total()));
        }
    }
    out
}

#[test]
fn a_reader_keeps_its_snapshot_across_later_commits() {
    let first = generate_scene(&GenOptions { preset: Preset::Tanker1, objects: None, seed: 4 }).unwrap();
    let second = generate_scene(&GenOptions { preset: Preset::Ship, objects: Some(300), seed: 5 }).unwrap();
    let db = mem_redb();
    let load = |scene: &mktree::Scene| {
        let txn = db.begin_write().unwrap();
        txn.open_table(COUNT).unwrap().insert("objects", scene.len() as u64).unwrap();
        INDEX.write(&txn, |w| w.bulk_load(scene, &BuildParams::default(), &|_| {}).map(|_| ())).unwrap();
        txn.commit().unwrap();
    };
    load(&first);
    let before = db.begin_read().unwrap();
    let old = INDEX.read(&before).unwrap();
    let old_answers = answers(&old, &first.aabb());
    assert!(old_answers.iter().any(|a| !a.0.is_empty()));
    drop(before);
    load(&second);
    let txn = db.begin_write().unwrap();
    INDEX
        .write(&txn, |w| {
            w.remove(&Key::Int(0))?;
            w.insert(Object::new("new", box_mesh([0.0; 3], [500.0; 3])))?;
            Ok(())
        })
        .unwrap();
    txn.commit().unwrap();
    // The old reader: its tree, its reads, whatever was committed since.
    assert_eq!(old.info().unwrap().objects as usize, first.len());
    assert_eq!(answers(&old, &first.aabb()), old_answers);
    // A new reader sees the newest tree and the row committed with it.
    let now = db.begin_read().unwrap();
    let r = INDEX.read(&now).unwrap();
    assert_eq!(r.info().unwrap().objects as usize, second.len());
    assert_eq!(now.open_table(COUNT).unwrap().get("objects").unwrap().unwrap().value(), second.len() as u64);
    assert!(r.get(&Key::Int(0)).unwrap().is_none());
}

#[derive(Debug, Clone)]
enum Edit {
    Insert { at: [f64; 3], side: f64 },
    Remove(prop::sample::Index),
}

fn edit() -> impl Strategy<Value = Edit> {
    prop_oneof![
        (prop::array::uniform3(0.0f64..2000.0), 10.0f64..300.0)
            .prop_map(|(at, side)| Edit::Insert { at, side }),
        any::<prop::sample::Index>().prop_map(Edit::Remove),
    ]
}

/// The keys of the tree a snapshot reads, and the application's count there.
fn snapshot(txn: &redb::ReadTransaction) -> (Vec<Key>, u64) {
    let r = SMALL.read(txn).unwrap();
    let mut keys = match r.info() {
        Some(_) => r.query_box(&Aabb::from_array([-1.0, -1.0, -1.0, 3000.0, 3000.0, 3000.0])).unwrap().keys,
        None => Vec::new(),
    };
    keys.sort();
    let count = txn.open_table(COUNT).map_or(0, |t| t.get("objects").unwrap().map_or(0, |v| v.value()));
    if let Some(info) = r.info() {
        let values = txn.open_table(SMALL_BLOCKS).unwrap().len().unwrap();
        assert_eq!(
            values,
            u64::from(info.file_blocks - info.free_blocks),
            "the table holds the tree's blocks"
        );
    }
    (keys, count)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]
    /// Each transaction edits the tree and the application's count of its
    /// objects; some abort. Every snapshot taken along the way still reads
    /// its own state at the end.
    #[test]
    fn every_snapshot_agrees_with_its_rows(steps in prop::collection::vec((edit(), any::<bool>()), 1..12)) {
        let db = mem_redb();
        let mut model: BTreeMap<Key, ()> = BTreeMap::new();
        let mut next = 0u64;
        let mut held = Vec::new();
        for (step, (e, commit)) in steps.into_iter().enumerate() {
            let txn = db.begin_write().unwrap();
            let mut after = model.clone();
            match e {
                Edit::Insert { at, side } => {
                    let key = Key::Int(next);
                    next += 1;
                    let o = Object::new(format!("o{step}"), box_mesh(at, [at[0] + side, at[1] + side, at[2] + side]))
                        .with_key(key.clone());
                    let params = BuildParams { leaf: LeafRule::Objects(3), ..BuildParams::paper() };
                    SMALL.write(&txn, |w| {
                        if after.is_empty() {
                            w.bulk_load(&mktree::Scene::new(vec![o]), &params, &|_| {})?;
                        } else {
                            w.insert(o)?;
                        }
                        Ok(())
                    }).unwrap();
                    after.insert(key, ());
                }
                Edit::Remove(i) if !model.is_empty() => {
                    let key = model.keys().nth(i.index(model.len())).unwrap().clone();
                    let removed = SMALL.write(&txn, |w| w.remove(&key)).unwrap();
                    prop_assert!(removed.is_some());
                    after.remove(&key);
                }
                Edit::Remove(_) => {}
            }
            txn.open_table(COUNT).unwrap().insert("objects", after.len() as u64).unwrap();
            if commit {
                txn.commit().unwrap();
                model = after;
            } else {
                txn.abort().unwrap();
            }
            let r = db.begin_read().unwrap();
            let expected: Vec<Key> = model.keys().cloned().collect();
            prop_assert_eq!(snapshot(&r), (expected.clone(), model.len() as u64), "step {}", step);
            held.push((r, expected));
        }
        for (r, expected) in &held {
            let n = expected.len() as u64;
            prop_assert_eq!(snapshot(r), (expected.clone(), n));
        }
    }
}
