//! `mktree clash-status`: the statuses of a recorded clash test, or a
//! person's status (Reviewed, Approved, Active) set on a pair.

use std::path::Path;

use anyhow::{Result, bail};
use mktree::clash::key_json::key_text;
use mktree::clash::{ClashKind, ClashStore, Status, set_status, store_path};
use serde_json::json;

use crate::output;

/// The pair and status to set (all optional: none lists the statuses).
pub struct Pair {
    pub a: Option<String>,
    pub b: Option<String>,
    pub kind: Option<String>,
    pub set: Option<String>,
    pub text: bool,
}

pub fn run(file: &Path, test: &str, pair: &Pair, store: Option<&Path>, as_json: bool) -> Result<()> {
    // The file must be an mktree file: a mistyped name is an error, not an empty store.
    drop(crate::input::open_to_read(file)?);
    let path = store.map_or_else(|| store_path(file), Path::to_path_buf);
    // Setting a status writes the store: one writer at a time.
    let lock = pair.set.is_some().then(|| crate::input::lock_store(&path)).transpose()?;
    let mut s = match &lock {
        Some(lock) => lock.load()?,
        None => ClashStore::load(&path)?,
    };
    let Some(run) = s.runs.get_mut(test) else {
        bail!("no recorded run of the test {test:?} in {}", path.display())
    };
    if let Some(set) = &pair.set {
        let status: Status = set.parse()?;
        if !status.is_set_by_person() {
            bail!("--set {set}: a person sets reviewed, approved or active; the runs set the rest");
        }
        let (Some(a), Some(b)) = (&pair.a, &pair.b) else { bail!("--set needs --a KEY and --b KEY") };
        let key = |k: &String| crate::input::parse_key(std::ffi::OsStr::new(k), pair.text);
        let kind = match pair.kind.as_deref() {
            None => None,
            Some("hard") => Some(ClashKind::Hard),
            Some("clearance") => Some(ClashKind::Clearance),
            Some("touch") => Some(ClashKind::Touch),
            Some("duplicate") => Some(ClashKind::Duplicate),
            Some(other) => bail!("--type {other}: expected hard, clearance, touch or duplicate"),
        };
        let n = set_status(&mut run.tracked, &key(a)?, &key(b)?, kind, status);
        if n == 0 {
            bail!("no open clash between {a} and {b} in the test {test:?}");
        }
        if let Some(lock) = &lock {
            lock.save(&s)?;
        }
        if as_json {
            return output::json(&json!({"test": test, "set": status.name(), "clashes": n}));
        }
        println!("{n} clash(es) between {a} and {b} set to {}", status.name());
        return Ok(());
    }
    if as_json {
        for t in &run.tracked {
            let mut v = serde_json::to_value(&t.clash)?;
            if let Some(o) = v.as_object_mut() {
                o.insert("status".into(), json!(t.status.name()));
                o.insert("first_txn".into(), json!(t.first_txn));
                o.insert("last_txn".into(), json!(t.last_txn));
            }
            println!("{v}");
        }
        return Ok(());
    }
    let rows: Vec<Vec<String>> = run
        .tracked
        .iter()
        .map(|t| {
            vec![
                t.status.name().to_string(),
                t.clash.kind.name().to_string(),
                key_text(&t.clash.a),
                key_text(&t.clash.b),
                t.first_txn.to_string(),
                t.last_txn.to_string(),
            ]
        })
        .collect();
    output::table(&["status", "type", "a", "b", "first commit", "last commit"], &rows);
    Ok(())
}
