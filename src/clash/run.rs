//! Running a clash test on a snapshot (docs/clash.md, "How a run works"):
//! the key index is read once for every object's key, name, payload and
//! exact box; the sets are chosen by their selectors; candidate pairs are
//! the boxes within the test's reach of one another (a sweep along x);
//! the meshes of the objects in a candidate pair are read in one walk of
//! the tree, each once; then each pair is measured (`geom::solid`) on
//! every core. The answer is a function of the pairs' meshes and the
//! test, so any subset of pairs measured again gives the same clashes:
//! what the incremental re-run relies on.

use std::collections::HashSet;
use std::time::Instant;

use rayon::prelude::*;
use serde::Serialize;

use super::ClashError;
use super::select::{Candidate, Selector, in_set};
use super::test::{Clash, ClashKind, ClashTest, TestKind};
use crate::db::ReadTransaction;
use crate::geom::{Aabb, Point, closest, overlap, same_within};
use crate::query::fetch_meshes;
use crate::scene::{Key, ObjectId};
use crate::store::format::keys::KeyEntry;

/// What a run did and how long each step took.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct RunStats {
    /// Objects in the file.
    pub objects: usize,
    /// Objects in set A.
    pub in_a: usize,
    /// Objects in set B (A's when the test has no B).
    pub in_b: usize,
    /// Pairs whose boxes lie within the test's reach.
    pub candidates: usize,
    /// Objects whose meshes were read.
    pub meshes_read: usize,
    /// Seconds listing the key index and choosing the sets.
    pub list_seconds: f64,
    /// Seconds reading meshes.
    pub read_seconds: f64,
    /// Seconds measuring pairs.
    pub measure_seconds: f64,
    /// Seconds in all.
    pub seconds: f64,
}

/// A run's clashes, sorted by (a, b, type), on the commit it read.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ClashRun {
    /// The commit the run read ([`ReadTransaction::txn`]).
    pub txn: u64,
    /// The clashes, sorted by (a, b, type).
    pub clashes: Vec<Clash>,
    /// What the run did.
    pub stats: RunStats,
}

/// Runs `test` on the snapshot `txn`.
pub fn run_test(txn: &ReadTransaction, test: &ClashTest) -> Result<ClashRun, ClashError> {
    let started = Instant::now();
    test.validate()?;
    let entries = txn.key_entries(&mut crate::db::Reads::new(Some(txn.cache())))?;
    let (clashes, mut stats) = run_on(txn, test, &entries, None, started)?;
    stats.seconds = started.elapsed().as_secs_f64();
    Ok(ClashRun { txn: txn.txn(), clashes, stats })
}

/// Which objects of `entries` lie in set A and in set B.
pub(crate) fn membership(test: &ClashTest, entries: &[KeyEntry]) -> (Vec<bool>, Vec<bool>) {
    let reads = |s: &[Selector]| s.iter().any(Selector::reads_payload);
    let parse = reads(&test.a) || test.b.as_deref().is_some_and(reads);
    let mut in_a = Vec::with_capacity(entries.len());
    let mut in_b = Vec::with_capacity(entries.len());
    for e in entries {
        let payload = if parse { serde_json::from_slice::<serde_json::Value>(&e.payload).ok() } else { None };
        let c = Candidate { key: &e.key, name: &e.name, payload: payload.as_ref() };
        let a = in_set(&test.a, &c);
        in_a.push(a);
        in_b.push(match &test.b {
            Some(b) => in_set(b, &c),
            None => a,
        });
    }
    (in_a, in_b)
}

/// The pairs (i, j) of `entries` a test may find a clash in, i from A and
/// j from B (both in both: the smaller key first), boxes within `reach`;
/// with `changed`, only pairs with a changed object.
pub(crate) fn candidates(
    entries: &[KeyEntry],
    in_a: &[bool],
    in_b: &[bool],
    reach: f64,
    changed: Option<&[bool]>,
) -> Vec<(usize, usize)> {
    let mut order: Vec<usize> = (0..entries.len()).filter(|&i| in_a[i] || in_b[i]).collect();
    order.sort_by(|&x, &y| entries[x].aabb.min.x.total_cmp(&entries[y].aabb.min.x));
    let mut out = Vec::new();
    for (n, &i) in order.iter().enumerate() {
        let bi = &entries[i].aabb;
        for &j in &order[n + 1..] {
            let bj = &entries[j].aabb;
            if bj.min.x > bi.max.x + reach {
                break;
            }
            if let Some(c) = changed
                && !c[i]
                && !c[j]
            {
                continue;
            }
            if !bi.within(bj, reach) {
                continue;
            }
            let (ij, ji) = (in_a[i] && in_b[j], in_a[j] && in_b[i]);
            let pair = match (ij, ji) {
                (true, true) if entries[j].key < entries[i].key => (j, i),
                (true, _) => (i, j),
                (false, true) => (j, i),
                (false, false) => continue,
            };
            out.push(pair);
        }
    }
    out
}

