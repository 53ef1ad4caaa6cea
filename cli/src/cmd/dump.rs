//! `mktree dump`: every node as JSON (`{"nodes": [...]}`).

use std::path::Path;

use anyhow::{Result, bail};

use crate::args::BuildArgs;
use crate::input::tree_of;
use crate::output;

pub fn run(input: &Path, build: &BuildArgs, as_json: bool) -> Result<()> {
    if !as_json {
        bail!("dump prints JSON only: add --json");
    }
    let (tree, _) = tree_of(input, build, false)?;
    output::json(&tree)
}
