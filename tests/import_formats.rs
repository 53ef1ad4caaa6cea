//! Claim: STL (ASCII and binary), directories of OBJ/STL files and glTF 2.0
//! (`.gltf` with external or embedded buffers, `.glb`) import as the
//! documented objects: one per file, or one per glTF mesh instance with its
//! world transform; bad files fail with a message naming the file and the
//! facet, node or accessor; and no bytes make the importer panic.
//!
//! The small files are made here: STL with `stl_io` or by hand, glTF as JSON
//! plus a little-endian binary buffer.

use std::path::{Path, PathBuf};

use mktree::geom::Point;
use mktree::scene::import::{ImportError, ImportOptions, Imported, UriRefusal, load};
use mktree::scene::{Object, Scene};
use proptest::prelude::*;
use serde_json::{Value, json};

const MM: ImportOptions = ImportOptions { gltf_scale: 1.0 };

fn write(dir: &Path, name: &str, bytes: impl AsRef<[u8]>) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

fn names(scene: &Scene) -> Vec<&str> {
    scene.objects().iter().map(|o| o.name.as_str()).collect()
}

fn assert_points_near(object: &Object, expected: &[[f64; 3]]) {
    let got: Vec<Point> = object.mesh.vertices().collect();
    assert_eq!(got.len(), expected.len(), "{}: {got:?}", object.name);
    for (g, e) in got.iter().zip(expected) {
        assert!((g - Point::from(*e)).norm() < 1e-5, "{}: {got:?} is not {expected:?}", object.name);
    }
}

// ---------------------------------------------------------------- STL

const ASCII_STL: &str = "solid bracket
  facet normal 0 0 1
    outer loop
      vertex 0 0 0
      vertex 10.5 0 0
      vertex 10.5 20.25 0
    endloop
  endfacet
  facet normal 0 0 1
    outer loop
      vertex 0 0 0
      vertex 10.5 20.25 0
      vertex 0 20.25 0
    endloop
  endfacet
endsolid bracket
";

fn binary_stl(triangles: &[[[f32; 3]; 3]]) -> Vec<u8> {
    let mesh: Vec<stl_io::Triangle> = triangles
        .iter()
        .map(|t| stl_io::Triangle {
            normal: stl_io::Normal::new([0.0; 3]),
            vertices: t.map(stl_io::Vertex::new),
        })
        .collect();
    let mut bytes = Vec::new();
    stl_io::write_stl(&mut bytes, mesh.iter()).unwrap();
    bytes
}

#[test]
fn ascii_stl_is_one_object_named_by_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = write(dir.path(), "bracket.stl", ASCII_STL);
    let imported = load(&path, &MM).unwrap();
    assert_eq!(names(&imported.scene), ["bracket"]);
    let object = &imported.scene.objects()[0];
    assert_eq!(object.mesh.triangles(), &[[0, 1, 2], [0, 2, 3]]);
    assert_points_near(object, &[[0.0, 0.0, 0.0], [10.5, 0.0, 0.0], [10.5, 20.25, 0.0], [0.0, 20.25, 0.0]]);
}

#[test]
fn binary_stl_is_one_object_and_counts_degenerate_facets() {
    let dir = tempfile::tempdir().unwrap();
    let a = [0.0, 0.0, 0.0];
    let b = [1.0, 0.0, 0.0];
    let c = [0.0, 1.0, 0.0];
    let path = write(dir.path(), "Plate.STL", binary_stl(&[[a, b, c], [a, b, [2.0, 0.0, 0.0]], [a, c, c]]));
    let imported = load(&path, &MM).unwrap();
    assert_eq!(names(&imported.scene), ["Plate"]);
    assert_eq!((imported.scene.triangle_count(), imported.degenerate_triangles), (3, 2));
}

#[test]
fn truncated_and_malformed_stl_name_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let mut bytes = binary_stl(&[[[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]; 4]);
    bytes.truncate(200);
    let path = write(dir.path(), "cut.stl", &bytes);
    let err = load(&path, &MM).unwrap_err();
    assert!(matches!(err, ImportError::Truncated { facets: 4, .. }), "{err}");
    assert!(err.to_string().contains("cut.stl: truncated: the header announces 4 facets"), "{err}");

    let path = write(dir.path(), "bad.stl", ASCII_STL.replace("vertex 10.5 0 0", "vertex 10.5 zero 0"));
    let err = load(&path, &MM).unwrap_err().to_string();
    assert!(err.contains("bad.stl: STL: facet 0:"), "{err}");
}

