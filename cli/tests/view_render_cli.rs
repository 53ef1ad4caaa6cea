//! Claim: `mktree view` prints the library's cut as JSON, `mktree render`
//! writes a PNG that decodes to the picture the library draws (the same
//! pixels), and a bad camera is a one-line error with a non-zero exit.

mod common;

use common::{mktree, tanker1_in};
use mktree::db::Database;
use mktree::render::{draw_cut, framing};
use mktree::{View, ViewOptions};

#[test]
fn view_prints_the_cut_and_render_writes_its_picture() {
    let dir = tempfile::tempdir().unwrap();
    let (_, mkt) = tanker1_in(dir.path());
    let file = mkt.to_str().unwrap();
    let camera = "-3000,-2500,2500,1960,967,654";
    let out = mktree()
        .args(["view", file, "--camera", camera, "--tolerance", "3", "--near", "50"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let db = Database::open_read_only(&mkt).unwrap();
    let r = db.begin_read().unwrap();
    let scene = r.root().unwrap().aabb;
    let view = View {
        eye: mktree::Point::new(-3000.0, -2500.0, 2500.0),
        target: mktree::Point::new(1960.0, 967.0, 654.0),
        fov_deg: 60.0,
        width_px: 1280,
        height_px: 720,
        near_mm: 50.0,
        far_mm: 1.0,
    }
    .seeing_all_of(&scene);
    let cut = r.view(&view, &ViewOptions { tolerance_px: 3.0, budget: None, shapes: true }, None).unwrap();
    assert_eq!(v["piece_count"], cut.nodes.len());
    assert_eq!(v["exact_objects"], cut.exact_objects());
    assert_eq!(v["max_error_px"], cut.max_error_px);
    assert!(cut.max_error_px <= 3.0);

    // The picture: the file decodes to the library's drawing, pixel for pixel.
    let png = dir.path().join("view.png");
    let (w, h) = (160, 100);
    let args =
        ["render", file, "--tolerance", "3", "--width-px", "160", "--height-px", "100", "--fov-deg", "40"];
    let out = mktree().args(args).arg("-o").arg(&png).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&png).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!((info.width, info.height, info.color_type), (w, h, png::ColorType::Rgb));
    // The CLI frames the scene as `framing` does, its near capped at --near's default.
    let framed = framing(&scene, w, h, 40.0);
    let framed = View { near_mm: framed.near_mm.min(100.0), ..framed }.seeing_all_of(&scene);
    let cut = r.view(&framed, &ViewOptions { tolerance_px: 3.0, budget: None, shapes: true }, None).unwrap();
    let img = draw_cut(&framed, &cut, db.lod_levels()).unwrap();
    assert!(img.coverage() > 1000, "the scene fills part of the picture");
    assert_eq!(&buf[..info.buffer_size()], &img.rgb[..]);

    // A vertical view direction has no "right" (up is +z): refused.
    let out = mktree().args(["view", file, "--camera", "0,0,5000,0,0,0"]).output().unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("vertical"), "{err}");
}
