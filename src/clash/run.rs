//! Running a clash test on a snapshot (docs/clash.md, "How a run works"):
//! the key index is read once for every object's key, name, payload and
//! exact box; the sets are chosen by their selectors; candidate pairs are
//! the boxes within the test's reach of one another (a sweep along the axis
//! where it checks the fewest pairs);
//! the pairs are measured (`geom::solid`) a chunk at a time in the sweep's
//! order, on every core, each object's mesh read through its key entry's
//! path when a chunk first names it and dropped after the last chunk that
//! does, so a run holds the meshes its sweep spans, not every candidate's.
//! The answer is a function of the pairs' meshes and the
//! test, so any subset of pairs measured again gives the same clashes:
//! what the incremental re-run relies on.

use std::collections::HashMap;
use std::time::Instant;

use rayon::prelude::*;
use serde::Serialize;

use super::ClashError;
use super::select::{Candidate, Selector, in_set};
use super::test::{Clash, ClashKind, ClashTest, TestKind};
use crate::db::{ReadTransaction, Reads};
use crate::geom::{Aabb, Point, closest, overlap, same_within};
use crate::scene::Key;
use crate::store::format::keys::KeyEntry;

/// What a run did and how long each step took.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct RunStats {
    /// Objects in the file.
    pub objects: usize,
    /// Key entries the run read: every object's, or for a re-run after a
    /// few logged changes, the changed objects' and their neighbours'.
    pub listed: usize,
    /// Objects in set A, of those listed.
    pub in_a: usize,
    /// Objects in set B (A's when the test has no B), of those listed.
    pub in_b: usize,
    /// Pairs whose boxes lie within the test's reach.
    pub candidates: usize,
    /// Objects whose meshes were read (each once).
    pub meshes_read: usize,
    /// The most objects' meshes held at once.
    pub peak_meshes: usize,
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
    // On every core: with payload selectors, each object's payload is
    // parsed (a re-run of 50,288 IFC objects spent 15% of its time here).
    entries
        .par_iter()
        .map(|e| {
            let payload =
                if parse { serde_json::from_slice::<serde_json::Value>(&e.payload).ok() } else { None };
            let c = Candidate { key: &e.key, name: &e.name, payload: payload.as_ref() };
            let a = in_set(&test.a, &c);
            (a, test.b.as_ref().map_or(a, |b| in_set(b, &c)))
        })
        .unzip()
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
    candidates_by(entries, in_a, in_b, reach, changed, FEW_CHANGES)
}

/// The test's objects sorted by their boxes' lower ends along the axis
/// whose sweep checks the fewest pairs, with that axis. A sweep checks,
/// for each box, the later ones that begin within reach of its upper end:
/// along x in a building, every box after a slab that spans it in x, a
/// handful along z. The count per axis is exact (a binary search per box
/// in that axis's order), so the choice costs two more sorts (on every core), not a sweep.
fn sweep_order(entries: &[KeyEntry], members: Vec<usize>, reach: f64) -> (usize, Vec<usize>) {
    let mut best: Option<(u64, usize, Vec<usize>)> = None;
    for axis in 0..3 {
        let mut order = members.clone();
        order.par_sort_by(|&x, &y| entries[x].aabb.min[axis].total_cmp(&entries[y].aabb.min[axis]));
        let lows: Vec<f64> = order.iter().map(|&i| entries[i].aabb.min[axis]).collect();
        let checks: u64 = order
            .iter()
            .enumerate()
            .map(|(n, &i)| {
                let end = entries[i].aabb.max[axis] + reach;
                (lows.partition_point(|&l| l <= end).max(n + 1) - n - 1) as u64
            })
            .sum();
        if best.as_ref().is_none_or(|b| checks < b.0) {
            best = Some((checks, axis, order));
        }
    }
    best.map_or((0, Vec::new()), |(_, axis, order)| (axis, order))
}

