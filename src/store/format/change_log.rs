//! The change log in the meta block (format-spec/meta.md, "The change
//! log"): which keys the latest change commits inserted, updated or
//! removed, as many commits as the block has room for, so that a reader
//! of a later commit learns what changed since an earlier one without
//! comparing the two trees (docs/clash.md, "Re-runs").
//!
//! The log is kept as its stored bytes, checked when the meta block is
//! decoded (every count bounded by the bytes that follow it) and parsed
//! into keys only when asked: a commit copies it forward, dropping its
//! oldest commits when the new one does not fit.

use crate::scene::{Key, KeyRef};
use crate::store::StorageError;

/// How a commit changed a key.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ChangeKind {
    /// The key had no object before the commit.
    Inserted,
    /// The key's object was replaced or moved.
    Updated,
    /// The key's object was removed.
    Removed,
}

impl ChangeKind {
    fn code(self) -> u8 {
        match self {
            ChangeKind::Inserted => 1,
            ChangeKind::Updated => 2,
            ChangeKind::Removed => 3,
        }
    }

    fn of(code: u8) -> Option<ChangeKind> {
        match code {
            1 => Some(ChangeKind::Inserted),
            2 => Some(ChangeKind::Updated),
            3 => Some(ChangeKind::Removed),
            _ => None,
        }
    }
}

/// One key a logged commit changed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LoggedChange {
    /// The commit ([`crate::ReadTransaction::txn`] of the state it made).
    pub txn: u64,
    /// How it changed the key.
    pub kind: ChangeKind,
    /// The key.
    pub key: Key,
}

/// A commit record's head: its `txn` (u64) and its count of keys (u32).
const RECORD_HEAD: usize = 12;

/// The change log as a meta block stores it: every key changed by each
/// commit with a transaction id in (`since`, the block's own], in commit
/// records of increasing transaction id.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct ChangeLog {
    /// Commits up to this one are not listed (a bulk load's own id: what
    /// it wrote is not a change of keys).
    pub since: u64,
    /// The commit records, as stored.
    pub(crate) bytes: Vec<u8>,
}

impl ChangeLog {
    /// The log of a tree bulk-loaded by commit `txn`: nothing listed.
    pub fn starting_at(txn: u64) -> ChangeLog {
        ChangeLog { since: txn, bytes: Vec::new() }
    }

    /// The log after commit `txn` (above every commit listed) changed
    /// `changes` (each key once, in key order), kept within `room` bytes:
    /// the oldest commits go first, and when the new commit alone does not
    /// fit, the log starts after it.
    pub fn after(&self, txn: u64, changes: &[(ChangeKind, Key)], room: usize) -> Result<ChangeLog, StorageError> {
        let mut record = Vec::new();
        if !changes.is_empty() {
            record.extend_from_slice(&txn.to_le_bytes());
            let count = u32::try_from(changes.len())
                .map_err(|_| StorageError::Invalid("more changes in one commit than ids".into()))?;
            record.extend_from_slice(&count.to_le_bytes());
            for (kind, key) in changes {
                record.push(kind.code());
                key.encode(&mut record);
            }
        }
        if record.len() > room {
            return Ok(ChangeLog::starting_at(txn));
        }
        // The oldest records that must go for the rest and the new one to fit.
        let mut since = self.since;
        let mut start = 0;
        for r in records(&self.bytes) {
            if self.bytes.len() - start + record.len() <= room {
                break;
            }
            let r = r.map_err(|e| StorageError::Invalid(format!("the committed change log: {e}")))?;
            since = r.txn;
            start = r.end;
        }
        let mut bytes = self.bytes[start..].to_vec();
        bytes.extend_from_slice(&record);
        Ok(ChangeLog { since, bytes })
    }

    /// Checks the records of meta block `id`, written by commit `txn`:
    /// transaction ids increasing within (`since`, `txn`], each record at
    /// least one key, kinds known, keys strictly increasing, no byte left.
    pub(crate) fn validate(&self, id: u32, txn: u64) -> Result<(), StorageError> {
        if self.since > txn {
            return Err(StorageError::corrupt(id, "log_since", format!("{} is after the block's commit {txn}", self.since)));
        }
        let mut last = self.since;
        for r in records(&self.bytes) {
            let r = r.map_err(|e| StorageError::corrupt(id, "change log", e))?;
            if r.txn <= last || r.txn > txn {
                return Err(StorageError::corrupt(
                    id,
                    "change log",
                    format!("a record of commit {} after {last}, in a block of commit {txn}", r.txn),
                ));
            }
            last = r.txn;
        }
        Ok(())
    }

