//! `mktree publish`: the file at its last commit uploaded as one object
//! (format-spec/remote.md, "Publishing").

use std::path::Path;
use std::time::Instant;

use anyhow::Result;
use mktree::db::Database;
use mktree::store::device::RemoteOptions;

use crate::output;

pub fn run(file: &Path, url: &str, as_json: bool) -> Result<()> {
    let db = Database::open(file).map_err(|e| crate::input::opening(e, file))?;
    let started = Instant::now();
    let done = db.publish(url, &RemoteOptions::default())?;
    let seconds = started.elapsed().as_secs_f64();
    if as_json {
        let mut value = serde_json::to_value(&done)?;
        value["seconds"] = serde_json::json!(seconds);
        return output::json(&value);
    }
    println!(
        "{}: {} bytes to {url} in {} parts, {seconds:.2} s; ETag {}, version {}",
        file.display(),
        done.bytes,
        done.parts,
        done.e_tag.as_deref().unwrap_or("-"),
        done.version.as_deref().unwrap_or("-")
    );
    Ok(())
}
