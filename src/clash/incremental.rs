//! Re-running a recorded test after later commits (docs/clash.md,
//! "Re-runs"): only pairs with a changed object are measured; the
//! recorded clashes between unchanged objects are kept. The answer equals
//! a full run's, because a clash is a function of its pair's meshes and
//! the test (`run.rs`), and set membership of an unchanged object is
//! unchanged (its key, name and payload are).
//!
//! What changed comes from the file's change log (format-spec/meta.md,
//! "The change log"): the keys each commit since the recorded run
//! inserted, updated or removed. When the log does not reach back that
//! far (more changes than a meta block holds, a bulk load since), the
//! recorded run's fingerprints are compared with the key index instead:
//! every insert and update gives its object a new id (meta `object_ids`
//! only grows under change commits), so a key with the same id and box
//! holds the same object. A bulk load numbers ids from 0 again and writes
//! a new build time; when the file's `object_ids` shrank or its build
//! time differs, the run is a full one. Listing the key index still reads
//! every key block (O(N) small reads, no geometry); the measuring grows
//! with the changed objects.
//!
//! When the log tells, and the changed keys are few (at most one in
//! [`FEW`] of the objects), the key index is not listed: each changed
//! key's entry is looked up, and the objects whose boxes may lie within the
//! test's reach of a changed one are found by a box query through the tree
//! (level 1, the stored boxes, which contain the exact ones) and looked up
//! in turn. Only those entries are read, so the run's reads grow with the
//! changed objects and their neighbours, not with N.

use std::collections::BTreeMap;

use rustc_hash::FxHashSet as HashSet;
use std::time::Instant;

use serde::Serialize;

use super::ClashError;
use super::group::GroupBy;
use super::run::{RunStats, run_on, sort};
use super::status::{Status, Tracked, merge};
use super::store::{ClashStore, Fingerprint, RecordedRun, SavedTest};
use super::test::ClashTest;
use crate::db::{ReadTransaction, Reads};
use crate::geom::{Aabb, Vector};
use crate::query::{QueryOptions, Region, query_region};
use crate::scene::Key;
use crate::store::StorageError;
use crate::store::format::keys::KeyEntry;

/// How a run was made.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "mode", rename_all = "lowercase")]
pub enum RunMode {
    /// Every pair measured; why.
    Full {
        /// Why the run was full.
        why: String,
    },
    /// Only pairs with a changed object measured.
    Incremental {
        /// How the changed objects were found.
        by: FoundBy,
        /// Objects inserted or changed since the recorded run.
        changed: usize,
        /// Objects removed since.
        removed: usize,
        /// Recorded clashes kept as they were.
        kept: usize,
    },
}

/// Where an incremental run learned what changed since the recorded run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum FoundBy {
    /// The file's change log.
    Log,
    /// The recorded run's fingerprints compared with the key index.
    Fingerprints,
}

/// A run, recorded: what it did and how it was made. Its clashes, with
/// their statuses and every clash recorded so far (resolved ones too), are
/// the store's record of the run ([`ClashStore::runs`],
/// `RecordedRun::clashes`), not copied here: a run on 10^6 objects
/// tracks over a million.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Recorded {
    /// The commit the run read ([`ReadTransaction::txn`]).
    pub txn: u64,
    /// What the run did.
    pub stats: RunStats,
    /// Full or incremental.
    pub mode: RunMode,
}

fn fingerprints(entries: &[KeyEntry]) -> Vec<Fingerprint> {
    entries
        .iter()
        .map(|e| Fingerprint { key: e.key.clone(), id: e.object_id, aabb: e.aabb.to_array() })
        .collect()
}

/// Why `previous` cannot seed an incremental run on `txn`, if it cannot.
fn why_full(txn: &ReadTransaction, test: &ClashTest, previous: Option<&RecordedRun>) -> Option<String> {
    let Some(p) = previous else { return Some("no recorded run".into()) };
    if &p.test != test {
        return Some("the test changed since the recorded run".into());
    }
    if txn.txn() < p.txn {
        return Some(format!("the file's commit {} is older than the recorded run's {}", txn.txn(), p.txn));
    }
    None
}

/// Why `p`'s fingerprints cannot tell what changed on `txn`, if they cannot.
fn why_not_fingerprints(txn: &ReadTransaction, p: &RecordedRun) -> Option<String> {
    if txn.object_ids() < p.object_ids {
        return Some("object ids were numbered anew (a bulk load)".into());
    }
    let build = txn.info().map_or(0, |i| i.build_seconds.to_bits());
    if build != p.build {
        return Some("the tree was built anew (a bulk load)".into());
    }
    None
}

