//! `mktree view`: the view's cut through the levels of detail for one
//! camera, as JSON (pieces front to back, errors, block reads).

use std::path::Path;

use anyhow::{Context, Result};
use mktree::Aabb;

use crate::args::ViewArgs;
use crate::output;

pub fn run(file: &Path, args: &ViewArgs) -> Result<()> {
    let db = crate::input::open_to_read(file)?;
    let r = db.begin_read()?;
    let scene = r.root().map_or(Aabb::EMPTY, |n| n.aabb);
    let cut = r
        .view(&args.view(&scene), &args.view_options(false), None)
        .with_context(|| format!("{}", file.display()))?;
    output::json(&output::cut_json(&cut))
}