    /// Every key changed by a commit after `txn`, oldest commit first;
    /// `None` when the log does not reach back to `txn` (a commit in
    /// (`txn`, `since`] is not listed).
    pub fn changes_after(&self, txn: u64) -> Result<Option<Vec<LoggedChange>>, StorageError> {
        if txn < self.since {
            return Ok(None);
        }
        let mut out = Vec::new();
        for r in records(&self.bytes) {
            let r = r.map_err(|e| StorageError::Invalid(format!("the change log: {e}")))?;
            if r.txn > txn {
                out.extend(r.changes.into_iter().map(|(kind, key)| LoggedChange { txn: r.txn, kind, key: key.to_key() }));
            }
        }
        Ok(Some(out))
    }
}

/// A commit record in place.
struct Record<'a> {
    txn: u64,
    changes: Vec<(ChangeKind, KeyRef<'a>)>,
    /// Where the next record starts.
    end: usize,
}

/// The records of `bytes` in order; each checked on its own (at least one
/// key, kinds known, keys strictly increasing, within the bytes).
fn records(bytes: &[u8]) -> impl Iterator<Item = Result<Record<'_>, String>> {
    let mut at = 0;
    std::iter::from_fn(move || {
        if at >= bytes.len() {
            return None;
        }
        let r = record(bytes, at);
        // A damaged record ends the walk: nothing after it can be found.
        at = r.as_ref().map_or(bytes.len(), |r| r.end);
        Some(r)
    })
}

