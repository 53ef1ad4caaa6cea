//! Claim: `bulk_load` accepts only scenes that a file can hold, and every
//! file it writes reads back. A scene wider than f32's range on an axis
//! (split values and vertex offsets are stored as f32) is refused before
//! anything is written, with an error that names the axis, the coordinates
//! and the objects; an object wider than that is refused when its mesh is
//! made. Degenerate scenes (points, 1e-100 mm triangles, segments), alone
//! or among good objects, are accepted, with or without stored levels of
//! detail, and read back: `check` finds no fault, a query answers them.

use mktree::build::{BuildError, BuildParams, LeafRule};
use mktree::db::{CreateOptions, Database, check};
use mktree::geom::{Axis, Point};
use mktree::lod::LodParams;
use mktree::scene::{Mesh, MeshError, Object, ObjectId, Scene};

/// Small leaves, so that a few objects make internal nodes (splits).
fn params() -> BuildParams {
    BuildParams { leaf: LeafRule::Objects(2), ..BuildParams::default() }
}

fn mesh(points: &[[f64; 3]]) -> Mesh {
    let points: Vec<Point> = points.iter().map(|&p| p.into()).collect();
    Mesh::from_world(&points, vec![[0, 1, 2]]).expect("a valid mesh")
}

/// A unit right triangle with its corner at `(x, 0, 0)`.
fn triangle_at(x: f64) -> Mesh {
    mesh(&[[x, 0.0, 0.0], [x + 1.0, 0.0, 0.0], [x, 1.0, 0.0]])
}

fn scene(meshes: impl IntoIterator<Item = Mesh>) -> Scene {
    Scene::new(meshes.into_iter().enumerate().map(|(i, m)| Object::new(format!("o{i}"), m)).collect())
}

/// Builds `scene` into a new file (every level-of-detail bound stored when
/// `store_all`). A refusal is returned, after checking that the file was
/// left without a tree; an accepted scene's file must read back: it opens,
/// `check` finds no fault, and a query over the scene's box answers every
/// object.
fn build_then_read(scene: &Scene, store_all: bool) -> Result<(), mktree::Error> {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("scene.mkt");
    let built = {
        let db = Database::create(&path, CreateOptions::default()).unwrap();
        let mut w = db.begin_write().unwrap();
        w.set_lod_params(LodParams { store_all, ..LodParams::default() });
        w.bulk_load(scene, &params(), &|_| {}).and_then(|_| Ok(w.commit()?))
    };
    let db = Database::open(&path).expect("the file opens");
    if built.is_err() {
        assert!(db.begin_read().unwrap().info().is_none(), "a refused scene left a tree");
        return built;
    }
    let report = check(&db).expect("check runs");
    assert!(report.ok(), "check finds faults: {:?}", report.faults);
    let answer = db.begin_read().unwrap().query_box(&scene.aabb()).expect("the query answers");
    assert_eq!(answer.objects.len(), scene.len());
    Ok(())
}

fn too_wide(scene: &Scene) -> BuildError {
    match build_then_read(scene, false) {
        Err(mktree::Error::Build(e @ BuildError::TooWide { .. })) => e,
        other => panic!("expected the scene to be refused as too wide, got {other:?}"),
    }
}

#[test]
fn a_scene_wider_than_f32_on_an_axis_is_refused_before_anything_is_written() {
    // Two groups of triangles 1e39 mm apart: the split between them did not fit an f32.
    let wide = scene(
        (0..4)
            .map(|i| triangle_at(f64::from(i)))
            .chain((0..4).map(|i| triangle_at(1e39 + 1e24 * f64::from(i)))),
    );
    let e = too_wide(&wide);
    let high = wide.aabb().max.x;
    let expected = BuildError::TooWide {
        axis: Axis::X,
        low: 0.0,
        low_object: ObjectId(0),
        high,
        high_object: ObjectId(7),
    };
    assert_eq!(e, expected);
    let m = e.to_string();
    assert!(m.contains(&format!("spans x from 0e0 mm (object 0) to {high:e} mm (object 7)")), "{m}");
    assert!(m.contains("3.4028234663852886e38 mm"), "{m}");
    // Coordinates at either end of f64, whose difference is not even finite.
    let ends = scene([triangle_at(-1e308), triangle_at(1e308), triangle_at(0.0)]);
    assert!(matches!(too_wide(&ends), BuildError::TooWide { axis: Axis::X, .. }));
}

