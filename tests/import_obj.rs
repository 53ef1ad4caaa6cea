//! Claim: OBJ import is the inverse of OBJ export for every scene whose
//! meshes use all their vertices; every kind of bad input is refused with a
//! message naming the file and the line or object; and no input, however
//! broken, makes the importer panic.
//!
//! `parse_speed_on_a_generated_scene` (ignored by default) measures import
//! speed: `cargo test --release --test import_obj -- --ignored --nocapture`,
//! with `MKTREE_SPEED_OBJECTS` objects (default 100,000); set
//! `MKTREE_SPEED_DIR` to keep the generated file there between runs.

use std::io::{BufWriter, Write};
use std::path::Path;
use std::time::Instant;

use mktree::geom::Point;
use mktree::scene::import::{ImportError, ImportOptions, load, read_obj};
use mktree::scene::{Mesh, ObjWriter, Object, Scene, write_obj};
use proptest::prelude::*;

fn read(text: &str) -> Result<mktree::scene::import::Imported, ImportError> {
    read_obj(text.as_bytes(), Path::new("models/hull.obj"))
}

/// A mesh of `points` whose triangles use every vertex: a fan over
/// consecutive triples, plus the extra triangles given.
fn mesh_using_every_vertex(points: &[Point], extra: &[[usize; 3]]) -> Mesh {
    let n = points.len();
    let mut triangles: Vec<[u32; 3]> =
        (0..n).step_by(2).map(|i| [i, (i + 1) % n, (i + 2) % n]).map(|t| t.map(|i| i as u32)).collect();
    triangles.extend(extra.iter().map(|t| t.map(|i| (i % n) as u32)));
    Mesh::from_world(points, triangles).unwrap()
}

fn arb_coordinate() -> impl Strategy<Value = f64> {
    prop_oneof![
        -1.0e4f64..1.0e4,
        (-10_000_000i64..10_000_000).prop_map(|i| i as f64 / 1000.0),
        -1.0e7f64..1.0e7,
        Just(0.0),
        -1.0e-3f64..1.0e-3,
    ]
}

fn arb_object() -> impl Strategy<Value = Object> {
    let points = prop::collection::vec(prop::array::uniform3(arb_coordinate()), 3..24);
    let extra = prop::collection::vec(prop::array::uniform3(0usize..64), 0..8);
    let name = "[A-Za-z0-9_$.é-]([A-Za-z0-9_$ .-]{0,12}[A-Za-z0-9_$.-])?";
    (name, points, extra).prop_map(|(name, points, extra)| {
        let points: Vec<Point> = points.into_iter().map(Point::from).collect();
        Object::new(name, mesh_using_every_vertex(&points, &extra))
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    #[test]
    fn import_of_export_is_the_same_scene(objects in prop::collection::vec(arb_object(), 1..12)) {
        let scene = Scene::new(objects);
        let text = write_obj(&scene, Vec::new()).unwrap();
        let imported = read_obj(text.as_slice(), Path::new("round-trip.obj")).unwrap();
        prop_assert_eq!(imported.scene, scene);
    }

    #[test]
    fn arbitrary_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..512)) {
        let _ = read_obj(bytes.as_slice(), Path::new("noise.obj"));
    }

    #[test]
    fn arbitrary_obj_like_lines_never_panic(lines in prop::collection::vec(arb_obj_line(), 0..40)) {
        let text = lines.join("\n");
        let _ = read_obj(text.as_bytes(), Path::new("lines.obj"));
    }
}

/// Lines built from OBJ's vocabulary, so the fuzzing reaches the parser's
/// deeper states (objects, faces, renumbering) instead of stopping at the
/// first bad keyword.
fn arb_obj_line() -> impl Strategy<Value = String> {
    let number = prop_oneof![
        Just("0".to_string()),
        Just("nan".to_string()),
        Just("-inf".to_string()),
        Just("1e308".to_string()),
        (-5i64..5).prop_map(|i| i.to_string()),
        any::<f64>().prop_map(|x| x.to_string()),
        "[-+.0-9eE]{0,6}",
    ];
    let index = prop_oneof![
        (-6i64..8).prop_map(|i| i.to_string()),
        Just("9223372036854775807".to_string()),
        Just("-9223372036854775808".to_string()),
        (-6i64..8, 0i64..3).prop_map(|(i, t)| format!("{i}/{t}/1")),
        (-6i64..8).prop_map(|i| format!("{i}//2")),
        "[-/0-9]{0,4}",
    ];
    prop_oneof![
        prop::collection::vec(number, 0..5).prop_map(|n| format!("v {}", n.join(" "))),
        prop::collection::vec(index, 0..6).prop_map(|i| format!("f {}", i.join(" "))),
        "[a-z ]{0,6}".prop_map(|name| format!("o {name}")),
        "[a-z ]{0,6}".prop_map(|name| format!("g {name}")),
        Just("# comment".to_string()),
        Just(String::new()),
        "[ -~]{0,12}",
    ]
}

