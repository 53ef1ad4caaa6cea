//! The tree does not depend on the number of threads: every method builds
//! the same hierarchy, node for node, on a pool of 1 and of 2 threads (and
//! 3 for the cheap methods), on a scene big enough (20 000 objects, seed
//! printed) for the six orders, the partitions, the subtrees and LAA's
//! trials to run on rayon.

use mktree::bulk::{BuildParams, Hierarchy, LeafRule, LookAhead, Method, build};
use mktree::geom::Aabb;

/// Splitmix64 as uniform [0, 1).
fn uniform(seed: u64) -> impl FnMut() -> f64 {
    let mut state = seed;
    move || {
        state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        (z ^ (z >> 31)) as f64 / (u64::MAX as f64 + 1.0)
    }
}

/// `n` boxes in a 10 m cube, up to 200 mm a side, a few on a 100 mm grid
/// so that coordinates tie.
fn scene(n: usize, seed: u64) -> Vec<Aabb> {
    let mut next = uniform(seed);
    (0..n)
        .map(|i| {
            let mut lo = [next() * 10_000.0, next() * 10_000.0, next() * 10_000.0];
            if i % 7 == 0 {
                lo = lo.map(|c| (c / 100.0).floor() * 100.0);
            }
            let e = [next() * 200.0, next() * 200.0, next() * 200.0];
            Aabb::from_array([lo[0], lo[1], lo[2], lo[0] + e[0], lo[1] + e[1], lo[2] + e[2]])
        })
        .collect()
}

fn build_on(threads: usize, boxes: &[Aabb], params: &BuildParams) -> Hierarchy {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    pool.install(|| build(boxes, None, params, &|_| {})).unwrap()
}

#[test]
fn every_method_builds_the_same_tree_on_one_two_and_three_threads() {
    let seed = 0x5EED_0001;
    println!("seed {seed:#x}");
    let boxes = scene(20_000, seed);
    let base = BuildParams { rate: 0.2, leaf: LeafRule::Objects(64), ..BuildParams::paper() };
    let mut cases: Vec<BuildParams> =
        Method::ALL.iter().map(|&method| BuildParams { method, ..base.clone() }).collect();
    cases.push(BuildParams { method: Method::Laa, look_ahead: LookAhead::Max, ..base.clone() });
    for params in &cases {
        let one = build_on(1, &boxes, params);
        one.validate(&boxes, None, params).unwrap();
        let pools: &[usize] = if params.method == Method::Laa { &[2] } else { &[2, 3] };
        for &threads in pools {
            assert!(one == build_on(threads, &boxes, params), "{params:?} differs on {threads} threads");
        }
    }
}
