// Temporary probe: times one iteration of each combination.
use std::time::Instant;

use mktree::build::{BuildParams, LeafRule, LookAhead, Method, build};
use mktree::geom::Aabb;
use mktree::scene::generate::{GenOptions, Preset, generate};

fn main() {
    let only: Vec<String> = std::env::args().skip(1).filter(|a| !a.starts_with("--")).collect();
    for (label, preset, objects) in [
        ("tanker2", Preset::Tanker2, None),
        ("tanker3", Preset::Tanker3, None),
        ("ship-1e5", Preset::Ship, Some(100_000)),
        ("ship-1e6", Preset::Ship, Some(1_000_000)),
    ] {
        if !only.is_empty() && !only.iter().any(|o| o == label) {
            continue;
        }
        let t = Instant::now();
        let mut boxes: Vec<Aabb> = Vec::new();
        generate(&GenOptions { preset, objects, seed: 0 }, &mut |o| {
            boxes.push(o.aabb());
            Ok(())
        })
        .unwrap();
        eprintln!("{label}: {} boxes generated in {:.2?}", boxes.len(), t.elapsed());
        let t = Instant::now();
        let rects: Vec<rstar::primitives::Rectangle<[f64; 3]>> = boxes
            .iter()
            .map(|b| rstar::primitives::Rectangle::from_corners([b.min.x, b.min.y, b.min.z], [b.max.x, b.max.y, b.max.z]))
            .collect();
        let tree = rstar::RTree::bulk_load(rects);
        eprintln!("{label} rstar: {:.3?} ({})", t.elapsed(), tree.size());
        let las: Vec<Option<LookAhead>> = std::env::var("LAS")
            .unwrap_or("moa,0,2,5,max".into())
            .split(',')
            .map(|s| if s == "moa" { None } else { Some(s.parse().unwrap()) })
            .collect();
        for la in las {
            let params = BuildParams {
                method: if la.is_some() { Method::Laa } else { Method::Moa },
                rate: 0.3,
                leaf: LeafRule::Objects(100),
                look_ahead: la.unwrap_or(LookAhead::Levels(0)),
                ..BuildParams::default()
            };
            let t = Instant::now();
            let h = build(&boxes, None, &params, &|_| {}).unwrap();
            eprintln!("{label} {:?}: {:.3?} ({} nodes)", la, t.elapsed(), h.nodes.len());
        }
    }
}