#[test]
fn relative_indices_and_polygons_import_as_fans() {
    let text = "o quad\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf -4 -3 -2 -1\n";
    let imported = read(text).unwrap();
    assert_eq!(imported.scene.objects()[0].mesh.triangles(), &[[0, 1, 2], [0, 2, 3]]);
}

#[test]
fn faces_before_any_o_form_an_object_named_after_the_file() {
    let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\no named\nf 3 2 1\n";
    let names: Vec<String> = read(text).unwrap().scene.objects().iter().map(|o| o.name.clone()).collect();
    assert_eq!(names, ["hull", "named"]);
}

/// The message of the error for `text`, checked to name the file.
fn message(text: &str) -> String {
    let message = read(text).unwrap_err().to_string();
    assert!(message.starts_with("models/hull.obj: "), "does not name the file: {message}");
    message
}

#[test]
fn a_truncated_file_names_the_line_and_what_was_expected() {
    let scene = "o a\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\no b\nv 0 0 5\nv 1 0 5\nv 0 1.5 5\nf 4 5 6\n";
    // Cut inside the last vertex line and inside the last face line.
    let cut_vertex = &scene[..scene.find("v 0 1.5").unwrap() + 5];
    assert!(message(cut_vertex).contains("line 9: expected 3 coordinates after `v`, found \"0 1\""));
    let cut_face = &scene[..scene.len() - 3];
    assert!(
        message(cut_face).contains("line 10: expected at least 3 vertex indices after `f`, found \"4 5\"")
    );
    // Cut right after the `o` line: that object has no triangles.
    let cut_object = &scene[..scene.find("v 0 0 5").unwrap()];
    assert!(message(cut_object).ends_with("object \"b\" (line 6) has no triangles"));
}

#[test]
fn malformed_lines_name_the_line_and_what_was_expected() {
    assert!(message("v 1 2 three\n").contains("line 1: expected a number, found \"three\""));
    assert!(message("o a\nv 0 0 0\nf 1 1 one\n").contains("line 3: expected a vertex index"));
}

#[test]
fn nan_and_infinite_coordinates_name_the_line_and_object() {
    for bad in ["nan", "NaN", "inf", "-infinity", "1e400"] {
        let text = format!("o pipe\nv 0 0 0\nv 0 {bad} 0\n");
        let m = message(&text);
        assert!(m.contains("line 3: object \"pipe\" has a NaN or infinite coordinate"), "{bad}: {m}");
    }
}

#[test]
fn out_of_range_indices_name_the_line_index_and_object() {
    let text = "o valve\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n";
    assert!(message(text).contains("line 5: object \"valve\": vertex index 4 is out of range (3 vertices)"));
    let text = "o valve\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n";
    assert!(message(text).contains("line 5: object \"valve\": vertex index -4 is out of range"));
    // An index may only name a vertex defined on an earlier line.
    let text = "o valve\nf 1 2 3\nv 0 0 0\nv 1 0 0\nv 0 1 0\n";
    assert!(message(text).contains("line 2: object \"valve\": vertex index 1 is out of range (0 vertices)"));
}

#[test]
fn an_object_without_triangles_is_named_with_its_line() {
    let text = "o full\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\no empty\nv 5 5 5\no after\nf 1 2 3\n";
    assert!(message(text).ends_with("object \"empty\" (line 6) has no triangles"));
}

#[test]
fn a_file_without_objects_is_an_empty_scene() {
    let m = message("# made by hand\nv 0 0 0\nvn 0 0 1\n");
    assert!(m.contains("the scene is empty"), "{m}");
    assert!(matches!(read("").unwrap_err(), ImportError::EmptyScene { .. }));
}

#[test]
fn an_unreadable_file_names_the_path() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("absent.obj");
    let err = load(&missing, &ImportOptions::default()).unwrap_err();
    assert!(matches!(err, ImportError::Io { .. }), "{err}");
    assert!(err.to_string().contains(&*missing.to_string_lossy()), "{err}");
}

#[test]
fn an_unsupported_extension_names_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("scene.fbx");
    std::fs::write(&path, "Kaydara FBX").unwrap();
    let err = load(&path, &ImportOptions::default()).unwrap_err();
    assert!(matches!(err, ImportError::UnsupportedExtension { .. }), "{err}");
    assert!(err.to_string().contains("scene.fbx"), "{err}");
}