#[test]
fn a_scene_exactly_as_wide_as_f32_allows_builds_and_reads_back() {
    let max = f64::from(f32::MAX);
    let edge = scene((0..4).map(|i| triangle_at(f64::from(i))).chain([mesh(&[
        [max, 0.0, 0.0],
        [max, 1.0, 0.0],
        [max, 0.0, 1.0],
    ])]));
    build_then_read(&edge, false).unwrap();
    let over =
        scene([triangle_at(0.0), mesh(&[[max, 0.0, 0.0], [max * (1.0 + 1e-15), 0.0, 0.0], [max, 1.0, 0.0]])]);
    assert!(matches!(too_wide(&over), BuildError::TooWide { .. }));
}

#[test]
fn an_object_wider_than_f32_is_refused_as_a_mesh() {
    let points: Vec<Point> = [[0.0, 0.0, 0.0], [1e39, 0.0, 0.0], [0.0, 1.0, 0.0]].map(Point::from).to_vec();
    let e = Mesh::from_world(&points, vec![[0, 1, 2]]).unwrap_err();
    assert_eq!(e, MeshError::TooWide { vertex: 1, offset: 1e39 });
    assert!(e.to_string().contains("vertex 1 lies 1e39 mm from the object's lower corner"), "{e}");
}

/// Scenes whose objects have no area, each alone and among good objects.
fn degenerate_scenes() -> Vec<(&'static str, Scene)> {
    let points = || (0..6).map(|i| mesh(&[[f64::from(i), 2.0, 3.0]; 3]));
    let specks = || {
        (0..6).map(|i| {
            let x = f64::from(i) * 1e-100;
            mesh(&[[x, 0.0, 0.0], [x + 1e-100, 0.0, 0.0], [x, 1e-100, 0.0]])
        })
    };
    let segments = || {
        (0..6).map(|i| {
            let x = f64::from(i) * 2.0;
            mesh(&[[x, 0.0, 0.0], [x + 1.0, 0.0, 0.0], [x + 0.5, 0.0, 0.0]])
        })
    };
    let good = || (0..6).map(|i| triangle_at(10.0 * f64::from(i)));
    vec![
        ("one point", scene([mesh(&[[5.0, 5.0, 5.0]; 3])])),
        ("points", scene(points())),
        ("the same point", scene((0..6).map(|_| mesh(&[[1.0, 2.0, 3.0]; 3])))),
        ("1e-100 mm triangles", scene(specks())),
        ("segments", scene(segments())),
        ("points among triangles", scene(points().chain(good()))),
        ("1e-100 mm triangles among triangles", scene(specks().chain(good()))),
        ("segments among triangles", scene(segments().chain(good()))),
    ]
}

#[test]
fn degenerate_scenes_build_and_read_back() {
    for (name, scene) in degenerate_scenes() {
        build_then_read(&scene, false).unwrap_or_else(|e| panic!("{name}: {e}"));
    }
}

#[test]
fn degenerate_scenes_with_every_level_of_detail_stored_read_back() {
    // The measured error of a bound of an object without area was infinite.
    for (name, scene) in degenerate_scenes() {
        build_then_read(&scene, true).unwrap_or_else(|e| panic!("{name}: {e}"));
    }
}

#[test]
fn a_far_scene_within_the_span_reads_back() {
    // Anchors are f64: a scene far from the origin only needs a small span.
    let far = scene((0..6).map(|i| triangle_at(1e15 + 10.0 * f64::from(i))));
    build_then_read(&far, true).unwrap();
}
