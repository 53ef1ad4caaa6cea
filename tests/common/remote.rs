//! What the object-store tests share: a file built on disk, the boxes they
//! query, and the comparison of a remote reader with the local one.

use std::path::Path;

use mktree::bulk::BuildParams;
use mktree::db::{CreateOptions, Database};
use mktree::geom::Aabb;
use mktree::scene::Scene;
use mktree::scene::generate::{GenOptions, Preset, generate_scene};

/// Builds `preset` (seed 0) into a new file at `path`; the scene.
pub fn build_file(path: &Path, preset: Preset) -> Scene {
    let scene = generate_scene(&GenOptions { preset, objects: None, seed: 0 }).expect("preset");
    let db = Database::create(path, CreateOptions::default()).expect("create");
    let mut w = db.begin_write().expect("write");
    w.bulk_load(&scene, &BuildParams::default(), &|_| {}).expect("bulk load");
    w.commit().expect("commit");
    scene
}

/// 27 boxes of a third of the scene's extent each way, then the whole box.
pub fn boxes(scene: &Scene) -> Vec<Aabb> {
    let b = scene.aabb();
    let (lo, size) = (b.min, b.max - b.min);
    let mut out = Vec::new();
    for i in 0..27 {
        let c = [i % 3, (i / 3) % 3, i / 9].map(f64::from);
        let at = |a: usize| lo[a] + size[a] * c[a] / 3.0;
        let third = |a: usize| size[a] / 3.0;
        out.push(Aabb::from_array([
            at(0),
            at(1),
            at(2),
            at(0) + third(0),
            at(1) + third(1),
            at(2) + third(2),
        ]));
    }
    out.push(b);
    out
}

/// Asserts that `remote` answers every box as `local` does, with the same
/// block reads; their sum.
pub fn assert_same_answers(local: &Database, remote: &Database, boxes: &[Aabb]) -> u64 {
    let (l, r) = (local.begin_read().expect("read"), remote.begin_read().expect("read"));
    let mut reads = 0;
    for b in boxes {
        let (a, c) = (l.query_box(b).expect("local query"), r.query_box(b).expect("remote query"));
        assert_eq!(a.objects, c.objects, "answers differ for {b:?}");
        assert_eq!(a.stats.reads, c.stats.reads, "block reads differ for {b:?}");
        reads += c.stats.reads.total();
    }
    reads
}
