//! `mktree get`: one object by its key, through the key index: id, key,
//! box, payload and name, with the block reads it took.

use std::path::Path;

use anyhow::{Result, bail};
use mktree::db::Reads;
use mktree::scene::Key;
use serde_json::json;

use crate::output;

pub fn run(file: &Path, key: &Key, mesh: bool, as_json: bool) -> Result<()> {
    let db = crate::input::open_to_read(file)?;
    let r = db.begin_read()?;
    let mut reads = Reads::new(None);
    let Some(rec) = r.get_with(key, &mut reads)? else { bail!("no object has the key {key}") };
    let triangles = if mesh { r.mesh_with(key, &mut reads)?.map(|m| m.triangle_count()) } else { None };
    let s = &reads.stats;
    if as_json {
        return output::json(&json!({
            "id": rec.id,
            "key": rec.key,
            "box": rec.aabb.to_array(),
            "payload_hex": rec.payload.iter().map(|b| format!("{b:02x}")).collect::<String>(),
            "triangles": triangles,
            "block_reads": { "keys": s.keys, "node": s.node, "geometry": s.geometry, "total": s.total() },
        }));
    }
    println!(
        "object {} key {} box {:?}, {} payload bytes",
        rec.id,
        rec.key,
        rec.aabb.to_array(),
        rec.payload.len()
    );
    if let Some(t) = triangles {
        println!("mesh: {t} triangles");
    }
    println!("{} block reads ({} key index, {} node, {} geometry)", s.total(), s.keys, s.node, s.geometry);
    Ok(())
}
