//! Claim: a picture of a view's cut covers every pixel the exact picture
//! covers (stand-ins hold what they stand for), and draws nothing farther
//! than the tolerance (stretched by perspective off the axis of view) from
//! what the exact picture draws; at τ = 0 the two pictures are the same.
//! One node's b(S_n,k) is drawn as a solid that holds its objects' picture.

mod common;

use common::lod_db;
use mktree::geom::Point;
use mktree::lod::LodParams;
use mktree::query::{View, ViewOptions};
use mktree::render::{Image, draw_cut, draw_level, framing};
use mktree::scene::generate::{GenOptions, Preset, generate_scene};

/// The drawn pixels of `img` grown by `r` pixels (a square of side 2r + 1).
fn grown(img: &Image, r: u32) -> Vec<bool> {
    let (w, h) = (img.width, img.height);
    let mut rows = vec![false; (w * h) as usize];
    for y in 0..h {
        for x in 0..w {
            if img.drawn(x, y) {
                for dx in x.saturating_sub(r)..=(x + r).min(w - 1) {
                    rows[(y * w + dx) as usize] = true;
                }
            }
        }
    }
    let mut out = vec![false; (w * h) as usize];
    for y in 0..h {
        for x in 0..w {
            if rows[(y * w + x) as usize] {
                for dy in y.saturating_sub(r)..=(y + r).min(h - 1) {
                    out[(dy * w + x) as usize] = true;
                }
            }
        }
    }
    out
}

/// Pixels drawn in `a` and not in `b` (grown by `r`).
fn outside(a: &Image, b: &Image, r: u32) -> u64 {
    let g = grown(b, r);
    let mut n = 0;
    for y in 0..a.height {
        for x in 0..a.width {
            n += u64::from(a.drawn(x, y) && !g[(y * a.width + x) as usize]);
        }
    }
    n
}

#[test]
fn the_cuts_picture_covers_the_exact_one_and_strays_at_most_the_tolerance() {
    let scene = generate_scene(&GenOptions { preset: Preset::Tanker1, objects: None, seed: 7 }).unwrap();
    let db = lod_db(&scene, 4, 4096, 10, LodParams { store_all: true, ..LodParams::default() });
    let r = db.begin_read().unwrap();
    let b = scene.aabb();
    let c = b.center();
    let view = View {
        eye: Point::new(b.min.x - 0.3 * b.extent().x, c.y - 0.4 * b.extent().y, c.z + 0.3 * b.extent().z),
        target: c,
        fov_deg: 50.0,
        width_px: 240,
        height_px: 160,
        near_mm: 10.0,
        far_mm: 1.0,
    }
    .seeing_all_of(&b);
    let m = r.lod_info().unwrap().levels;
    let picture = |tau: f64| {
        let cut =
            r.view(&view, &ViewOptions { tolerance_px: tau, budget: None, shapes: true }, None).unwrap();
        (draw_cut(&view, &cut, m).unwrap(), cut)
    };
    let (exact, _) = picture(0.0);
    assert!(exact.coverage() > 2000, "the scene fills part of the picture: {}", exact.coverage());
    // Perspective stretches a length off the axis by up to 1/cos^2 of the
    // angle to the view's corner.
    let t = (view.fov_deg.to_radians() / 2.0).tan();
    let aspect = f64::from(view.width_px) / f64::from(view.height_px);
    let stretch = 1.0 + t * t * (1.0 + aspect * aspect);
    let mut coarser = Vec::new();
    for tau in [0.0, 2.0, 6.0, 20.0] {
        let (img, cut) = picture(tau);
        // Rasterization decides a pixel by its centre: an edge shared by
        // two pictures may fall either way (1 px).
        assert_eq!(outside(&exact, &img, 1), 0, "tau {tau}: an exact pixel the cut leaves blank");
        let reach = (tau * stretch).ceil() as u32 + 1;
        assert_eq!(outside(&img, &exact, reach), 0, "tau {tau}: a pixel more than {reach} px from the scene");
        if tau == 0.0 {
            assert_eq!(img, exact);
        }
        coarser.push((img.coverage(), cut.exact_objects()));
    }
    assert!(coarser.last().unwrap().1 < coarser[0].1, "a large tau shows fewer exact objects: {coarser:?}");
    assert!(coarser.last().unwrap().0 > coarser[0].0, "stand-ins are larger than their objects: {coarser:?}");
    // The colours say the level: the exact picture has no red node box.
    let red = |img: &Image| {
        (0..img.height).flat_map(|y| (0..img.width).map(move |x| (x, y))).any(|(x, y)| {
            img.pixel(x, y).is_some_and(|p| i32::from(p[0]) > i32::from(p[2]) + 60 && p[1] < 120)
        })
    };
    assert!(!red(&exact));
}

#[test]
fn a_nodes_group_bound_holds_its_objects_picture() {
    let scene = generate_scene(&GenOptions { preset: Preset::Tanker1, objects: None, seed: 8 }).unwrap();
    let db = lod_db(&scene, 4, 4096, 10, LodParams { store_all: true, ..LodParams::default() });
    let r = db.begin_read().unwrap();
    let mut stats = Default::default();
    let node = 1;
    let exact = r.fetch_level(node, 4, true, &mut stats).unwrap();
    let (at, _) = r.locate(node).unwrap();
    let view = framing(&at.aabb, 200, 150, 40.0);
    let objects = draw_level(&view, &exact, 4, 4, false).unwrap();
    assert!(objects.coverage() > 500);
    for k in [1, 2, 3] {
        let level = r.fetch_level(node, k, false, &mut stats).unwrap();
        for group in [false, true] {
            let img = draw_level(&view, &level, k, 4, group).unwrap();
            assert_eq!(
                outside(&objects, &img, 1),
                0,
                "level {k} (group {group}) leaves an object pixel blank"
            );
            assert!(img.coverage() >= objects.coverage());
        }
    }
}