#[test]
fn degenerate_triangles_are_kept_and_counted() {
    let text = "o flat\nv 0 0 0\nv 1 0 0\nv 2 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 4\nf 4 4 1\n";
    let imported = read(text).unwrap();
    assert_eq!(imported.scene.triangle_count(), 3);
    assert_eq!(imported.degenerate_triangles, 2);
}

#[test]
fn load_reads_an_obj_file_with_an_upper_case_extension() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("DECK.OBJ");
    std::fs::write(&path, "o deck\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    let imported = load(&path, &ImportOptions::default()).unwrap();
    assert_eq!(imported.scene.objects()[0].name, "deck");
}

/// A scene of `objects` capped prisms, from boxes (4 sides, 12 triangles)
/// to 16-sided pipes (60 triangles), about 1.8 kB of OBJ each as the
/// generator's scenes are (10^6 objects ~ 2 GB), laid out on a grid and
/// written with `ObjWriter`. Returns the number of triangles.
fn write_pipes(path: &Path, objects: usize) -> usize {
    let mut writer = ObjWriter::new(BufWriter::with_capacity(1 << 20, std::fs::File::create(path).unwrap()));
    let mut triangles = 0;
    for i in 0..objects {
        let sides = 4 + (i * 7) % 13;
        let (x, y) = ((i % 1000) as f64 * 500.0, (i / 1000) as f64 * 500.0);
        let (radius, length) = (20.0 + (i % 13) as f64 * 7.25, 300.0 + (i % 17) as f64 * 41.5);
        let mut points = Vec::with_capacity(2 * sides);
        for z in [0.0, length] {
            for s in 0..sides {
                let a = std::f64::consts::TAU * s as f64 / sides as f64;
                let p = [x + radius * a.cos(), y + radius * a.sin(), 1000.0 + z];
                // Millimetres to three decimals, as real scenes store them.
                points.push(Point::from(p.map(|c| (c * 1000.0).round() / 1000.0)));
            }
        }
        let sides32 = sides as u32;
        let mut tris = Vec::with_capacity(4 * sides);
        for s in 0..sides32 {
            let t = (s + 1) % sides32;
            tris.push([s, t, sides32 + t]);
            tris.push([s, sides32 + t, sides32 + s]);
        }
        for s in 1..sides32 - 1 {
            tris.push([0, s + 1, s]);
            tris.push([sides32, sides32 + s, sides32 + s + 1]);
        }
        triangles += tris.len();
        writer
            .write_object(&Object::new(format!("pipe_{i}"), Mesh::from_world(&points, tris).unwrap()))
            .unwrap();
    }
    writer.finish().unwrap().flush().unwrap();
    triangles
}

#[test]
#[ignore = "measurement: run in release mode with --ignored --nocapture"]
fn parse_speed_on_a_generated_scene() {
    let objects: usize =
        std::env::var("MKTREE_SPEED_OBJECTS").ok().and_then(|s| s.parse().ok()).unwrap_or(100_000);
    // MKTREE_SPEED_DIR keeps the generated file, to time repeated imports.
    let temporary = tempfile::tempdir().unwrap();
    let dir = std::env::var_os("MKTREE_SPEED_DIR").map_or(temporary.path().to_path_buf(), Into::into);
    let path = dir.join(format!("pipes-{objects}.obj"));
    let triangles = match std::fs::read(dir.join(format!("pipes-{objects}.triangles"))) {
        Ok(count) if path.exists() => String::from_utf8(count).unwrap().parse().unwrap(),
        _ => {
            let triangles = write_pipes(&path, objects);
            std::fs::write(dir.join(format!("pipes-{objects}.triangles")), triangles.to_string()).unwrap();
            triangles
        }
    };
    let bytes = std::fs::metadata(&path).unwrap().len();
    // Read once to warm the page cache, so the timing is the parser's.
    std::io::copy(&mut std::fs::File::open(&path).unwrap(), &mut std::io::sink()).unwrap();
    let start = Instant::now();
    let imported = load(&path, &ImportOptions::default()).unwrap();
    let seconds = start.elapsed().as_secs_f64();
    assert_eq!((imported.scene.len(), imported.scene.triangle_count()), (objects, triangles));
    eprintln!(
        "imported {objects} objects, {triangles} triangles, {:.1} MB of OBJ in {seconds:.2} s: \
         {:.1} M triangles/s, {:.0} MB/s",
        bytes as f64 / 1e6,
        triangles as f64 / seconds / 1e6,
        bytes as f64 / seconds / 1e6
    );
}
