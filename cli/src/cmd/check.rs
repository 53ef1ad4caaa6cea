//! `mktree check`: verify a file; exit 1 on any fault.

use std::path::Path;

use anyhow::{Result, bail};
use mktree::db::check;

use crate::output;

pub fn run(file: &Path, as_json: bool) -> Result<()> {
    let db = crate::input::open_to_read(file)?;
    let report = check(&db)?;
    if as_json {
        output::json(&report)?;
    } else {
        if report.interrupted {
            println!("a write transaction was interrupted; the next write cleans up after it");
        }
        for w in &report.warnings {
            println!("warning: {w}");
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
