//! Claim: the PNG chart `mktree tradeoff` writes has its title and axis
//! labels drawn, in the font the binary embeds, as its SVG has them as
//! text (bench-build, bench-peers and bench-view's PNGs are checked in
//! their own tests with the same rule, `common::assert_chart_has_text`).

mod common;

use common::{assert_chart_has_text, dark_pixels, mktree, read_png, tanker1_in};

#[test]
fn the_tradeoff_png_has_a_title_and_axis_labels() {
    let dir = tempfile::tempdir().unwrap();
    let (_, mkt) = tanker1_in(dir.path());
    let out = mktree()
        .arg("tradeoff")
        .arg(&mkt)
        .args(["--queries", "10", "--out"])
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let png = dir.path().join("tradeoff.png");
    assert_chart_has_text(&png);
    let svg = std::fs::read_to_string(dir.path().join("tradeoff.svg")).unwrap();
    for text in ["speed against accuracy", "mean block reads per query", "precision"] {
        assert!(svg.contains(text), "the SVG lacks {text:?}");
    }
    // The title is centred: glyph pixels on both sides of the middle.
    let (w, _, _) = read_png(&png);
    assert!(dark_pixels(&png, w / 4..w / 2, 0..40) > 50 && dark_pixels(&png, w / 2..3 * w / 4, 0..40) > 50);
}