/// Runs `test` over `entries` (the snapshot's key index): every candidate
/// pair, or with `changed` those with a changed object.
pub(crate) fn run_on(
    txn: &ReadTransaction,
    test: &ClashTest,
    entries: &[KeyEntry],
    changed: Option<&[bool]>,
    started: Instant,
) -> Result<(Vec<Clash>, RunStats), ClashError> {
    let (in_a, in_b) = membership(test, entries);
    let pairs = candidates(entries, &in_a, &in_b, test.reach(), changed);
    let mut stats = RunStats {
        objects: entries.len(),
        in_a: in_a.iter().filter(|&&x| x).count(),
        in_b: in_b.iter().filter(|&&x| x).count(),
        candidates: pairs.len(),
        list_seconds: started.elapsed().as_secs_f64(),
        ..Default::default()
    };
    let t = Instant::now();
    let wanted: HashSet<ObjectId> =
        pairs.iter().flat_map(|&(i, j)| [i, j]).map(|i| ObjectId(entries[i].object_id)).collect();
    stats.meshes_read = wanted.len();
    let meshes = fetch_meshes(txn, wanted)?;
    let triangles: std::collections::HashMap<ObjectId, Vec<[Point; 3]>> =
        meshes.into_iter().map(|(id, m)| (id, m.triangle_points().collect())).collect();
    stats.read_seconds = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let mut clashes = pairs
        .par_iter()
        .map(|&(i, j)| {
            let (ea, eb) = (&entries[i], &entries[j]);
            let mesh = |e: &KeyEntry| {
                triangles.get(&ObjectId(e.object_id)).ok_or_else(|| {
                    ClashError::Storage(crate::store::StorageError::Invalid(format!(
                        "the key index names object {} (key {}), which the tree does not hold",
                        e.object_id, e.key
                    )))
                })
            };
            Ok(measure(test, (&ea.key, &ea.aabb, mesh(ea)?), (&eb.key, &eb.aabb, mesh(eb)?)))
        })
        .collect::<Result<Vec<Option<Clash>>, ClashError>>()?
        .into_iter()
        .flatten()
        .collect::<Vec<Clash>>();
    sort(&mut clashes);
    stats.measure_seconds = t.elapsed().as_secs_f64();
    Ok((clashes, stats))
}

/// Sorts clashes by (a, b, type): the order every run gives.
pub(crate) fn sort(clashes: &mut [Clash]) {
    clashes.sort_by(|x, y| (&x.a, &x.b, x.kind).cmp(&(&y.a, &y.b, y.kind)));
}

/// Distances within this share of the pair's largest coordinate of a
/// clearance test's d are taken as d (not below it): parry's distances
/// carry rounding of a few ulps of the coordinates.
pub const AT_D: f64 = 1e-12;

/// The clash test `test` finds between a and b (key, exact box, triangles), if any.
pub fn measure(
    test: &ClashTest,
    (ka, ba, ta): (&Key, &Aabb, &[[Point; 3]]),
    (kb, bb, tb): (&Key, &Aabb, &[[Point; 3]]),
) -> Option<Clash> {
    let clash = |kind, depth, distance, point, closest, overlap| Clash {
        a: ka.clone(),
        b: kb.clone(),
        kind,
        depth,
        distance,
        point,
        closest,
        overlap,
        a_box: *ba,
        b_box: *bb,
    };
    if test.kind == TestKind::Duplicate {
        return same_within(ta, tb, test.tolerance)
            .then(|| clash(ClashKind::Duplicate, 0.0, 0.0, ba.center(), None, None));
    }
    let o = overlap(ta, tb);
    if o.contact {
        let depth = o.depth();
        let kind = if depth > test.tolerance {
            ClashKind::Hard
        } else if test.touch {
            ClashKind::Touch
        } else {
            return None;
        };
        return Some(clash(kind, depth, 0.0, o.region.center(), None, Some(o.region)));
    }
    if test.kind == TestKind::Clearance {
        // Distances are floating point: a gap of exactly d measures within
        // a few ulps of the coordinates either side of it, and counts as d.
        let scale = ba.to_array().iter().chain(&bb.to_array()).fold(1.0f64, |m, x| m.max(x.abs()));
        let (d, p, q) = closest(ta, tb, test.distance - AT_D * scale)?;
        return Some(clash(ClashKind::Clearance, 0.0, d, nalgebra::center(&p, &q), Some([p, q]), None));
    }
    None
}