/// Per entry whether it changed, every key touched, and how they were found.
type Changed = (Vec<bool>, HashSet<Key>, FoundBy);

/// Which of `entries` changed since the recorded run `p`, and every key
/// touched (changed, inserted or removed), by `p`'s fingerprints (the
/// change log does not reach back to it); `Err(why)` when they cannot tell.
fn changed_by_fingerprints(
    txn: &ReadTransaction,
    entries: &[KeyEntry],
    p: &RecordedRun,
) -> Result<Changed, String> {
    if let Some(why) = why_not_fingerprints(txn, p) {
        return Err(format!("{why}, and the change log does not reach back to commit {}", p.txn));
    }
    // Keys whose (id, box) differ, are new, or are gone.
    let mut changed = vec![false; entries.len()];
    let mut touched: HashSet<Key> = HashSet::default();
    let (mut i, mut j) = (0, 0);
    while i < entries.len() || j < p.objects.len() {
        match (entries.get(i), p.objects.get(j)) {
            (Some(e), Some(f)) if e.key == f.key => {
                if e.object_id != f.id || e.aabb.to_array() != f.aabb {
                    changed[i] = true;
                    touched.insert(e.key.clone());
                }
                i += 1;
                j += 1;
            }
            (Some(e), Some(f)) if e.key < f.key => {
                changed[i] = true;
                touched.insert(e.key.clone());
                i += 1;
            }
            (Some(e), None) => {
                changed[i] = true;
                touched.insert(e.key.clone());
                i += 1;
            }
            (_, Some(f)) => {
                touched.insert(f.key.clone());
                j += 1;
            }
            (None, None) => break,
        }
    }
    Ok((changed, touched, FoundBy::Fingerprints))
}

/// Changed keys, at most one in this many of the file's objects, are read
/// with their neighbours through the tree rather than by listing the key
/// index (see the module's notes).
pub const FEW: usize = 64;

/// The entries of the keys in `touched` the file still has and of every
/// object whose stored box meets one of theirs grown by `reach` (a level-1
/// box query each), sorted by key, with whether each is a touched one.
fn near_changes(
    txn: &ReadTransaction,
    touched: &HashSet<Key>,
    reach: f64,
) -> Result<(Vec<KeyEntry>, Vec<bool>), ClashError> {
    let mut reads = Reads::new(Some(txn.cache()));
    let mut found: BTreeMap<Key, (KeyEntry, bool)> = BTreeMap::new();
    for key in touched {
        if let Some(e) = txn.key_entry(key, &mut reads)? {
            found.insert(key.clone(), (e, true));
        }
    }
    let grown: Vec<Aabb> = found
        .values()
        .map(|(e, _)| Aabb::new(e.aabb.min - Vector::repeat(reach), e.aabb.max + Vector::repeat(reach)))
        .collect();
    let boxes = QueryOptions { lod: Some(1), ..QueryOptions::default() };
    for g in grown {
        for key in query_region(txn, &Region::Box(g), &boxes, Some(txn.cache()))?.keys {
            if found.contains_key(&key) {
                continue;
            }
            // A key the tree holds and the index lacks is damage the lookup reports.
            let e = txn.key_entry(&key, &mut reads)?.ok_or_else(|| {
                StorageError::Invalid(format!("key {key} is in the tree and not in the key index"))
            })?;
            found.insert(key, (e, false));
        }
    }
    Ok(found.into_values().unzip())
}

/// `p`'s fingerprints with those of `touched` replaced by `now`'s (the
/// touched keys' entries the file still has), in key order.
fn fingerprints_after(p: &RecordedRun, touched: &HashSet<Key>, now: &[KeyEntry]) -> Vec<Fingerprint> {
    let mut fresh = fingerprints(now).into_iter().filter(|f| touched.contains(&f.key)).peekable();
    let mut out = Vec::with_capacity(p.objects.len() + touched.len());
    for f in p.objects.iter().filter(|f| !touched.contains(&f.key)) {
        while let Some(n) = fresh.next_if(|n| n.key < f.key) {
            out.push(n);
        }
        out.push(f.clone());
    }
    out.extend(fresh);
    out
}

