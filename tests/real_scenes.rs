//! Claim: the real CAD scenes in `../shared/data` (converted from the
//! Debian package assimp-testmodels, see that folder's README) import with
//! the object, triangle and vertex counts and the extent their README
//! states. Without `../shared` (a plain clone), the tests say so and pass.

use std::path::PathBuf;

use mktree::scene::import::{ImportOptions, Imported, load};

/// The imported scene `name` from the shared data folder, or `None` (with a
/// visible message) when the folder is not there.
fn import_shared(name: &str) -> Option<Imported> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data");
    if !dir.is_dir() {
        eprintln!(
            "SKIPPED: {} is absent (a plain clone has no ../shared), so the real-scene test for {name} \
             did not run",
            dir.display()
        );
        return None;
    }
    let path = dir.join(name);
    Some(load(&path, &ImportOptions::default()).unwrap_or_else(|e| panic!("{e}")))
}

/// Checks counts and the scene extent (mm, to the README's 3 decimals).
fn check(imported: &Imported, objects: usize, triangles: usize, vertices: usize, extent_mm: [f64; 3]) {
    let scene = &imported.scene;
    assert_eq!((scene.len(), scene.triangle_count(), scene.vertex_count()), (objects, triangles, vertices));
    let extent = scene.aabb().extent();
    for axis in 0..3 {
        assert!((extent[axis] - extent_mm[axis]).abs() < 5e-4, "extent {extent:?}, expected {extent_mm:?}");
    }
}

#[test]
fn fzk_haus_has_117_objects_and_36406_triangles() {
    let Some(imported) = import_shared("fzk-haus.obj") else { return };
    check(&imported, 117, 36_406, 18_346, [18_000.0, 16_000.0, 7317.691]);
    assert_eq!(imported.scene.objects()[0].name, "IfcSite_1Qvf0xqDT4HXo8jI81mHB$");
    // The README: "No triangle was degenerate."
    assert_eq!(imported.degenerate_triangles, 0);
}

#[test]
fn engine_has_67_objects_and_110336_triangles() {
    let Some(imported) = import_shared("engine.obj") else { return };
    check(&imported, 67, 110_336, 59_068, [743.384, 273.014, 268.0]);
    let springs =
        imported.scene.objects().iter().filter(|o| o.name.starts_with("Spring_Link__0_Parts_1_node")).count();
    assert_eq!(springs, 20);
}
