//! `mktree insert`: adds a scene's objects to a file in one write
//! transaction, and `mktree move`: translates one object by key. Both commit
//! copy on write (format-spec/commit.md, "Change commits") and print what
//! the commit wrote.

use std::path::Path;

use anyhow::{Result, bail};
use mktree::db::{ChangeStats, Database};
use mktree::geom::Vector;
use mktree::scene::Key;
use mktree::scene::import::{ImportOptions, load};
use serde_json::json;

use crate::output;

fn stats_json(s: &ChangeStats) -> serde_json::Value {
    json!({
        "in_place": s.in_place,
        "blocks_written": s.blocks_written,
        "blocks_freed": s.blocks_freed,
        "blocks_read": s.blocks_read,
    })
}

fn describe(s: &ChangeStats) -> String {
    if s.in_place {
        format!(
            "in place: {} blocks written, {} freed, {} read",
            s.blocks_written, s.blocks_freed, s.blocks_read
        )
    } else {
        "the tree written whole (a leaf had to split or empty)".to_string()
    }
}

/// Inserts every object of `scene` (OBJ, STL or glTF), keyed by its name
/// with `key_names`, else by the next integer keys.
pub fn run_insert(file: &Path, scene: &Path, key_names: bool, as_json: bool) -> Result<()> {
    let imported = load(scene, &ImportOptions::default())?;
    let mut scene_objects = imported.scene;
    if key_names {
        scene_objects.key_by_names()?;
    }
    let db = Database::open(file).map_err(|e| crate::input::opening(e, file))?;
    let mut w = db.begin_write()?;
    let mut keys: Vec<Key> = Vec::new();
    for object in scene_objects.into_objects() {
        keys.push(w.insert(object)?);
    }
    let stats = w.commit_with_stats()?;
    let objects = db.begin_read()?.info().map_or(0, |i| i.objects);
    if as_json {
        let keys: Vec<String> = keys.iter().map(ToString::to_string).collect();
        return output::json(
            &json!({ "inserted": keys.len(), "keys": keys, "objects": objects, "commit": stats_json(&stats) }),
        );
    }
    println!("{}: inserted {} object(s), {objects} in all; {}", file.display(), keys.len(), describe(&stats));
    Ok(())
}

/// Moves the object of `key` by `by` (mm).
pub fn run_move(file: &Path, key: &Key, by: [f64; 3], as_json: bool) -> Result<()> {
    if !by.iter().all(|x| x.is_finite()) {
        bail!("--by {by:?} is not a finite offset");
    }
    let db = Database::open(file).map_err(|e| crate::input::opening(e, file))?;
    let mut w = db.begin_write()?;
    if !w.move_by(key, Vector::new(by[0], by[1], by[2]))? {
        bail!("no object has the key {key}");
    }
    let stats = w.commit_with_stats()?;
    if as_json {
        return output::json(&json!({ "moved": key.to_string(), "by": by, "commit": stats_json(&stats) }));
    }
    println!("{}: moved {key} by {by:?}; {}", file.display(), describe(&stats));
    Ok(())
}