// ---------------------------------------------------------------- directories

#[test]
fn a_directory_is_one_object_per_file_in_name_order() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), "c_valve.STL", ASCII_STL);
    write(dir.path(), "b_pipe.stl", binary_stl(&[[[0.0; 3], [0.0, 0.0, 5.0], [0.0, 5.0, 0.0]]]));
    let obj = "o top\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\no bottom\nv 0 0 -1\nf 1 2 4\n";
    write(dir.path(), "a_deck.obj", obj);
    write(dir.path(), "notes.txt", "not a model");
    std::fs::create_dir(dir.path().join("d_sub.obj")).unwrap();
    write(&dir.path().join("d_sub.obj"), "inner.obj", obj);

    let imported = load(dir.path(), &MM).unwrap();
    assert_eq!(names(&imported.scene), ["a_deck", "b_pipe", "c_valve"]);
    // The OBJ file's two `o` objects are one object here.
    let deck = &imported.scene.objects()[0];
    assert_eq!((deck.mesh.vertex_count(), deck.mesh.triangle_count()), (4, 2));
}

#[test]
fn a_directory_without_models_is_an_empty_scene() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), "readme.md", "# nothing");
    let err = load(dir.path(), &MM).unwrap_err();
    assert!(matches!(err, ImportError::EmptyScene { .. }), "{err}");
}

// ---------------------------------------------------------------- glTF

/// The binary buffer of the test document: two sets of four positions and
/// six u16 indices.
fn buffer_bytes() -> Vec<u8> {
    let plate = [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]];
    let wall = [[0.0f32, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 1.0]];
    let mut bytes: Vec<u8> = plate.iter().chain(&wall).flatten().flat_map(|c| c.to_le_bytes()).collect();
    bytes.extend([0u16, 1, 2, 0, 2, 3].iter().flat_map(|i| i.to_le_bytes()));
    bytes
}

/// A document with a node hierarchy: root (translated) -> plate scaled by
/// 2, and -> a rotated wall (triangle strip plus a line primitive) -> plate
/// moved by a matrix; a lines-only mesh; a mirrored plate; and a second
/// scene with one more plate. `buffer` is the buffer object.
fn document(buffer: Value) -> Value {
    let half = std::f64::consts::FRAC_1_SQRT_2;
    json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0, 4, 6]}, {"nodes": [5]}],
        "nodes": [
            {"name": "root", "translation": [10.0, 0.0, 0.0], "children": [1, 2]},
            {"mesh": 0, "scale": [2.0, 2.0, 2.0]},
            {"mesh": 1, "rotation": [0.0, 0.0, half, half], "children": [3]},
            {"mesh": 0, "matrix": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 5, 1]},
            {"mesh": 2},
            {"mesh": 0},
            {"mesh": 0, "scale": [-1.0, 1.0, 1.0]}
        ],
        "meshes": [
            {"name": "plate", "primitives": [{"attributes": {"POSITION": 0}, "indices": 2}]},
            {"primitives": [
                {"attributes": {"POSITION": 1}, "mode": 5},
                {"attributes": {"POSITION": 1}, "mode": 1}
            ]},
            {"name": "wire", "primitives": [{"attributes": {"POSITION": 1}, "mode": 3}]}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
             "min": [0.0, 0.0, 0.0], "max": [1.0, 1.0, 0.0]},
            {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC3",
             "min": [0.0, 0.0, 0.0], "max": [0.0, 1.0, 1.0]},
            {"bufferView": 2, "componentType": 5123, "count": 6, "type": "SCALAR"}
        ],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 48},
            {"buffer": 0, "byteOffset": 48, "byteLength": 48},
            {"buffer": 0, "byteOffset": 96, "byteLength": 12}
        ],
        "buffers": [buffer]
    })
}

