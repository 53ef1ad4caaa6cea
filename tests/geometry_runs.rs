//! A bulk load writes its geometry blocks in runs of whole leaves, encoded
//! and written in parallel (format-spec/geometry.md, "Placement": no block
//! holds two leaves' records): wherever the runs fall, every object's mesh
//! reads back as it went in, and `check` finds every block sound.

mod common;

use common::mem_db;
use mktree::bulk::{BuildParams, LeafRule};
use mktree::db::{CreateOptions, check};
use mktree::scene::generate::{GenOptions, Preset, generate_scene};
use mktree::scene::{Key, Mesh};

#[test]
fn every_mesh_reads_back_from_geometry_written_in_many_runs() {
    let scene = generate_scene(&GenOptions { preset: Preset::Tanker2, objects: None, seed: 5 }).unwrap();
    // Small blocks and leaves: thousands of geometry blocks, so many runs of 64.
    let params = BuildParams { leaf: LeafRule::Objects(4), ..BuildParams::default() };
    let (db, _) = mem_db(&scene, &params, CreateOptions { block_size: 1024, lod_levels: 3 });
    let report = check(&db).unwrap();
    assert!(report.ok(), "{:?}", report.faults);
    let geometry = report.blocks_by_type.get("geometry").copied().unwrap_or(0);
    assert!(geometry > 10 * 64, "{geometry} geometry blocks: too few to make many runs");
    let r = db.begin_read().unwrap();
    for (i, o) in scene.objects().iter().enumerate() {
        let back = r.mesh(&Key::Int(i as u64)).unwrap().expect("every object is stored");
        // An object larger than a block reads back as its parts joined, its
        // triangles in another order: the same triangles, the same points.
        assert_eq!(back.aabb(), o.mesh.aabb(), "object {i}");
        assert_eq!(triangles(&back), triangles(&o.mesh), "object {i}");
    }
}

/// A mesh's triangles as the bits of their points, sorted.
fn triangles(mesh: &Mesh) -> Vec<[[u64; 3]; 3]> {
    let mut t: Vec<[[u64; 3]; 3]> =
        mesh.triangle_points().map(|ps| ps.map(|p| [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()])).collect();
    t.sort_unstable();
    t
}
