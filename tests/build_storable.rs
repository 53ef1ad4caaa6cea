//! Claim: `bulk_load` accepts only scenes that a file can hold, and every
//! file it writes reads back. A scene with a coordinate beyond the format's
//! range (±2^53 mm, format-spec/geometry.md) is refused before anything is
//! written, with an error that names the object, the axis and the
//! coordinate; an object wider than an f32 offset holds is refused when its
//! mesh is made. Degenerate scenes (points, 1e-100 mm triangles, segments), alone
//! or among good objects, are accepted, with or without stored levels of
//! detail, and read back: `check` finds no fault, a query answers them.

use mktree::bulk::{BuildError, BuildParams, LeafRule};
use mktree::db::{CreateOptions, Database, check};
use mktree::geom::{Axis, Point};
use mktree::lod::LodParams;
use mktree::scene::{Mesh, MeshError, Object, ObjectId, Scene};
use mktree::store::format::geometry::MAX_COORDINATE;

/// Small leaves, so that a few objects make internal nodes (splits).
fn params() -> BuildParams {
    BuildParams { leaf: LeafRule::Objects(2), ..BuildParams::paper() }
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
        w.bulk_load(scene, &params(), &|_| {}).and_then(|_| w.commit())
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

fn out_of_range(scene: &Scene) -> BuildError {
    match build_then_read(scene, false) {
        Err(mktree::Error::Build(e @ BuildError::OutOfRange { .. })) => e,
        other => panic!("expected the scene to be refused as out of range, got {other:?}"),
    }
}

#[test]
fn a_scene_beyond_the_format_range_is_refused_before_anything_is_written() {
    // Two groups of triangles 1e39 mm apart: the split between them did not even fit an f32.
    let far_apart = scene(
        (0..4)
            .map(|i| triangle_at(f64::from(i)))
            .chain((0..4).map(|i| triangle_at(1e39 + 1e24 * f64::from(i)))),
    );
    let e = out_of_range(&far_apart);
    let expected = BuildError::OutOfRange {
        object: ObjectId(4),
        axis: Axis::X,
        coordinate: 1e39,
        limit: MAX_COORDINATE,
    };
    assert_eq!(e, expected);
    let m = e.to_string();
    assert_eq!(m, "object 4: x = 1e39 mm is beyond the range of ±9007199254740992 mm a file holds");
    // A narrow scene far out: its anchors were written, and refused by every reader.
    let far = scene(
        (0..4).map(|i| mesh(&[[0.0, -1e20, 0.0], [1.0, -1e20, f64::from(i)], [0.0, -1e20 + 5e4, 1.0]])),
    );
    let e = out_of_range(&far);
    assert_eq!(
        e,
        BuildError::OutOfRange {
            object: ObjectId(0),
            axis: Axis::Y,
            coordinate: -1e20,
            limit: MAX_COORDINATE
        }
    );
    // Coordinates at either end of f64.
    let ends = scene([triangle_at(0.0), triangle_at(-1e308), triangle_at(1e308)]);
    assert!(matches!(out_of_range(&ends), BuildError::OutOfRange { object: ObjectId(1), .. }));
}

#[test]
fn a_scene_out_to_the_ends_of_the_range_builds_and_reads_back() {
    let max = MAX_COORDINATE;
    let edge = scene(
        (0..4)
            .map(|i| triangle_at(f64::from(i)))
            .chain([mesh(&[[-max, 0.0, 0.0], [-max + 2.0, 0.0, 0.0], [-max, 1.0, -max]])])
            .chain([mesh(&[[max - 2.0, max, 0.0], [max, max, 0.0], [max, max - 2.0, max]])]),
    );
    build_then_read(&edge, false).unwrap();
    let over = scene([triangle_at(0.0), mesh(&[[max, 0.0, 0.0], [max + 2.0, 0.0, 0.0], [max, 1.0, 0.0]])]);
    assert!(matches!(
        out_of_range(&over),
        BuildError::OutOfRange { object: ObjectId(1), coordinate: 9007199254740994.0, .. }
    ));
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
fn a_far_scene_within_the_range_reads_back() {
    // Anchors are f64: a scene far from the origin only needs a small span.
    let far = scene((0..6).map(|i| triangle_at(1e15 + 10.0 * f64::from(i))));
    build_then_read(&far, true).unwrap();
}