/// Runs `test` on `txn` against `previous` (the recorded run of the same
/// test): incrementally when it can (see the module's notes), else in
/// full. With `incremental` false, always in full. Statuses are updated.
pub fn rerun(
    txn: &ReadTransaction,
    test: &ClashTest,
    previous: Option<&RecordedRun>,
    incremental: bool,
) -> Result<(Recorded, RecordedRun), ClashError> {
    rerun_by(txn, test, previous, incremental, FEW)
}

/// [`rerun`], reading the changed objects' neighbours through the tree
/// when the log's keys are at most one in `few` of the objects.
fn rerun_by(
    txn: &ReadTransaction,
    test: &ClashTest,
    previous: Option<&RecordedRun>,
    incremental: bool,
    few: usize,
) -> Result<(Recorded, RecordedRun), ClashError> {
    let started = Instant::now();
    test.validate()?;
    let why = if incremental { why_full(txn, test, previous) } else { Some("asked for a full run".into()) };
    let txn_now = txn.txn();
    let objects = txn.info().map_or(0, |i| i.objects as usize);
    // What the log says changed, when this run may be incremental and the
    // log reaches back to the recorded run.
    let logged = match (&why, previous) {
        (None, Some(p)) => txn.changes_since(p.txn)?.map(|c| (p, c)),
        _ => None,
    };
    let (entries, seed) = match logged {
        Some((p, changes)) => {
            let touched: HashSet<Key> = changes.into_iter().map(|c| c.key).collect();
            let (entries, changed) = if touched.len() <= objects / few {
                near_changes(txn, &touched, test.reach())?
            } else {
                let entries = txn.key_entries(&mut Reads::new(Some(txn.cache())))?;
                let changed = entries.iter().map(|e| touched.contains(&e.key)).collect();
                (entries, changed)
            };
            (entries, Ok((p, (changed, touched, FoundBy::Log))))
        }
        None => {
            let entries = txn.key_entries(&mut Reads::new(Some(txn.cache())))?;
            let seed = match (why, previous) {
                (None, Some(p)) => changed_by_fingerprints(txn, &entries, p).map(|c| (p, c)),
                (why, _) => Err(why.unwrap_or_default()),
            };
            (entries, seed)
        }
    };
    let listed_all = entries.len() == objects;
    let (tracked, mut stats, mode, fingerprinted) = match seed {
        Ok((p, (changed, touched, by))) => {
            let n_changed = changed.iter().filter(|&&c| c).count();
            // Keys the recorded run had and the file no longer has.
            let removed = touched
                .iter()
                .filter(|&k| {
                    p.objects.binary_search_by(|f| f.key.cmp(k)).is_ok()
                        && entries.binary_search_by(|e| e.key.cmp(k)).is_err()
                })
                .count();
            let (mut fresh, stats) = run_on(txn, test, &entries, Some(&changed), started)?;
            sort(&mut fresh);
            // The recorded clashes between unchanged objects stand: found
            // again as they were, in place in the merge, not copied out.
            let kept = |t: &Tracked| {
                t.status != Status::Resolved
                    && t.last_txn == p.txn
                    && !touched.contains(&t.clash.a)
                    && !touched.contains(&t.clash.b)
            };
            let (tracked, n_kept) = merge(&p.tracked, fresh, kept, txn_now);
            let fingerprinted =
                if listed_all { fingerprints(&entries) } else { fingerprints_after(p, &touched, &entries) };
            (
                tracked,
                stats,
                RunMode::Incremental { by, changed: n_changed, removed, kept: n_kept },
                fingerprinted,
            )
        }
        Err(why) => {
            let (c, s) = run_on(txn, test, &entries, None, started)?;
            let (tracked, _) = merge(previous.map_or(&[][..], |p| &p.tracked), c, |_| false, txn_now);
            (tracked, s, RunMode::Full { why }, fingerprints(&entries))
        }
    };
    stats.objects = objects;
    stats.seconds = started.elapsed().as_secs_f64();
    let record = RecordedRun {
        txn: txn_now,
        test: test.clone(),
        tracked,
        object_ids: txn.object_ids(),
        build: txn.info().map_or(0, |i| i.build_seconds.to_bits()),
        objects: fingerprinted,
    };
    Ok((Recorded { txn: txn_now, stats, mode }, record))
}

