//! Claim: the 3D Tiles export is a tileset a viewer can stream: one tile
//! per node (and an exact child per leaf), REPLACE refinement, internal
//! tiles drawn from their nodes' group bounds (hierarchical levels of
//! detail: more than a box, with the bound's error), geometric
//! errors in metres that never grow from a tile to its children, each
//! tile's box holding its children's and its content's, millimetres and the
//! anchor in the root's transform, and .glb files that parse as glTF and
//! hold, over the exact tiles, every triangle of the scene once. When the
//! official validator (`3d-tiles-validator`) is on the PATH it must accept
//! the tileset; otherwise the test says it was skipped.

mod common;

use common::lod_db;
use mktree::lod::LodParams;
use mktree::scene::generate::{GenOptions, Preset, generate_scene};
use mktree::tiles::export_3d_tiles;
use serde_json::Value;

/// A tile's box as [min, max] per axis (axis-aligned boxes only).
fn tile_box(t: &Value) -> [[f64; 2]; 3] {
    let b: Vec<f64> =
        t["boundingVolume"]["box"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
    assert_eq!(b.len(), 12);
    let half = [b[3], b[7], b[11]];
    assert_eq!([b[4], b[5], b[6], b[8], b[9], b[10]], [0.0; 6], "axis-aligned");
    std::array::from_fn(|i| [b[i] - half[i], b[i] + half[i]])
}

fn holds(outer: &[[f64; 2]; 3], inner: &[[f64; 2]; 3], slack: f64) -> bool {
    (0..3).all(|i| outer[i][0] <= inner[i][0] + slack && inner[i][1] <= outer[i][1] + slack)
}

struct Walk {
    tiles: u64,
    exact_triangles: u64,
    /// Internal tiles whose content has more than a box's 12 triangles.
    shaped: u64,
    internal: u64,
    dir: std::path::PathBuf,
}

impl Walk {
    fn tile(&mut self, t: &Value, parent_error: f64) {
        self.tiles += 1;
        assert_eq!(t["refine"], "REPLACE");
        let error = t["geometricError"].as_f64().unwrap();
        assert!(error >= 0.0 && error <= parent_error, "error {error} m under a parent of {parent_error} m");
        let b = tile_box(t);
        let internal = t["children"].as_array().is_some_and(|c| c.len() == 2);
        self.internal += u64::from(internal);
        if let Some(uri) = t["content"]["uri"].as_str() {
            let bytes = std::fs::read(self.dir.join(uri)).unwrap();
            let g = gltf::Gltf::from_slice(&bytes).unwrap_or_else(|e| panic!("{uri}: {e}"));
            for mesh in g.meshes() {
                for p in mesh.primitives() {
                    let pos = p.get(&gltf::Semantic::Positions).unwrap();
                    let (lo, hi) = (pos.min().unwrap(), pos.max().unwrap());
                    let f = |v: &Value, i: usize| v[i].as_f64().unwrap();
                    // glTF's (x, z, -y) back to the tiles' (x, y, z).
                    let content = [[f(&lo, 0), f(&hi, 0)], [-f(&hi, 2), -f(&lo, 2)], [f(&lo, 1), f(&hi, 1)]];
                    assert!(holds(&b, &content, 1e-3), "{uri}: content {content:?} outside its tile {b:?}");
                    let triangles = p.indices().unwrap().count() as u64 / 3;
                    if uri.ends_with("-exact.glb") {
                        self.exact_triangles += triangles;
                    }
                    if internal && triangles > 12 {
                        self.shaped += 1;
                    }
                }
            }
        }
        for c in t["children"].as_array().map_or(&[][..], |v| v) {
            assert!(holds(&b, &tile_box(c), 1e-6), "a child's box outside its parent's");
            self.tile(c, error);
        }
    }
}

#[test]
fn tanker1_exports_as_a_tileset_of_one_tile_per_node() {
    let scene = generate_scene(&GenOptions { preset: Preset::Tanker1, objects: None, seed: 2 }).unwrap();
    let db = lod_db(&scene, 4, 4096, 10, LodParams { store_all: true, ..LodParams::default() });
    let r = db.begin_read().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("tiles");
    let report = export_3d_tiles(&r, &out).unwrap();
    let info = r.info().unwrap();
    assert_eq!(
        report.tiles,
        u64::from(info.nodes + info.leaves),
        "a tile per node and an exact one per leaf"
    );
    let tileset: Value = serde_json::from_slice(&std::fs::read(out.join("tileset.json")).unwrap()).unwrap();
    assert_eq!(tileset["asset"]["version"], "1.1");
    let root = &tileset["root"];
    let t: Vec<f64> = root["transform"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
    let a = scene.aabb().min;
    assert_eq!((t[0], t[5], t[10], t[15]), (1e-3, 1e-3, 1e-3, 1.0), "mm to m");
    for (i, c) in [a.x, a.y, a.z].iter().enumerate() {
        assert!((t[12 + i] - c * 1e-3).abs() < 1e-12, "the anchor in metres");
    }
    // The root's error: its finest group bound's, in metres (its largest
    // cell's diagonal), or a child's where that is larger; well under the
    // scene's diagonal (a box's error).
    let groups = r.group_summary().unwrap();
    let finest = groups.levels.iter().rev().find_map(|l| l.root_eps_mm).expect("the root has a group bound");
    let d = scene.aabb().extent().norm() * 1e-3;
    let e = root["geometricError"].as_f64().unwrap();
    let children = root["children"].as_array().unwrap().iter().map(|c| c["geometricError"].as_f64().unwrap());
    assert_eq!(
        e,
        children.fold(finest * 1e-3, f64::max),
        "the root's error is its group bound's, or a child's"
    );
    assert!(e < d / 4.0, "{e} m against the scene's diagonal {d} m");
    let mut walk = Walk { tiles: 0, exact_triangles: 0, shaped: 0, internal: 0, dir: out.clone() };
    walk.tile(root, tileset["geometricError"].as_f64().unwrap());
    assert_eq!(walk.tiles, report.tiles);
    assert_eq!(walk.shaped, walk.internal, "every internal tile shows more than a box");
    let triangles: u64 = scene.objects().iter().map(|o| o.mesh.triangle_count() as u64).sum();
    assert_eq!(walk.exact_triangles, triangles, "every triangle once in the exact tiles");
    // The official validator, when it is installed.
    match std::process::Command::new("3d-tiles-validator")
        .arg("--tilesetFile")
        .arg(out.join("tileset.json"))
        .output()
    {
        Ok(o) => {
            let text = String::from_utf8_lossy(&o.stdout);
            assert!(o.status.success() && !text.contains("\"severity\": \"ERROR\""), "validator: {text}");
        }
        Err(_) => eprintln!("3d-tiles-validator is not on the PATH: the official validation was skipped"),
    }
}