/// A GLB file: header, JSON chunk (space padded), BIN chunk (zero padded).
fn glb(document: &Value, bin: &[u8]) -> Vec<u8> {
    let mut json = serde_json::to_vec(document).unwrap();
    json.resize(json.len().next_multiple_of(4), b' ');
    let mut bin = bin.to_vec();
    bin.resize(bin.len().next_multiple_of(4), 0);
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut bytes = Vec::with_capacity(total);
    bytes.extend_from_slice(b"glTF");
    bytes.extend_from_slice(&2u32.to_le_bytes());
    bytes.extend_from_slice(&(total as u32).to_le_bytes());
    for (chunk, kind) in [(&json, b"JSON"), (&bin, b"BIN\0")] {
        bytes.extend_from_slice(&(chunk.len() as u32).to_le_bytes());
        bytes.extend_from_slice(kind);
        bytes.extend_from_slice(chunk);
    }
    bytes
}

fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::new();
    for chunk in bytes.chunks(3) {
        let n = chunk.iter().enumerate().fold(0u32, |n, (i, &b)| n | u32::from(b) << (16 - 8 * i));
        for i in 0..4 {
            let symbol = if i <= chunk.len() { ALPHABET[(n >> (18 - 6 * i) & 63) as usize] } else { b'=' };
            out.push(char::from(symbol));
        }
    }
    out
}

/// Checks the objects that `document` gives for its default scene.
fn assert_default_scene(imported: &Imported) {
    let scene = &imported.scene;
    assert_eq!(names(scene), ["plate_node1", "mesh1_node2", "plate_node3", "plate_node6"]);
    let objects = scene.objects();
    // root * scale 2.
    assert_points_near(
        &objects[0],
        &[[10.0, 0.0, 0.0], [12.0, 0.0, 0.0], [12.0, 2.0, 0.0], [10.0, 2.0, 0.0]],
    );
    // root * quarter turn about z: (x, y, z) -> (-y, x, z); a strip of 4 is 2 triangles.
    assert_points_near(&objects[1], &[[10.0, 0.0, 0.0], [9.0, 0.0, 0.0], [10.0, 0.0, 1.0], [9.0, 0.0, 1.0]]);
    assert_eq!(objects[1].mesh.triangles(), &[[0, 1, 2], [1, 3, 2]]);
    // root * turn * (move 5 up by matrix): parent * child.
    assert_points_near(&objects[2], &[[10.0, 0.0, 5.0], [10.0, 1.0, 5.0], [9.0, 1.0, 5.0], [9.0, 0.0, 5.0]]);
    // A mirror reverses the winding, so faces keep their side.
    assert_points_near(&objects[3], &[[0.0, 0.0, 0.0], [-1.0, 0.0, 0.0], [-1.0, 1.0, 0.0], [0.0, 1.0, 0.0]]);
    assert_eq!(objects[3].mesh.triangles(), &[[0, 2, 1], [0, 3, 2]]);
    assert_eq!(imported.degenerate_triangles, 0);
}

#[test]
fn gltf_with_an_external_buffer_applies_world_transforms() {
    let dir = tempfile::tempdir().unwrap();
    let bin = buffer_bytes();
    write(dir.path(), "parts.bin", &bin);
    let doc = document(json!({"uri": "parts.bin", "byteLength": bin.len()}));
    let path = write(dir.path(), "assembly.gltf", serde_json::to_vec(&doc).unwrap());
    assert_default_scene(&load(&path, &MM).unwrap());
}

#[test]
fn gltf_with_an_embedded_buffer_imports_the_same() {
    let dir = tempfile::tempdir().unwrap();
    let bin = buffer_bytes();
    let uri = format!("data:application/octet-stream;base64,{}", base64(&bin));
    let doc = document(json!({"uri": uri, "byteLength": bin.len()}));
    let path = write(dir.path(), "assembly.gltf", serde_json::to_vec(&doc).unwrap());
    assert_default_scene(&load(&path, &MM).unwrap());
}

#[test]
fn glb_imports_the_same_as_gltf() {
    let dir = tempfile::tempdir().unwrap();
    let bin = buffer_bytes();
    let doc = document(json!({"byteLength": bin.len()}));
    let path = write(dir.path(), "assembly.GLB", glb(&doc, &bin));
    assert_default_scene(&load(&path, &MM).unwrap());
}

