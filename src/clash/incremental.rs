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

use rustc_hash::FxHashSet as HashSet;
use std::time::Instant;

use serde::Serialize;

use super::ClashError;
use super::group::GroupBy;
use super::run::{RunStats, run_on, sort};
use super::status::{Status, Tracked, merge};
use super::store::{ClashStore, Fingerprint, RecordedRun, SavedTest};
use super::test::ClashTest;
use crate::db::ReadTransaction;
use crate::scene::Key;
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
/// touched (changed, inserted or removed); `Err(why)` when neither the
/// change log nor the fingerprints can tell.
fn changed_since(
    txn: &ReadTransaction,
    entries: &[KeyEntry],
    p: &RecordedRun,
) -> Result<Result<Changed, String>, ClashError> {
    if let Some(logged) = txn.changes_since(p.txn)? {
        let touched: HashSet<Key> = logged.into_iter().map(|c| c.key).collect();
        let changed = entries.iter().map(|e| touched.contains(&e.key)).collect();
        return Ok(Ok((changed, touched, FoundBy::Log)));
    }
    if let Some(why) = why_not_fingerprints(txn, p) {
        return Ok(Err(format!("{why}, and the change log does not reach back to commit {}", p.txn)));
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
    Ok(Ok((changed, touched, FoundBy::Fingerprints)))
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
    let started = Instant::now();
    test.validate()?;
    let entries = txn.key_entries(&mut crate::db::Reads::new(Some(txn.cache())))?;
    let why = if incremental { why_full(txn, test, previous) } else { Some("asked for a full run".into()) };
    let txn_now = txn.txn();
    let seed = match (why, previous) {
        (None, Some(p)) => changed_since(txn, &entries, p)?.map(|c| (p, c)),
        (why, _) => Err(why.unwrap_or_default()),
    };
    let (tracked, mut stats, mode) = match seed {
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
            (tracked, stats, RunMode::Incremental { by, changed: n_changed, removed, kept: n_kept })
        }
        Err(why) => {
            let (c, s) = run_on(txn, test, &entries, None, started)?;
            let (tracked, _) = merge(previous.map_or(&[][..], |p| &p.tracked), c, |_| false, txn_now);
            (tracked, s, RunMode::Full { why })
        }
    };
    stats.seconds = started.elapsed().as_secs_f64();
    let record = RecordedRun {
        txn: txn_now,
        test: test.clone(),
        tracked,
        object_ids: txn.object_ids(),
        build: txn.info().map_or(0, |i| i.build_seconds.to_bits()),
        objects: fingerprints(&entries),
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