fn record(bytes: &[u8], start: usize) -> Result<Record<'_>, String> {
    let head = bytes
        .get(start..start + RECORD_HEAD)
        .ok_or_else(|| format!("a record head cut short at byte {start}"))?;
    let txn = u64::from_le_bytes(head[..8].try_into().map_err(|_| "a record head".to_string())?);
    let count = u32::from_le_bytes(head[8..].try_into().map_err(|_| "a record head".to_string())?) as usize;
    // Each key takes at least 3 bytes (a kind and an empty byte key).
    if count == 0 || count > (bytes.len() - start - RECORD_HEAD) / 3 {
        return Err(format!("a record of {count} keys in {} bytes", bytes.len() - start - RECORD_HEAD));
    }
    let mut at = start + RECORD_HEAD;
    let mut changes: Vec<(ChangeKind, KeyRef<'_>)> = Vec::with_capacity(count);
    for _ in 0..count {
        let kind = bytes.get(at).and_then(|&c| ChangeKind::of(c)).ok_or_else(|| format!("an unknown change at byte {at}"))?;
        let (key, len) =
            bytes.get(at + 1..).and_then(KeyRef::decode).ok_or_else(|| format!("a damaged key at byte {}", at + 1))?;
        if changes.last().is_some_and(|(_, k)| *k >= key) {
            return Err(format!("keys out of order in the record of commit {txn}"));
        }
        changes.push((kind, key));
        at += 1 + len;
    }
    Ok(Record { txn, changes, end: at })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn ints(kind: ChangeKind, keys: &[u64]) -> Vec<(ChangeKind, Key)> {
        keys.iter().map(|&k| (kind, Key::Int(k))).collect()
    }

    #[test]
    fn a_commit_is_listed_and_read_back_by_the_commits_after_a_state() {
        let log = ChangeLog::starting_at(3);
        let log = log.after(4, &ints(ChangeKind::Inserted, &[1, 5]), 1000).unwrap();
        let log = log.after(5, &[(ChangeKind::Removed, Key::bytes(*b"ab").unwrap())], 1000).unwrap();
        log.validate(1, 5).unwrap();
        assert_eq!(log.since, 3);
        let all = log.changes_after(3).unwrap().unwrap();
        let seen: Vec<(u64, ChangeKind)> = all.iter().map(|c| (c.txn, c.kind)).collect();
        assert_eq!(seen, [(4, ChangeKind::Inserted), (4, ChangeKind::Inserted), (5, ChangeKind::Removed)]);
        assert_eq!(log.changes_after(4).unwrap().unwrap().len(), 1);
        assert!(log.changes_after(5).unwrap().unwrap().is_empty());
        assert_eq!(log.changes_after(2).unwrap(), None, "before the log starts");
    }

    #[test]
    fn the_oldest_commits_go_when_a_new_one_does_not_fit() {
        let mut log = ChangeLog::starting_at(1);
        // Each record: 12 bytes of head and 10 per integer key.
        for txn in 2..=6 {
            log = log.after(txn, &ints(ChangeKind::Updated, &[txn]), 45).unwrap();
        }
        assert_eq!(log.bytes.len(), 44, "two records of 22 bytes");
        assert_eq!(log.since, 4);
        assert_eq!(log.changes_after(3).unwrap(), None);
        let keys: Vec<Key> = log.changes_after(4).unwrap().unwrap().into_iter().map(|c| c.key).collect();
        assert_eq!(keys, [Key::Int(5), Key::Int(6)]);
        // A commit larger than the room: the log starts after it.
        let big = log.after(7, &ints(ChangeKind::Inserted, &[1, 2, 3, 4]), 45).unwrap();
        assert_eq!(big, ChangeLog::starting_at(7));
        // A commit of no change keeps the log, within the room.
        assert_eq!(log.after(8, &[], 45).unwrap(), log);
        assert_eq!(log.after(8, &[], 22).unwrap().since, 5);
    }

    #[test]
    fn damaged_records_are_refused() {
        let good = ChangeLog::starting_at(1).after(2, &ints(ChangeKind::Inserted, &[1, 2]), 100).unwrap();
        good.validate(9, 2).unwrap();
        let bad = |f: &dyn Fn(&mut ChangeLog), txn: u64| {
            let mut log = good.clone();
            f(&mut log);
            log.validate(9, txn).is_err()
        };
        assert!(bad(&|_| {}, 1), "a record after the block's commit");
        assert!(bad(&|l| l.since = 2, 2), "a record not after since");
        assert!(bad(&|l| l.since = 3, 2), "since after the block's commit");
        assert!(bad(&|l| l.bytes[12] = 4, 2), "an unknown kind");
        assert!(bad(&|l| l.bytes[12 + 1] = 7, 2), "an unknown key tag");
        assert!(bad(&|l| l.bytes.truncate(25), 2), "a key cut short");
        assert!(bad(&|l| l.bytes.push(0), 2), "a byte past the last record");
        assert!(bad(&|l| l.bytes[8..12].copy_from_slice(&0u32.to_le_bytes()), 2), "a record of no key");
        assert!(bad(&|l| l.bytes[8..12].copy_from_slice(&u32::MAX.to_le_bytes()), 2), "a count past the bytes");
        assert!(bad(&|l| l.bytes[12 + 10 + 9] = 0, 2), "keys out of order");
    }

    proptest! {
        /// Whatever commits come, the log lists exactly the keys of the
        /// commits after `since`, which are the latest that fit the room,
        /// and a reader of any state at or after `since` gets every key
        /// changed after it.
        #[test]
        fn the_log_holds_the_latest_commits_that_fit(
            commits in proptest::collection::vec(proptest::collection::btree_map(0u64..50, 1u8..4, 0..6), 1..30),
            room in 0usize..200,
        ) {
            let mut log = ChangeLog::starting_at(1);
            let mut model: Vec<(u64, Vec<(ChangeKind, Key)>)> = Vec::new();
            for (n, keys) in commits.iter().enumerate() {
                let txn = n as u64 + 2;
                let changes: Vec<(ChangeKind, Key)> =
                    keys.iter().map(|(&k, &c)| (ChangeKind::of(c).unwrap(), Key::Int(k))).collect();
                log = log.after(txn, &changes, room).unwrap();
                model.push((txn, changes));
                prop_assert!(log.bytes.len() <= room);
                log.validate(1, txn).unwrap();
            }
            let last = model.last().map_or(1, |m| m.0);
            for t in 1..=last {
                let got = log.changes_after(t).unwrap();
                if t < log.since {
                    prop_assert!(got.is_none());
                    continue;
                }
                let want: Vec<LoggedChange> = model
                    .iter()
                    .filter(|(txn, _)| *txn > t)
                    .flat_map(|(txn, c)| c.iter().map(|(kind, key)| LoggedChange { txn: *txn, kind: *kind, key: key.clone() }))
                    .collect();
                prop_assert_eq!(got, Some(want));
            }
            // Nothing was dropped that fit: the commit at `since` (if any
            // listed one) would not fit beside the rest.
            if let Some((_, c)) = model.iter().find(|(txn, _)| *txn == log.since) {
                let size = if c.is_empty() { 0 } else { RECORD_HEAD + c.iter().map(|(_, k)| 1 + k.encoded_len()).sum::<usize>() };
                prop_assert!(size == 0 || log.bytes.len() + size > room);
            }
        }
    }
}
