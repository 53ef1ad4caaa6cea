//! `mktree export-3dtiles`: the tree as a 3D Tiles 1.1 tileset.

use std::path::Path;

use anyhow::{Context, Result};

use crate::output;

pub fn run(file: &Path, out: &Path, as_json: bool) -> Result<()> {
    let db = crate::input::open_to_read(file)?;
    let r = db.begin_read()?;
    let report = mktree::tiles::export_3d_tiles(&r, out).with_context(|| format!("{}", file.display()))?;
    if as_json {
        return output::json(&report);
    }
    println!(
        "{}: {} tiles, {} .glb files, {} triangles, {} bytes; {} block reads",
        out.display(),
        report.tiles,
        report.glb_files,
        report.triangles,
        report.bytes,
        report.reads.total()
    );
    Ok(())
}
