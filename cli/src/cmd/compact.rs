//! `mktree compact`: gives a file's free blocks back to the file system.

use std::path::Path;

use anyhow::Result;
use mktree::db::{Database, WriterWait};

use crate::output;

pub fn run(file: &Path, wait: bool, as_json: bool) -> Result<()> {
    let db = Database::open(file).map_err(|e| crate::input::opening(e, file))?;
    let c = db.compact_with(if wait { WriterWait::Wait } else { WriterWait::Fail })?;
    if as_json {
        return output::json(&c);
    }
    println!(
        "{}: {} -> {} blocks ({} free), tree moved {} time(s)",
        file.display(),
        c.blocks_before,
        c.blocks_after,
        c.free_after,
        c.rewrites
    );
    if let Some(txn) = c.held_by_reader {
        println!(
            "the tree was not moved: a reader holds transaction {txn}'s state (compact again once it ends)"
        );
    }
    Ok(())
}
