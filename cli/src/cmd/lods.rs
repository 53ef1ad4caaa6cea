//! `mktree lods` and `mktree node`: what each level of detail stores, and
//! one node's bound at one level, with its predicted and actual reads.

use std::io::{BufWriter, Write};
use std::path::Path;

use anyhow::{Context, Result, bail};
use mktree::db::{Database, GroupSummary, LodInfo, Piece, ReadTransaction, TreeInfo};
use mktree::query::level_benefit;
use mktree::scene::{Mesh, ObjWriter, Object};
use mktree::store::ReadStats;
use serde_json::{Value, json};

use crate::output;

fn open(file: &Path) -> Result<(Database, ReadTransaction)> {
    let db = crate::input::open_to_read(file)?;
    let r = db.begin_read()?;
    Ok((db, r))
}

/// `mktree lods`: each level of detail as a row, then the group bounds.
pub fn table(file: &Path, as_json: bool) -> Result<()> {
    let (_db, r) = open(file)?;
    let (Some(info), Some(tree)) = (r.lod_info(), r.info()) else {
        bail!("{} holds no tree", file.display())
    };
    let levels = level_rows(&r, &info, &tree)?;
    // The nodes' group bounds b(S_n,k) (format-spec/group.md), with the root's faces.
    let groups = r.group_summary()?;
    if as_json {
        return output::json(
            &json!({ "levels": levels, "query_extent": info.query_extent, "group": groups }),
        );
    }
    print_levels(file, &info, &tree, &levels);
    print_groups(&groups);
    Ok(())
}

/// The keys of a level's row, in the order the table shows them.
const LEVEL_KEYS: [&str; 11] = [
    "k",
    "faces_b",
    "faces_B",
    "eps",
    "measured_error",
    "bytes",
    "blocks",
    "stored",
    "predicted_saving",
    "predicted_cost",
    "measured_saving",
];

/// One JSON row per level of detail: what it stores, what the read model
/// predicted it saves and costs, and what it saves measured.
fn level_rows(r: &ReadTransaction, info: &LodInfo, tree: &TreeInfo) -> Result<Vec<Value>> {
    // What each level saves, measured on the file's read model (64 queries per scale).
    let benefit = level_benefit(r, 64)?;
    let measured = |k: usize| match (benefit.get(k.wrapping_sub(2)), benefit.get(k - 1)) {
        (Some(a), Some(b)) if k >= 2 => a.mean_reads - b.mean_reads,
        _ => 0.0,
    };
    let mut levels = Vec::new();
    for k in 1..=info.levels {
        let i = usize::from(k) - 1;
        // Faces at the root: b(S,k) is the union of the objects' bounds, so
        // both count the same pieces; level M is the objects themselves.
        let faces = if k == info.levels {
            tree.triangles
        } else {
            r.fetch_level(0, k, true, &mut ReadStats::default())?.faces()
        };
        let bytes = info.bytes[i];
        levels.push(json!({
            "k": k,
            "faces_b": faces,
            "faces_B": faces,
            "eps": info.eps[i],
            "measured_error": info.measured_error[i],
            "bytes": bytes,
            "blocks": info.blocks[i],
            "stored": info.stored[i],
            "predicted_saving": info.predicted_saving[i],
            "predicted_cost": info.predicted_cost[i],
            "measured_saving": measured(usize::from(k)),
        }));
    }
    Ok(levels)
}

/// The file's counts and query extent, then the levels' rows as a table.
fn print_levels(file: &Path, info: &LodInfo, tree: &TreeInfo, levels: &[Value]) {
    println!(
        "{}: {} objects, {} triangles, M = {}; bounds judged on box queries of {:.0} x {:.0} x {:.0} mm",
        file.display(),
        tree.objects,
        tree.triangles,
        info.levels,
        info.query_extent[0],
        info.query_extent[1],
        info.query_extent[2]
    );
    let rows: Vec<Vec<String>> = levels
        .iter()
        .map(|l| {
            LEVEL_KEYS
                .iter()
                .map(|key| match &l[*key] {
                    Value::Number(n) if n.is_f64() => format!("{:.2}", n.as_f64().unwrap_or(0.0)),
                    v => v.to_string(),
                })
                .collect()
        })
        .collect();
    output::table(
        &[
            "k",
            "Faces(b(S,k))",
            "Faces(B(S,k))",
            "eps mm",
            "measured mm",
            "bytes",
            "blocks",
            "bounds stored",
            "saves reads/query",
            "costs reads/query",
            "measured saving",
        ],
        &rows,
    );
}