#[test]
fn gltf_metres_become_millimetres_by_default() {
    let dir = tempfile::tempdir().unwrap();
    let bin = buffer_bytes();
    let path = write(dir.path(), "a.glb", glb(&document(json!({"byteLength": bin.len()})), &bin));
    let imported = load(&path, &ImportOptions::default()).unwrap();
    assert_eq!(ImportOptions::default().gltf_scale, 1000.0);
    assert_points_near(
        &imported.scene.objects()[0],
        &[[1e4, 0.0, 0.0], [1.2e4, 0.0, 0.0], [1.2e4, 2e3, 0.0], [1e4, 2e3, 0.0]],
    );
}

#[test]
fn without_a_default_scene_every_scene_is_imported() {
    let dir = tempfile::tempdir().unwrap();
    let bin = buffer_bytes();
    let mut doc = document(json!({"byteLength": bin.len()}));
    doc.as_object_mut().unwrap().remove("scene");
    let path = write(dir.path(), "all.glb", glb(&doc, &bin));
    let imported = load(&path, &MM).unwrap();
    assert_eq!(
        names(&imported.scene),
        ["plate_node1", "mesh1_node2", "plate_node3", "plate_node6", "plate_node5"]
    );
}

/// The error for the test document after `edit`, as a .glb file.
fn glb_error(edit: impl FnOnce(&mut Value)) -> String {
    let dir = tempfile::tempdir().unwrap();
    let bin = buffer_bytes();
    let mut doc = document(json!({"byteLength": bin.len()}));
    edit(&mut doc);
    let path = write(dir.path(), "broken.glb", glb(&doc, &bin));
    let message = load(&path, &MM).unwrap_err().to_string();
    assert!(message.contains("broken.glb: "), "does not name the file: {message}");
    message
}

#[test]
fn gltf_errors_name_the_file_and_the_node_mesh_or_accessor() {
    // Triangles whose index count is not a multiple of 3.
    let m = glb_error(|doc| doc["accessors"][2]["count"] = json!(4));
    assert!(m.contains("node 1, mesh 0, primitive 0: 4 vertex indices do not make whole triangles"), "{m}");
    // An accessor longer than its view.
    let m = glb_error(|doc| doc["accessors"][0]["count"] = json!(5));
    assert!(
        m.contains("node 1, mesh 0, primitive 0: accessor 0 reaches past the end of buffer view 0"),
        "{m}"
    );
    // Positions that are not f32 triples.
    let m = glb_error(|doc| doc["accessors"][0]["type"] = json!("VEC2"));
    assert!(m.contains("accessor 0 is Vec2 F32"), "{m}");
    // A cycle in the node hierarchy.
    let m = glb_error(|doc| doc["nodes"][3]["children"] = json!([2]));
    assert!(m.contains("node 2 occurs twice in the hierarchy of scene 0"), "{m}");
    // A POSITION accessor that does not exist (gltf-json's validation
    // would index with it), and a reference to a missing node.
    let m = glb_error(|doc| doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = json!(7));
    assert!(m.contains("glTF: mesh 0, primitive 0: POSITION names accessor 7, but there are 3"), "{m}");
    let m = glb_error(|doc| doc["scenes"][0]["nodes"] = json!([42]));
    assert!(m.contains("glTF: invalid glTF"), "{m}");
    // A scene whose meshes are only lines.
    let m = glb_error(|doc| doc["scenes"][0]["nodes"] = json!([4]));
    assert!(m.contains("the scene is empty"), "{m}");
}

#[test]
fn an_index_past_the_positions_names_object_and_primitive() {
    let dir = tempfile::tempdir().unwrap();
    let mut bin = buffer_bytes();
    // Index 3 of the plate becomes 9: the plate has 4 positions.
    bin[96 + 2 * 5] = 9;
    let path = write(dir.path(), "bad_index.glb", glb(&document(json!({"byteLength": bin.len()})), &bin));
    let m = load(&path, &MM).unwrap_err().to_string();
    assert!(
        m.contains("bad_index.glb: node 1, mesh 0, primitive 0: object \"plate_node1\": vertex index 9 is out of range (4 vertices)"),
        "{m}"
    );
}