/// Runs the test `name` of `store` (saved, or `test` when given: it is
/// saved under `name` then) on `txn`, incrementally when it can, and
/// records the run and its statuses in `store` (the caller saves it).
pub fn run_recorded(
    txn: &ReadTransaction,
    store: &mut ClashStore,
    name: &str,
    test: Option<&ClashTest>,
    incremental: bool,
) -> Result<Recorded, ClashError> {
    if name.is_empty() || name.len() > super::test::MAX_NAME {
        return Err(ClashError::Test(format!("a test name of {} bytes (1 ..= 255)", name.len())));
    }
    let test = match test {
        Some(t) => {
            let group = store.tests.get(name).map_or(GroupBy::None, |s| s.group);
            store.tests.insert(name.to_string(), SavedTest { test: t.clone(), group });
            t.clone()
        }
        None => store
            .tests
            .get(name)
            .map(|s| s.test.clone())
            .ok_or_else(|| ClashError::NotFound(format!("no saved test named {name:?}")))?,
    };
    let (recorded, record) = rerun(txn, &test, store.runs.get(name), incremental)?;
    store.runs.insert(name.to_string(), record);
    Ok(recorded)
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use super::*;
    use crate::clash::run_test;
    use crate::clash::test::TestKind;
    use crate::db::Database;
    use crate::scene::{Mesh, Object, Scene};
    use crate::store::device::MemDevice;
    use proptest::prelude::*;

    /// A box on a 50 mm grid, 30 mm past its cells (so boxes overlap, touch
    /// or lie 20 mm apart), named so that half are pipes.
    fn cell(k: u64, at: [u8; 3], size: u8) -> Object {
        let lo = at.map(|x| f64::from(x) * 50.0);
        let hi = lo.map(|x| x + f64::from(size) * 50.0 + 30.0);
        let mesh = Mesh::of_box(&Aabb::new(lo.into(), hi.into())).unwrap();
        Object::new(if k.is_multiple_of(2) { "PIPE" } else { "WALL" }, mesh).with_key(Key::Int(k))
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 32, ..ProptestConfig::default() })]

        /// A re-run after logged changes gives a full run's clashes and
        /// the fingerprints a listing would, whether it reads the changed
        /// objects' neighbours through the tree (`few` 1) or lists the
        /// index (`few` past any count of objects).
        #[test]
        fn neighbours_through_the_tree_give_a_full_runs_clashes(
            start in prop::collection::vec((prop::array::uniform3(0u8..10), 1u8..4), 8..40),
            moves in prop::collection::vec((any::<prop::sample::Index>(), prop::array::uniform3(0u8..10), 1u8..4, any::<bool>()), 1..6),
            through_tree in any::<bool>(),
            pipes_against_walls in any::<bool>(),
        ) {
            let scene = Scene::new(start.iter().enumerate().map(|(k, &(at, s))| cell(k as u64, at, s)).collect());
            let db = Database::create_on(Arc::new(MemDevice::new()), Default::default()).unwrap();
            let mut w = db.begin_write().unwrap();
            w.bulk_load(&scene, &Default::default(), &|_| {}).unwrap();
            w.commit().unwrap();
            let test = if pipes_against_walls {
                ClashTest {
                    a: vec!["name:PIPE".parse().unwrap()],
                    b: Some(vec!["name:WALL".parse().unwrap()]),
                    kind: TestKind::Hard,
                    touch: true,
                    ..Default::default()
                }
            } else {
                ClashTest { kind: TestKind::Clearance, distance: 30.0, touch: true, ..Default::default() }
            };
            let few = if through_tree { 1 } else { usize::MAX };
            let (_, record) = rerun_by(&db.begin_read().unwrap(), &test, None, true, few).unwrap();
            let mut w = db.begin_write().unwrap();
            for (i, at, s, remove) in moves {
                let k = i.index(start.len()) as u64;
                if remove {
                    w.remove(&Key::Int(k)).unwrap();
                } else if w.object(&Key::Int(k)).unwrap().is_some() {
                    w.update(cell(k, at, s)).unwrap();
                } else {
                    w.insert(cell(k, at, s)).unwrap();
                }
            }
            w.commit().unwrap();
            let r = db.begin_read().unwrap();
            let (rec, next) = rerun_by(&r, &test, Some(&record), true, few).unwrap();
            prop_assert!(matches!(rec.mode, RunMode::Incremental { by: FoundBy::Log, .. }), "{:?}", rec.mode);
            prop_assert!(through_tree || rec.stats.listed == rec.stats.objects);
            let got: Vec<_> = next.clashes().cloned().collect();
            prop_assert_eq!(got, run_test(&r, &test).unwrap().clashes);
            let listed = r.key_entries(&mut Reads::new(None)).unwrap();
            prop_assert_eq!(&next.objects, &fingerprints(&listed));
            prop_assert_eq!(next.txn, r.txn());
        }
    }
}