/// The group bounds' totals, then per level what is stored and the root's bound.
fn print_groups(groups: &GroupSummary) {
    println!(
        "group bounds b(S_n,k): {} group blocks ({} bytes of directory and blobs) over {} nodes, \
         level-2 grids of at most {} cells",
        groups.blocks, groups.block_bytes, groups.nodes, groups.cuberille_bits
    );
    let rows: Vec<Vec<String>> = groups
        .levels
        .iter()
        .map(|l| {
            let opt = |v: Option<u64>| v.map_or("-".to_string(), |v| v.to_string());
            vec![
                l.level.to_string(),
                l.stored.to_string(),
                l.bytes.to_string(),
                opt(l.root_faces),
                opt(l.root_triangles),
                l.root_eps_mm.map_or("-".to_string(), |e| format!("{e:.0}")),
            ]
        })
        .collect();
    output::table(
        &["k", "nodes stored", "bytes", "root Faces(b(S,k))", "root triangles", "root eps mm"],
        &rows,
    );
}

pub fn node(file: &Path, id: u32, k: u8, objects: bool, export: Option<&Path>, as_json: bool) -> Result<()> {
    let (_db, r) = open(file)?;
    let info = r.lod_info().with_context(|| format!("{} holds no tree", file.display()))?;
    if k == 0 || k > info.levels {
        bail!("--lod {k} is not a level of this file (1 ..= {})", info.levels);
    }
    let mut stats = ReadStats::default();
    let level = r.fetch_level(id, k, objects, &mut stats)?;
    let predicted = level.predicted_reads;
    if let Some(path) = export {
        write_obj(path, id, k, &level.pieces).with_context(|| format!("writing {}", path.display()))?;
    }
    let value = json!({
        "node": id,
        "lod": k,
        "objects": objects,
        "pieces": level.pieces.len(),
        "faces": level.faces(),
        "bytes": level.bytes,
        "eps": info.eps[usize::from(k) - 1],
        "predicted_reads": predicted,
        "actual_reads": stats.total(),
        "block_reads": stats,
    });
    if as_json {
        return output::json(&value);
    }
    println!(
        "node {id}, {} at level {k}: {} pieces, {} faces, {} bytes, eps {:.1} mm; reads predicted {predicted}, actual {} ({} node, {} geometry)",
        if objects { "B(S_n,k)" } else { "b(S_n,k)" },
        level.pieces.len(),
        level.faces(),
        level.bytes,
        info.eps[usize::from(k) - 1],
        stats.total(),
        stats.node,
        stats.geometry
    );
    Ok(())
}

/// Each piece as closed meshes: a box, a voxel set's boundary, or the objects.
fn write_obj(path: &Path, node: u32, k: u8, pieces: &[Piece]) -> Result<()> {
    let mut w = ObjWriter::new(BufWriter::new(std::fs::File::create(path)?));
    w.comment(&format!("mktree node {node}, level {k}"))?;
    let mut put = |name: String, mesh: Option<Mesh>| -> Result<()> {
        if let Some(mesh) = mesh {
            w.write_object(&Object::new(name, mesh))?;
        }
        Ok(())
    };
    for p in pieces {
        match p {
            Piece::Box { node, aabb } => put(format!("node{node}_k{k}"), Mesh::of_box(aabb))?,
            Piece::ObjectBoxes(b) => {
                for (id, aabb) in b {
                    put(format!("object{id}_k{k}"), Mesh::of_box(aabb))?;
                }
            }
            Piece::ObjectVoxels(v) => {
                for (id, voxels) in v {
                    put(format!("object{id}_k{k}"), Some(voxels.boundary_mesh()))?;
                }
            }
            Piece::Objects(o) => {
                for (id, mesh) in o {
                    put(format!("object{id}"), Some(mesh.clone()))?;
                }
            }
            Piece::Group { node, level, voxels } => {
                put(format!("node{node}_group_k{level}"), Some(voxels.boundary_mesh()))?
            }
        }
    }
    w.finish()?.flush()?;
    Ok(())
}
