//! `mktree remove`: deletes objects by key in one write transaction.

use std::path::Path;

use anyhow::{Result, bail};
use mktree::db::{Database, WriterWait};
use mktree::scene::Key;
use serde_json::json;

use crate::output;

pub fn run(file: &Path, keys: &[Key], wait: bool, as_json: bool) -> Result<()> {
    let db = Database::open(file).map_err(|e| crate::input::opening(e, file))?;
    let mut w = db.begin_write_with(if wait { WriterWait::Wait } else { WriterWait::Fail })?;
    for key in keys {
        if w.remove(key)?.is_none() {
            // Nothing is committed: the file keeps every object.
            bail!("no object has the key {key}");
        }
    }
    w.commit()?;
    let info = db.begin_read()?.info();
    let objects = info.as_ref().map_or(0, |i| i.objects);
    if as_json {
        return output::json(&json!({ "removed": keys.len(), "objects": objects }));
    }
    println!("{}: removed {} object(s), {objects} left", file.display(), keys.len());
    Ok(())
}
