//! Clash statuses across revisions (docs/clash.md, "Statuses"), as
//! Navisworks' Clash Detective keeps them: a run is recorded against the
//! commit it read; the next run marks each clash, by its keys and type,
//! New (not in the last run), Active (in it, and in this one) or Resolved
//! (in the last run, gone from this one). Reviewed and Approved, which a
//! person sets, persist while the clash does; a clash that comes back
//! after being resolved is New again.

use std::borrow::Cow;

use serde::{Deserialize, Serialize};

use super::test::{Clash, ClashKind};
use crate::scene::Key;

/// A clash's status.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Status {
    /// Found in this run and not in the last.
    New,
    /// Found in the last run and in this one.
    Active,
    /// A person looked at it; kept while the clash persists.
    Reviewed,
    /// A person accepted it; kept while the clash persists.
    Approved,
    /// Found in an earlier run, gone from the last one.
    Resolved,
}

impl Status {
    /// The lowercase name.
    pub fn name(self) -> &'static str {
        match self {
            Status::New => "new",
            Status::Active => "active",
            Status::Reviewed => "reviewed",
            Status::Approved => "approved",
            Status::Resolved => "resolved",
        }
    }

    /// Whether a person sets this status (`mktree clash-status`).
    pub fn is_set_by_person(self) -> bool {
        matches!(self, Status::Reviewed | Status::Approved | Status::Active)
    }
}

impl std::str::FromStr for Status {
    type Err = super::ClashError;

    fn from_str(s: &str) -> Result<Status, super::ClashError> {
        Ok(match s {
            "new" => Status::New,
            "active" => Status::Active,
            "reviewed" => Status::Reviewed,
            "approved" => Status::Approved,
            "resolved" => Status::Resolved,
            _ => {
                return Err(super::ClashError::Test(format!(
                    "status {s:?}: expected new, active, reviewed, approved or resolved"
                )));
            }
        })
    }
}

/// A clash with its status and the commits that saw it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Tracked {
    /// The clash as last measured.
    pub clash: Clash,
    /// Its status.
    pub status: Status,
    /// The commit of the run that first found it.
    pub first_txn: u64,
    /// The commit of the last run that found it.
    pub last_txn: u64,
}

impl AsRef<Clash> for Tracked {
    fn as_ref(&self) -> &Clash {
        &self.clash
    }
}

/// The statuses after a run on commit `txn` found `clashes` (sorted), given
/// those recorded before (`previous`). Resolved clashes stay listed.
///
/// Both lists are in (a, b, type) order, as runs and this function leave
/// them, so one merge pairs each clash with its record: no table of ids, and
/// the answer comes out in that order. A `previous` out of order (a store
/// written by something else) is sorted first.
pub fn update(previous: &[Tracked], clashes: &[Clash], txn: u64) -> Vec<Tracked> {
    merge(previous, clashes.iter().cloned(), |_| false, txn).0
}

/// [`update`] with the run's clashes given in two parts: `found` (sorted),
/// and the records of `previous` that `kept` holds, each found again as it
/// was (a re-run's clashes between unchanged objects, which it does not
/// copy out and sort in again). `kept` must hold no record whose clash
/// `found` has. Returns the records and how many `kept` held.
pub(crate) fn merge(
    previous: &[Tracked],
    found: impl IntoIterator<Item = Clash>,
    kept: impl Fn(&Tracked) -> bool,
    txn: u64,
) -> (Vec<Tracked>, usize) {
    let order = |x: &Clash, y: &Clash| (&x.a, &x.b, x.kind).cmp(&(&y.a, &y.b, y.kind));
    let previous: Cow<[Tracked]> = if previous.is_sorted_by(|x, y| order(&x.clash, &y.clash).is_le()) {
        Cow::Borrowed(previous)
    } else {
        let mut v = previous.to_vec();
        v.sort_by(|x, y| order(&x.clash, &y.clash));
        Cow::Owned(v)
    };
    // A record found again: its status carried, its commit this one.
    let again = |clash: Clash, seen: Option<&Tracked>| {
        let (status, first_txn) = match seen {
            None => (Status::New, txn),
            Some(t) => match t.status {
                Status::Resolved => (Status::New, txn),
                Status::Reviewed | Status::Approved => (t.status, t.first_txn),
                Status::New | Status::Active => (Status::Active, t.first_txn),
            },
        };
        Tracked { clash, status, first_txn, last_txn: txn }
    };
    // A record before the next clash found: kept, or gone from the run.
    let held = std::cell::Cell::new(0);
    let unmatched = |t: &Tracked| {
        if kept(t) {
            held.set(held.get() + 1);
            again(t.clash.clone(), Some(t))
        } else {
            Tracked { status: Status::Resolved, ..t.clone() }
        }
    };
    let mut out = Vec::with_capacity(previous.len());
    let mut old = previous.iter().peekable();
    for c in found {
        while let Some(t) = old.next_if(|t| order(&t.clash, &c).is_lt()) {
            out.push(unmatched(t));
        }
        let mut seen = None;
        while let Some(t) = old.next_if(|t| order(&t.clash, &c).is_eq()) {
            seen = Some(t);
        }
        out.push(again(c, seen));
    }
    out.extend(old.map(unmatched));
    (out, held.get())
}