/// [`candidates`], sweeping from the changed objects alone when they are
/// at most one in `few` of the test's objects (along x), else sweeping
/// them all along [`sweep_order`]'s axis.
fn candidates_by(
    entries: &[KeyEntry],
    in_a: &[bool],
    in_b: &[bool],
    reach: f64,
    changed: Option<&[bool]>,
    few: usize,
) -> Vec<(usize, usize)> {
    let members: Vec<usize> = (0..entries.len()).filter(|&i| in_a[i] || in_b[i]).collect();
    let changes = changed.map(|c| members.iter().filter(|&&i| c[i]).count());
    let few_changes = changed.filter(|_| changes.is_some_and(|n| n <= members.len() / few));
    // From a few changed objects, the walks are short along any axis: the
    // one sort along x; for the whole sweep, the axis of fewest checks.
    let (axis, order) = match few_changes {
        Some(_) => {
            let mut order = members;
            order.par_sort_by(|&x, &y| entries[x].aabb.min.x.total_cmp(&entries[y].aabb.min.x));
            (0, order)
        }
        None => sweep_order(entries, members, reach),
    };
    let pair = |i: usize, j: usize| -> Option<(usize, usize)> {
        if !entries[i].aabb.within(&entries[j].aabb, reach) {
            return None;
        }
        match (in_a[i] && in_b[j], in_a[j] && in_b[i]) {
            (true, true) if entries[j].key < entries[i].key => Some((j, i)),
            (true, _) => Some((i, j)),
            (false, true) => Some((j, i)),
            (false, false) => None,
        }
    };
    // The sweep from the n-th object of `order` on: the later objects whose
    // boxes begin within reach of its end; with `only`, pairs with a change.
    let later = |n: usize, only: Option<&[bool]>, out: &mut Vec<(usize, usize)>| {
        let i = order[n];
        let end = entries[i].aabb.max[axis] + reach;
        for &j in order[n + 1..].iter().take_while(|&&j| entries[j].aabb.min[axis] <= end) {
            if only.is_none_or(|c| c[i] || c[j]) {
                out.extend(pair(i, j));
            }
        }
    };
    let mut out = Vec::new();
    let Some(changed) = few_changes else {
        // Everything, or so many changes that a walk back from each could
        // cost more than the sweep (a long box early in the order is
        // reached from every later one): the sweep.
        (0..order.len()).for_each(|n| later(n, changed, &mut out));
        return out;
    };
    // From each changed object only, so a re-run after a few changes does
    // not sweep every object: forward as the sweep, and back over the
    // earlier objects while any of them still ends within reach (the
    // running largest end), skipping changed ones, whose own forward
    // sweep finds the pair.
    let mut reach_back = Vec::with_capacity(order.len());
    let mut furthest = f64::NEG_INFINITY;
    for &i in &order {
        furthest = furthest.max(entries[i].aabb.max.x);
        reach_back.push(furthest);
    }
    for (n, &i) in order.iter().enumerate().filter(|&(_, &i)| changed[i]) {
        later(n, None, &mut out);
        let start = entries[i].aabb.min.x - reach;
        for m in (0..n).rev().take_while(|&m| reach_back[m] >= start) {
            let k = order[m];
            if !changed[k] {
                out.extend(pair(k, i));
            }
        }
    }
    out
}

/// Changed objects, at most one in this many of a test's objects, are
/// swept from alone; more, and the whole sweep runs.
const FEW_CHANGES: usize = 64;

/// Runs `test` over `entries` (the snapshot's key index): every candidate
/// pair, or with `changed` those with a changed object.
pub(crate) fn run_on(
    txn: &ReadTransaction,
    test: &ClashTest,
    entries: &[KeyEntry],
    changed: Option<&[bool]>,
    started: Instant,
) -> Result<(Vec<Clash>, RunStats), ClashError> {
    run_chunked(txn, test, entries, changed, started, CHUNK_PAIRS)
}

/// [`run_on`], measuring `chunk` pairs at a time.
fn run_chunked(
    txn: &ReadTransaction,
    test: &ClashTest,
    entries: &[KeyEntry],
    changed: Option<&[bool]>,
    started: Instant,
    chunk: usize,
) -> Result<(Vec<Clash>, RunStats), ClashError> {
    let chunk = chunk.max(1);
    let (in_a, in_b) = membership(test, entries);
    let pairs = candidates(entries, &in_a, &in_b, test.reach(), changed);
    let mut stats = RunStats {
        objects: entries.len(),
        listed: entries.len(),
        in_a: in_a.iter().filter(|&&x| x).count(),
        in_b: in_b.iter().filter(|&&x| x).count(),
        candidates: pairs.len(),
        list_seconds: started.elapsed().as_secs_f64(),
        ..Default::default()
    };
    // Pairs are measured a chunk at a time, in the sweep's order: an
    // object's triangles are read for the first chunk that names it and
    // dropped after the last, so each is read once and a run holds about
    // the objects its sweep spans, not every candidate's.
    let last = last_chunks(&pairs, chunk, entries.len());
    let mut held: HashMap<usize, Vec<[Point; 3]>> = HashMap::new();
    let mut clashes = Vec::new();
    for (c, part) in pairs.chunks(chunk).enumerate() {
        held.retain(|&o, _| last[o] >= c);
        let t = Instant::now();
        read_missing(txn, entries, part, &mut held, &mut stats)?;
        stats.read_seconds += t.elapsed().as_secs_f64();
        let t = Instant::now();
        let held = &held;
        clashes.par_extend(part.par_iter().filter_map(|&(i, j)| {
            let (ea, eb) = (&entries[i], &entries[j]);
            measure(test, (&ea.key, &ea.aabb, &held[&i]), (&eb.key, &eb.aabb, &held[&j]))
        }));
        stats.measure_seconds += t.elapsed().as_secs_f64();
    }
    let t = Instant::now();
    sort(&mut clashes);
    stats.measure_seconds += t.elapsed().as_secs_f64();
    Ok((clashes, stats))
}

