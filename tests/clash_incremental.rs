//! Claim: a recorded clash test re-run after any sequence of change
//! commits (inserts, moves, updates, removals) gives exactly the clashes
//! of a full run on the same commit, with the statuses a full run's would
//! give them, and is incremental when only change commits came between:
//! from the file's change log when it reaches back to the recorded run,
//! else from the recorded fingerprints (1 KiB blocks hold little log).

mod common;

use std::sync::Arc;

use common::{box_mesh, load_on};
use mktree::clash::{
    Clash, ClashStore, ClashTest, FoundBy, RunMode, TestKind, run_recorded, run_test, update,
};
use mktree::geom::Vector;
use mktree::scene::{Key, Object, Scene};
use mktree::store::device::MemDevice;
use mktree::{BuildParams, CreateOptions};
use proptest::prelude::*;

/// A box on a 50 mm grid (contacts, touches and gaps of whole steps happen often).
fn cell(name: u64, at: [u8; 3], size: [u8; 3]) -> Object {
    let lo = at.map(|x| f64::from(x) * 50.0);
    let hi = [0, 1, 2].map(|i| lo[i] + f64::from(size[i]) * 50.0 + 10.0);
    Object::new(
        if name.is_multiple_of(2) { format!("PIPE-{name}") } else { format!("WALL-{name}") },
        box_mesh(lo, hi),
    )
    .with_key(Key::Int(name))
}

#[derive(Debug, Clone)]
enum Change {
    Move(usize, [i8; 3]),
    Insert([u8; 3], [u8; 3]),
    Remove(usize),
    Resize(usize, [u8; 3]),
}

fn arb_change() -> impl Strategy<Value = Change> {
    let at = prop::array::uniform3(0u8..12);
    let size = prop::array::uniform3(1u8..5);
    prop_oneof![
        (any::<usize>(), prop::array::uniform3(-3i8..=3)).prop_map(|(i, d)| Change::Move(i, d)),
        (at, size.clone()).prop_map(|(a, s)| Change::Insert(a, s)),
        any::<usize>().prop_map(Change::Remove),
        (any::<usize>(), size).prop_map(|(i, s)| Change::Resize(i, s)),
    ]
}

fn tests() -> Vec<ClashTest> {
    let pipes = vec!["name:PIPE*".parse().unwrap()];
    let walls = Some(vec!["name:WALL*".parse().unwrap()]);
    vec![
        ClashTest { kind: TestKind::Clearance, distance: 30.0, touch: true, ..Default::default() },
        ClashTest {
            a: pipes,
            b: walls,
            kind: TestKind::Hard,
            tolerance: 5.0,
            touch: true,
            ..Default::default()
        },
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]

    #[test]
    fn a_re_run_equals_a_full_run(
        start in prop::collection::vec((prop::array::uniform3(0u8..12), prop::array::uniform3(1u8..5)), 4..30),
        commits in prop::collection::vec(prop::collection::vec(arb_change(), 1..5), 1..5),
        small in any::<bool>(),
    ) {
        let scene = Scene::new(start.iter().enumerate().map(|(i, &(a, s))| cell(i as u64, a, s)).collect());
        let options = CreateOptions { block_size: if small { 1024 } else { 4096 }, ..Default::default() };
        let db = load_on(Arc::new(MemDevice::new()), &scene, &BuildParams::default(), options);
        let mut store = ClashStore::default();
        for (n, t) in tests().iter().enumerate() {
            run_recorded(&db.begin_read().unwrap(), &mut store, &format!("t{n}"), Some(t), true).unwrap();
        }
        let mut keys: Vec<u64> = (0..start.len() as u64).collect();
        let mut next = start.len() as u64;
        for changes in commits {
            let mut w = db.begin_write().unwrap();
            for c in changes {
                match c {
                    Change::Move(i, d) if !keys.is_empty() => {
                        let k = Key::Int(keys[i % keys.len()]);
                        w.move_by(&k, Vector::new(f64::from(d[0]) * 50.0, f64::from(d[1]) * 50.0, f64::from(d[2]) * 50.0)).unwrap();
                    }
                    Change::Insert(a, s) => {
                        w.insert(cell(next, a, s)).unwrap();
                        keys.push(next);
                        next += 1;
                    }
                    Change::Remove(i) if keys.len() > 1 => {
                        let k = keys.remove(i % keys.len());
                        w.remove(&Key::Int(k)).unwrap();
                    }
                    Change::Resize(i, s) if !keys.is_empty() => {
                        let k = keys[i % keys.len()];
                        let at = w.object(&Key::Int(k)).unwrap().unwrap().aabb().min;
                        let at = [at.x, at.y, at.z].map(|x| (x / 50.0).round().clamp(0.0, 250.0) as u8);
                        w.update(cell(k, at, s)).unwrap();
                    }
                    _ => {}
                }
            }
            w.commit().unwrap();
            // Through the store's bytes, as the CLI keeps it between runs.
            store = ClashStore::from_bytes(&store.to_bytes().unwrap()).unwrap();
            let r = db.begin_read().unwrap();
            for (n, t) in tests().iter().enumerate() {
                let name = format!("t{n}");
                let before = store.runs[&name].tracked.clone();
                let rec = run_recorded(&r, &mut store, &name, None, true).unwrap();
                let RunMode::Incremental { by, .. } = rec.mode else {
                    return Err(TestCaseError::fail(format!("{:?}", rec.mode)));
                };
                // 4 KiB meta blocks hold a few commits of a few changes each.
                prop_assert!(small || by == FoundBy::Log, "{:?}", rec.mode);
                let full = run_test(&r, t).unwrap();
                let got: Vec<Clash> = store.runs[&name].clashes().cloned().collect();
                prop_assert_eq!(&got, &full.clashes);
                prop_assert_eq!(&store.runs[&name].tracked, &update(&before, &full.clashes, r.txn()));
            }
        }
    }
}

/// A commit of more changes than a meta block's log has room for: the
/// re-run after it learns what changed from the fingerprints, and the one
/// after a small commit from the log; both equal a full run.
#[test]
fn a_re_run_past_the_logs_reach_compares_fingerprints() {
    let scene =
        Scene::new((0..40).map(|i| cell(i, [(i % 12) as u8, (i / 12) as u8, 0], [1, 1, 1])).collect());
    let options = CreateOptions { block_size: 1024, ..Default::default() };
    let db = load_on(Arc::new(MemDevice::new()), &scene, &BuildParams::for_blocks(1024), options);
    let test = &tests()[0];
    let mut store = ClashStore::default();
    run_recorded(&db.begin_read().unwrap(), &mut store, "t", Some(test), true).unwrap();
    for (moved, expect) in [(0..20, FoundBy::Fingerprints), (3..4, FoundBy::Log)] {
        let mut w = db.begin_write().unwrap();
        for k in moved {
            assert!(w.move_by(&Key::Int(k), Vector::new(50.0, 0.0, 0.0)).unwrap());
        }
        w.commit().unwrap();
        let r = db.begin_read().unwrap();
        let rec = run_recorded(&r, &mut store, "t", None, true).unwrap();
        assert!(matches!(rec.mode, RunMode::Incremental { by, .. } if by == expect), "{:?}", rec.mode);
        let got: Vec<Clash> = store.runs["t"].clashes().cloned().collect();
        assert_eq!(got, run_test(&r, test).unwrap().clashes);
    }
}