/// Sets the status of the clashes of `tracked` between `a` and `b` (of
/// `kind`, or any kind) to `status`, which a person sets (Reviewed,
/// Approved, or Active to take either back). Returns how many changed;
/// a resolved clash is not set.
pub fn set_status(
    tracked: &mut [Tracked],
    a: &Key,
    b: &Key,
    kind: Option<ClashKind>,
    status: Status,
) -> usize {
    let mut n = 0;
    for t in tracked.iter_mut() {
        let hit = (&t.clash.a == a && &t.clash.b == b) || (&t.clash.a == b && &t.clash.b == a);
        if hit && kind.is_none_or(|k| k == t.clash.kind) && t.status != Status::Resolved {
            t.status = status;
            n += 1;
        }
    }
    n
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::Point;

    fn c(a: u64, b: u64) -> Clash {
        let p = Point::origin();
        Clash::hard_at(a, b, p)
    }

    #[test]
    fn new_active_resolved_and_a_persisting_approval() {
        let r1 = update(&[], &[c(1, 2), c(3, 4)], 10);
        assert!(r1.iter().all(|t| t.status == Status::New));
        let mut r1 = r1;
        assert_eq!(set_status(&mut r1, &Key::Int(4), &Key::Int(3), None, Status::Approved), 1);
        let r2 = update(&r1, &[c(1, 2), c(3, 4), c(5, 6)], 11);
        let st = |r: &[Tracked], a: u64| r.iter().find(|t| t.clash.a == Key::Int(a)).map(|t| t.status);
        assert_eq!(
            (st(&r2, 1), st(&r2, 3), st(&r2, 5)),
            (Some(Status::Active), Some(Status::Approved), Some(Status::New))
        );
        let r3 = update(&r2, &[c(3, 4)], 12);
        assert_eq!(
            (st(&r3, 1), st(&r3, 3), st(&r3, 5)),
            (Some(Status::Resolved), Some(Status::Approved), Some(Status::Resolved))
        );
        let r4 = update(&r3, &[c(1, 2)], 13);
        assert_eq!((st(&r4, 1), st(&r4, 3)), (Some(Status::New), Some(Status::Resolved)));
        assert_eq!(r4.iter().find(|t| t.clash.a == Key::Int(1)).map(|t| t.first_txn), Some(13));
    }

    proptest::proptest! {
        /// The merge gives what a lookup by id would: every clash once, with
        /// its record's status carried; every record the run lost, resolved;
        /// all in (a, b, type) order, whatever order the records came in.
        #[test]
        fn the_merge_matches_a_lookup_by_id(
            before in proptest::collection::btree_set((0u64..12, 0u64..12), 0..40),
            now in proptest::collection::btree_set((0u64..12, 0u64..12), 0..40),
            statuses in proptest::collection::vec(0u8..5, 40),
            reverse in proptest::bool::ANY,
        ) {
            let status = |i: usize| match statuses[i % statuses.len()] {
                0 => Status::New, 1 => Status::Active, 2 => Status::Reviewed, 3 => Status::Approved, _ => Status::Resolved,
            };
            let mut previous: Vec<Tracked> = before.iter().enumerate().map(|(i, &(a, b))| {
                Tracked { clash: c(a, b), status: status(i), first_txn: i as u64, last_txn: 5 }
            }).collect();
            if reverse {
                previous.reverse();
            }
            let clashes: Vec<Clash> = now.iter().map(|&(a, b)| c(a, b)).collect();
            let out = update(&previous, &clashes, 9);
            let key = |t: &Tracked| (t.clash.a.clone(), t.clash.b.clone(), t.clash.kind);
            proptest::prop_assert!(out.windows(2).all(|w| key(&w[0]) < key(&w[1])));
            for t in &out {
                let old = previous.iter().find(|p| key(p) == key(t));
                let found = clashes.iter().any(|c| (c.a.clone(), c.b.clone(), c.kind) == key(t));
                let want = match (found, old.map(|p| p.status)) {
                    (false, _) => Status::Resolved,
                    (true, None | Some(Status::Resolved)) => Status::New,
                    (true, Some(s @ (Status::Reviewed | Status::Approved))) => s,
                    (true, Some(_)) => Status::Active,
                };
                proptest::prop_assert_eq!(t.status, want);
            }
            proptest::prop_assert_eq!(out.len(), before.union(&now).count());
        }
    }
}