/// Candidate pairs measured at a time: the meshes a run holds are those of
/// one chunk's pairs and of the objects a later chunk still needs.
const CHUNK_PAIRS: usize = 1 << 14;

/// Per object (entry index, `objects` of them): the last chunk of `size`
/// pairs of `pairs` that names it (0 for one no pair names).
fn last_chunks(pairs: &[(usize, usize)], size: usize, objects: usize) -> Vec<usize> {
    let mut last = vec![0; objects];
    for (n, &(i, j)) in pairs.iter().enumerate() {
        last[i] = n / size;
        last[j] = n / size;
    }
    last
}

/// Reads the triangles of the objects `pairs` name that `held` lacks (on
/// every core, each through its own reads and the snapshot's shared cache).
fn read_missing(
    txn: &ReadTransaction,
    entries: &[KeyEntry],
    pairs: &[(usize, usize)],
    held: &mut HashMap<usize, Vec<[Point; 3]>>,
    stats: &mut RunStats,
) -> Result<(), ClashError> {
    let mut missing: Vec<usize> =
        pairs.iter().flat_map(|&(i, j)| [i, j]).filter(|o| !held.contains_key(o)).collect();
    missing.sort_unstable();
    missing.dedup();
    let read: Vec<(usize, Vec<[Point; 3]>)> = missing
        .par_iter()
        .map_init(
            || Reads::new(Some(txn.cache())),
            |reads, &o| {
                let mesh = txn.mesh_of_entry(&entries[o], reads)?;
                Ok((o, mesh.triangle_points().collect()))
            },
        )
        .collect::<Result<_, ClashError>>()?;
    stats.meshes_read += read.len();
    held.extend(read);
    stats.peak_meshes = stats.peak_meshes.max(held.len());
    Ok(())
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

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use super::*;
    use crate::db::{Database, Reads};
    use crate::scene::generate::{GenOptions, Preset, generate_scene};
    use crate::store::device::MemDevice;
    use proptest::prelude::*;

    #[test]
    fn chunks_of_any_size_find_the_same_clashes_reading_each_mesh_once() {
        let scene = generate_scene(&GenOptions { preset: Preset::Tanker1, objects: None, seed: 3 }).unwrap();
        let db = Database::create_on(Arc::new(MemDevice::new()), Default::default()).unwrap();
        let mut w = db.begin_write().unwrap();
        w.bulk_load(&scene, &Default::default(), &|_| {}).unwrap();
        w.commit().unwrap();
        let r = db.begin_read().unwrap();
        let entries = r.key_entries(&mut Reads::new(None)).unwrap();
        let test = ClashTest { kind: TestKind::Clearance, distance: 50.0, touch: true, ..Default::default() };
        let run = |chunk| run_chunked(&r, &test, &entries, None, Instant::now(), chunk).unwrap();
        let (whole, ws) = run(usize::MAX);
        assert!(
            ws.candidates > 1000 && whole.len() > 100,
            "{} pairs, {} clashes",
            ws.candidates,
            whole.len()
        );
        for chunk in [1, 7, 500] {
            let (clashes, s) = run(chunk);
            assert_eq!(clashes, whole, "chunks of {chunk}");
            assert_eq!(s.meshes_read, ws.meshes_read, "each mesh once, chunks of {chunk}");
            assert!(
                s.peak_meshes < ws.peak_meshes,
                "chunks of {chunk} hold {} of {}",
                s.peak_meshes,
                ws.peak_meshes
            );
        }
    }

    /// Boxes long along x (slabs spanning a building), stacked along z:
    /// the sweep takes z, where each box meets only its own storey.
    #[test]
    fn the_sweep_takes_the_axis_of_fewest_checks() {
        let entries: Vec<KeyEntry> = (0..40)
            .map(|n| {
                let (x, z) = (f64::from(n % 4), f64::from(n / 4) * 10.0);
                entry(n, Aabb::new(Point::new(x, 0.0, z), Point::new(x + 100.0, 100.0, z + 1.0)))
            })
            .collect();
        let (axis, order) = sweep_order(&entries, (0..40).collect(), 0.5);
        assert_eq!(axis, 2);
        assert!(order.windows(2).all(|w| entries[w[0]].aabb.min.z <= entries[w[1]].aabb.min.z));
    }

    fn entry(n: u32, aabb: Aabb) -> KeyEntry {
        KeyEntry {
            key: Key::Int(u64::from(n) * 7 % 61),
            payload: Vec::new(),
            name: String::new(),
            object_id: n,
            path: Default::default(),
            aabb,
        }
    }

    proptest! {
        /// The sweep's pairs are every pair of boxes within reach, with A's
        /// object first (the smaller key when both are in both sets), each
        /// once, whichever axis the sweep takes: boxes long along any axis.
        #[test]
        fn the_sweep_finds_every_pair_within_reach(
            boxes in proptest::collection::vec(
                (proptest::array::uniform3(0.0..100.0f64), proptest::array::uniform3(0.0..8.0f64), 0usize..3, 0u8..4),
                0..60,
            ),
            reach in 0.0..5.0f64,
        ) {
            let entries: Vec<KeyEntry> = boxes.iter().enumerate().map(|(n, &(lo, size, long, _))| {
                let mut hi = [lo[0] + size[0], lo[1] + size[1], lo[2] + size[2]];
                hi[long] += 60.0;
                entry(n as u32, Aabb::new(Point::from(lo), Point::from(hi)))
            }).collect();
            let in_a: Vec<bool> = boxes.iter().map(|b| b.3 & 1 == 1).collect();
            let in_b: Vec<bool> = boxes.iter().map(|b| b.3 & 2 == 2 || b.3 == 0).collect();
            let mut brute = Vec::new();
            for i in 0..entries.len() {
                for j in i + 1..entries.len() {
                    if !entries[i].aabb.within(&entries[j].aabb, reach) {
                        continue;
                    }
                    let (ij, ji) = (in_a[i] && in_b[j], in_a[j] && in_b[i]);
                    brute.extend(match (ij, ji) {
                        (true, true) if entries[j].key < entries[i].key => Some((j, i)),
                        (true, true) => Some((i, j)),
                        (true, false) => Some((i, j)),
                        (false, true) => Some((j, i)),
                        (false, false) => None,
                    });
                }
            }
            brute.sort_unstable();
            let mut swept = candidates(&entries, &in_a, &in_b, reach, None);
            swept.sort_unstable();
            prop_assert_eq!(swept, brute);
        }

        /// Candidates from the changed objects only, or from the whole
        /// sweep kept to them, are exactly the full sweep's pairs that name
        /// a changed object, whatever the boxes
        /// (long ones that reach far back in the sweep included), the sets
        /// and the reach.
        #[test]
        fn changed_candidates_are_the_sweeps_pairs_with_a_change(
            boxes in proptest::collection::vec((0.0..100.0f64, 0.0..100.0f64, 0.0..60.0f64, 0.0..60.0f64, 0u8..4, any::<bool>()), 0..60),
            reach in 0.0..5.0f64,
        ) {
            let entries: Vec<KeyEntry> = boxes.iter().enumerate().map(|(n, &(x, y, w, h, _, _))| KeyEntry {
                key: Key::Int(n as u64 * 7 % 61),
                payload: Vec::new(),
                name: String::new(),
                object_id: n as u32,
                path: Default::default(),
                aabb: Aabb::new(Point::new(x, y, 0.0), Point::new(x + w, y + h / 4.0, 1.0)),
            }).collect();
            let in_a: Vec<bool> = boxes.iter().map(|b| b.4 & 1 == 1).collect();
            let in_b: Vec<bool> = boxes.iter().map(|b| b.4 & 2 == 2 || b.4 == 0).collect();
            let changed: Vec<bool> = boxes.iter().map(|b| b.5).collect();
            let mut all = candidates(&entries, &in_a, &in_b, reach, None);
            all.retain(|&(i, j)| changed[i] || changed[j]);
            all.sort_unstable();
            // From the changed objects alone (any share of them), and the whole sweep kept to them.
            for few in [1, usize::MAX] {
                let mut some = candidates_by(&entries, &in_a, &in_b, reach, Some(&changed), few);
                some.sort_unstable();
                prop_assert_eq!(&some, &all, "few = {}", few);
            }
        }
    }
}
