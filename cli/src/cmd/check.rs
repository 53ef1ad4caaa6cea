//! `mktree check`: verify a file; exit 1 on any fault.

use std::path::Path;

use anyhow::{Context, Result, bail};
use mktree::db::{Database, check};

use crate::output;

pub fn run(file: &Path, as_json: bool) -> Result<()> {
    let db = Database::open(file).with_context(|| format!("opening {}", file.display()))?;
    let rec = db.recovery();
    let report = check(&db)?;
    if as_json {
        output::json(&report)?;
    } else {
        if rec.interrupted {
            println!(
                "recovered an interrupted transaction: {} torn free blocks rewritten, {} blocks truncated",
                rec.scrubbed_blocks, rec.truncated_blocks
            );
        }
        let types: Vec<String> = report.blocks_by_type.iter().map(|(t, n)| format!("{n} {t}")).collect();
        println!(
            "{}: txn {}, {} blocks ({}; {} free), {} objects, {} nodes",
            file.display(),
            report.txn,
            report.file_blocks,
            types.join(", "),
            report.free_blocks,
            report.objects,
            report.nodes
        );
        for f in &report.faults {
            println!("fault: {f}");
        }
    }
    if !report.ok() {
        bail!("{} faults found", report.faults.len());
    }
    if !as_json {
        println!("ok");
    }
    Ok(())
}