#[test]
fn broken_gltf_files_are_refused_with_their_name() {
    let dir = tempfile::tempdir().unwrap();
    let path = write(dir.path(), "text.gltf", "{ not json");
    let m = load(&path, &MM).unwrap_err().to_string();
    assert!(m.starts_with(&format!("{}: glTF: ", path.display())), "{m}");

    let bin = buffer_bytes();
    let whole = glb(&document(json!({"byteLength": bin.len()})), &bin);
    for cut in [0, 5, 12, 19, 40, whole.len() - 1] {
        let path = write(dir.path(), "cut.glb", &whole[..cut]);
        let m = load(&path, &MM).unwrap_err().to_string();
        assert!(m.contains("cut.glb: "), "cut at {cut}: {m}");
    }

    let doc = document(json!({"uri": "missing.bin", "byteLength": 108}));
    let path = write(dir.path(), "lonely.gltf", serde_json::to_vec(&doc).unwrap());
    let e = load(&path, &MM).unwrap_err();
    assert!(matches!(&e, ImportError::Io { file, .. } if file.ends_with("missing.bin")), "{e:?}");
}

// ------------------------------------------------- glTF buffer URIs

/// Loads `<root>/scene/assembly.gltf`, the test document with one buffer
/// of `uri` declaring `byte_length` bytes (and `extra` merged into the
/// document), with `parts.bin` in `<root>/scene/bin/` and a copy of it,
/// the "secret", in `<root>/outside/`.
fn load_buffer_uri(
    root: &Path,
    uri: &str,
    byte_length: usize,
    extra: Value,
) -> Result<Imported, ImportError> {
    let bin = buffer_bytes();
    for folder in ["scene/bin", "outside"] {
        std::fs::create_dir_all(root.join(folder)).unwrap();
    }
    write(&root.join("scene/bin"), "parts one.bin", &bin);
    write(&root.join("outside"), "secret.bin", &bin);
    let mut doc = document(json!({"uri": uri, "byteLength": byte_length}));
    if let (Some(doc), Value::Object(extra)) = (doc.as_object_mut(), extra) {
        doc.extend(extra);
    }
    let path = write(&root.join("scene"), "assembly.gltf", serde_json::to_vec(&doc).unwrap());
    load(&path, &MM)
}

/// The refusal of `uri` (as a buffer URI of the test document), checked to
/// name the URI in its message.
fn refused_uri(root: &Path, uri: &str, byte_length: usize) -> UriRefusal {
    match load_buffer_uri(root, uri, byte_length, json!({})) {
        Err(e @ ImportError::BufferUri { .. }) => {
            let message = e.to_string();
            assert!(message.contains(&format!("{uri:?}")), "does not name the URI: {message}");
            assert!(message.contains("assembly.gltf: "), "does not name the file: {message}");
            let ImportError::BufferUri { buffer, reason, .. } = e else { unreachable!() };
            assert_eq!(buffer, 0);
            reason
        }
        other => panic!("{uri}: expected a refused URI, got {other:?}"),
    }
}

#[test]
fn a_buffer_uri_in_a_subfolder_is_read_and_images_are_never_opened() {
    let dir = tempfile::tempdir().unwrap();
    let bin = buffer_bytes();
    // Images are never needed for geometry: not even ones that would be refused as buffers.
    let images =
        json!({"images": [{"uri": "/dev/zero"}, {"uri": "../outside/secret.bin"}, {"uri": "none.png"}]});
    for uri in ["bin/parts%20one.bin", "./bin/../bin/parts one.bin"] {
        let imported = load_buffer_uri(dir.path(), uri, bin.len(), images.clone()).unwrap();
        assert_default_scene(&imported);
    }
}

#[test]
fn absolute_and_foreign_scheme_buffer_uris_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let secret = dir.path().join("outside/secret.bin");
    let len = buffer_bytes().len();
    // Before this was refused, /dev/zero was read until memory ran out.
    assert_eq!(refused_uri(dir.path(), "/dev/zero", 1 << 40), UriRefusal::Absolute);
    assert_eq!(refused_uri(dir.path(), secret.to_str().unwrap(), len), UriRefusal::Absolute);
    let file_uri = format!("file://{}", secret.display());
    assert_eq!(refused_uri(dir.path(), &file_uri, len), UriRefusal::Scheme);
    assert_eq!(refused_uri(dir.path(), "https://example.com/parts.bin", len), UriRefusal::Scheme);
}

