//! What the CLI tests share: the binary, and a generated scene built into a file.
#![allow(dead_code)]

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

pub fn mktree() -> Command {
    Command::new(env!("CARGO_BIN_EXE_mktree"))
}

/// tanker1 generated and built in `dir` with 4 KiB blocks: (t1.obj, t1.mkt).
pub fn tanker1_in(dir: &Path) -> (PathBuf, PathBuf) {
    let (obj, mkt) = (dir.join("t1.obj"), dir.join("t1.mkt"));
    for args in [
        vec!["gen", "tanker1", "-o", obj.to_str().unwrap()],
        vec!["build", obj.to_str().unwrap(), "-o", mkt.to_str().unwrap(), "--block-size", "4096"],
    ] {
        let out = mktree().args(&args).output().unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    }
    (obj, mkt)
}

/// The PNG at `path`: (width, height, RGB pixels row by row).
pub fn read_png(path: &Path) -> (u32, u32, Vec<[u8; 3]>) {
    let decoder = png::Decoder::new(std::fs::File::open(path).unwrap());
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size()];
    let frame = reader.next_frame(&mut buf).unwrap();
    let step = match frame.color_type {
        png::ColorType::Rgb => 3,
        png::ColorType::Rgba => 4,
        other => panic!("{}: colour type {other:?}", path.display()),
    };
    assert_eq!(frame.bit_depth, png::BitDepth::Eight, "{}", path.display());
    let pixels = buf[..frame.buffer_size()].chunks(step).map(|p| [p[0], p[1], p[2]]).collect();
    (frame.width, frame.height, pixels)
}

/// Pixels of the PNG at `path` in columns `x` and rows `y` dark enough to
/// be glyphs (every channel below 110: the charts' text is black, their
/// series coloured, their grid light grey).
pub fn dark_pixels(path: &Path, x: std::ops::Range<u32>, y: std::ops::Range<u32>) -> usize {
    let (w, h, pixels) = read_png(path);
    (y.start..y.end.min(h))
        .flat_map(|row| (x.start..x.end.min(w)).map(move |col| (row * w + col) as usize))
        .filter(|&i| pixels[i].iter().all(|&c| c < 110))
        .count()
}

/// Asserts that the chart at `path` has text where a title, the y axis's
/// label and the x axis's label go: glyph pixels in its top 40 rows (the
/// title; only text is drawn there), in its 30 leftmost columns (the y
/// label, turned) and in its 26 bottom rows (the x label). A chart drawn
/// without text has none in any of the three.
pub fn assert_chart_has_text(path: &Path) {
    let (w, h, _) = read_png(path);
    let bands = [
        ("title (top 40 rows)", dark_pixels(path, 0..w, 0..40), 200),
        ("y label (left 30 columns)", dark_pixels(path, 0..30, 0..h), 25),
        ("x label (bottom 26 rows)", dark_pixels(path, 0..w, h.saturating_sub(26)..h), 60),
    ];
    for (band, found, least) in bands {
        assert!(
            found >= least,
            "{}: {found} glyph pixels in the {band}, expected {least} or more",
            path.display()
        );
    }
}

/// Runs `mktree batch FILE` with `args`, `input` on stdin written by
/// another thread (so a large input cannot deadlock against the output).
pub fn batch_with(
    mkt: &Path,
    args: &[&str],
    input: Vec<u8>,
) -> (std::process::ExitStatus, Vec<serde_json::Value>, String) {
    let mut child = mktree()
        .arg("batch")
        .arg(mkt)
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdin = child.stdin.take().unwrap();
    let writer = std::thread::spawn(move || {
        // The server may stop reading early on failure; the test then fails on its output.
        let _ = stdin.write_all(&input);
    });
    let out = child.wait_with_output().unwrap();
    writer.join().unwrap();
    let answers =
        String::from_utf8(out.stdout).unwrap().lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    (out.status, answers, String::from_utf8_lossy(&out.stderr).into_owned())
}

/// Kills the server when the test ends, pass or fail.
pub struct Serving(pub std::process::Child);

impl Drop for Serving {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Starts `mktree serve DIR/tiles` on a free port with stand-in packages;
/// the server and its port.
pub fn serve(dir: &Path) -> (Serving, u16) {
    use std::io::BufRead;
    let vendor = dir.join("vendor");
    std::fs::create_dir_all(vendor.join("three")).unwrap();
    std::fs::create_dir_all(vendor.join("3d-tiles-renderer")).unwrap();
    let mut child = mktree()
        .arg("serve")
        .arg(dir.join("tiles"))
        .args(["--port", "0", "--vendor"])
        .arg(&vendor)
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let mut line = String::new();
    std::io::BufReader::new(child.stdout.take().unwrap()).read_line(&mut line).unwrap();
    assert!(line.contains("http://127.0.0.1:"), "{line}");
    let port = line.trim().rsplit(':').next().unwrap().trim_end_matches('/').parse().unwrap();
    (Serving(child), port)
}