#[test]
fn buffer_uris_that_leave_the_folder_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let len = buffer_bytes().len();
    for uri in ["../outside/secret.bin", "bin/../../outside/secret.bin", "%2E%2E/outside/secret.bin"] {
        assert_eq!(refused_uri(dir.path(), uri, len), UriRefusal::OutsideFolder, "{uri}");
    }
}

#[cfg(unix)]
#[test]
fn a_symbolic_link_out_of_the_folder_is_refused_and_one_within_it_is_followed() {
    let dir = tempfile::tempdir().unwrap();
    let len = buffer_bytes().len();
    std::fs::create_dir_all(dir.path().join("scene/bin")).unwrap();
    std::os::unix::fs::symlink("../../outside/secret.bin", dir.path().join("scene/bin/leak.bin")).unwrap();
    std::os::unix::fs::symlink("/dev/zero", dir.path().join("scene/zero.bin")).unwrap();
    assert_eq!(refused_uri(dir.path(), "bin/leak.bin", len), UriRefusal::OutsideFolder);
    assert_eq!(refused_uri(dir.path(), "zero.bin", len), UriRefusal::OutsideFolder);
    std::os::unix::fs::symlink("bin/parts one.bin", dir.path().join("scene/alias.bin")).unwrap();
    assert_default_scene(&load_buffer_uri(dir.path(), "alias.bin", len, json!({})).unwrap());
}

#[cfg(unix)]
#[test]
fn a_pipe_or_a_folder_is_not_a_buffer_file() {
    let dir = tempfile::tempdir().unwrap();
    let len = buffer_bytes().len();
    std::fs::create_dir_all(dir.path().join("scene")).unwrap();
    let fifo = dir.path().join("scene/pipe.bin");
    // Opening a pipe for reading would wait for a writer forever.
    let made = std::process::Command::new("mkfifo").arg(&fifo).status().unwrap();
    assert!(made.success());
    assert_eq!(refused_uri(dir.path(), "pipe.bin", len), UriRefusal::NotAFile);
    assert_eq!(refused_uri(dir.path(), "bin", len), UriRefusal::NotAFile);
}

#[test]
fn a_buffer_file_shorter_than_its_byte_length_is_refused_and_a_longer_one_is_cut() {
    let dir = tempfile::tempdir().unwrap();
    let len = buffer_bytes().len() as u64;
    assert_eq!(
        refused_uri(dir.path(), "bin/parts one.bin", 1 << 40),
        UriRefusal::Short { declared: 1 << 40, actual: len }
    );
    // Reading stops at byteLength: an accessor past it is out of its buffer.
    let m = load_buffer_uri(dir.path(), "bin/parts one.bin", 100, json!({})).unwrap_err().to_string();
    assert!(m.contains("accessor 2 reaches past the end of buffer view 2"), "{m}");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn arbitrary_bytes_never_panic_in_any_format(bytes in prop::collection::vec(any::<u8>(), 0..400)) {
        let dir = tempfile::tempdir().unwrap();
        for name in ["x.stl", "x.glb", "x.gltf", "x.obj"] {
            let _ = load(&write(dir.path(), name, &bytes), &MM);
        }
    }

    #[test]
    fn corrupted_glb_and_stl_files_never_panic(
        flips in prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..6),
        cut in any::<prop::sample::Index>(),
    ) {
        let dir = tempfile::tempdir().unwrap();
        let bin = buffer_bytes();
        let sources = [
            ("x.glb", glb(&document(json!({"byteLength": bin.len()})), &bin)),
            ("x.stl", binary_stl(&[[[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]; 3])),
            ("y.stl", ASCII_STL.as_bytes().to_vec()),
        ];
        for (name, mut bytes) in sources {
            for (at, value) in &flips {
                let i = at.index(bytes.len());
                bytes[i] = *value;
            }
            let _ = load(&write(dir.path(), name, &bytes), &MM);
            let keep = cut.index(bytes.len());
            let _ = load(&write(dir.path(), name, &bytes[..keep]), &MM);
        }
    }
}
