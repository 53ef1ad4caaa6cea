//! Build time of the bulk loaders (issue 3, "Benchmarks"): MOA (MOA1/MOA2,
//! §3.1) and LAA (LAA1-LAA3, §3.2) with `look_ahead_level` 0, 2, 5 and
//! max, with rstar's `RTree::bulk_load` (OMT, default parameters) on the
//! same object boxes as a reference line in the same run; and volume-SAH
//! and `refine` (issue 7), whose cost is about 20 to 60 times volume-SAH's.
//!
//! One group per scene: the `tanker2` (3,900 objects) and `tanker3`
//! (4,096) presets of Table 1 and the `ship` preset with 10^5 and 10^6
//! objects, all with seed 0. Ids are `<scene>/moa`, `<scene>/laa/<look>`,
//! `<scene>/vsah`, `<scene>/refine` and `<scene>/rstar`; throughput is in objects. Every build uses R = 0.3,
//! `mem_page` = 100 objects (`LeafRule::Objects(100)`), the paper's
//! first-found tie-break and rayon's global pool; rstar's bulk load is
//! single-threaded.
//!
//! Skipped: LAA(5), LAA(max) and refine on `ship` with 10^6 objects
//! (refine: about 100 s an iteration in `mktree bench-build`). Timed once
//! while writing this file, on the shared 2-core machine, one iteration
//! took 35 s and 52 s, so criterion's warm-up plus 10 samples would spend
//! 6 to 10 minutes on each; LAA(2) (11 to 17 s) is the deepest look-ahead
//! measured there. How the cost grows with the look-ahead shows on `ship`
//! with 10^5 objects, where every look-ahead runs.
//!
//! `cargo bench --bench build [-- FILTER]`, e.g. `-- tanker2/`; the whole
//! run takes about 6 minutes. Every scene is generated even when a filter
//! leaves it out (a few seconds for the ship scenes).

use std::hint::black_box;
use std::time::Duration;

use criterion::{
    BatchSize, BenchmarkId, Criterion, SamplingMode, Throughput, criterion_group, criterion_main,
};
use mktree::bulk::{BuildParams, LeafRule, LookAhead, Method, build};
use mktree::geom::Aabb;
use mktree::scene::generate::{GenOptions, Preset, generate};
use rstar::RTree;
use rstar::primitives::Rectangle;

/// One benchmark group: a generated scene and the LAA look-aheads run on it.
struct Scene {
    name: &'static str,
    preset: Preset,
    /// `None`: the preset's own count (Table 1's for the tankers).
    objects: Option<u64>,
    look_aheads: &'static [LookAhead],
    /// Whether `refine` runs.
    refine: bool,
}

/// The look-aheads of issue 3.
const ALL_LOOK_AHEADS: &[LookAhead] =
    &[LookAhead::Levels(0), LookAhead::Levels(2), LookAhead::Levels(5), LookAhead::Max];

const SCENES: [Scene; 4] = [
    Scene {
        name: "tanker2",
        preset: Preset::Tanker2,
        objects: None,
        look_aheads: ALL_LOOK_AHEADS,
        refine: true,
    },
    Scene {
        name: "tanker3",
        preset: Preset::Tanker3,
        objects: None,
        look_aheads: ALL_LOOK_AHEADS,
        refine: true,
    },
    Scene {
        name: "ship-1e5",
        preset: Preset::Ship,
        objects: Some(100_000),
        look_aheads: ALL_LOOK_AHEADS,
        refine: true,
    },
    // LAA(5), LAA(max) and refine skipped here: over 30 s per iteration (see the module doc).
    Scene {
        name: "ship-1e6",
        preset: Preset::Ship,
        objects: Some(1_000_000),
        look_aheads: &[LookAhead::Levels(0), LookAhead::Levels(2)],
        refine: false,
    },
];

/// The scene's object boxes, in id order. Meshes are dropped as they are
/// generated: 10^6 objects' meshes (about 30 triangles each, plus names)
/// would take most of a gigabyte, and the builders only read boxes.
fn scene_boxes(scene: &Scene) -> Vec<Aabb> {
    let mut boxes = Vec::new();
    let options = GenOptions { preset: scene.preset, objects: scene.objects, seed: 0 };
    generate(&options, &mut |object| {
        boxes.push(object.aabb());
        Ok(())
    })
    .expect("the scenes are valid preset options");
    boxes
}

/// rstar's view of an object: its box as a rectangle.
fn rectangle(b: &Aabb) -> Rectangle<[f64; 3]> {
    Rectangle::from_corners(b.min.into(), b.max.into())
}

/// The options every line shares; `look_ahead` matters to LAA only.
fn params(method: Method, look_ahead: LookAhead) -> BuildParams {
    BuildParams { method, rate: 0.3, leaf: LeafRule::Objects(100), look_ahead, ..BuildParams::paper() }
}

fn bench_build(c: &mut Criterion) {
    for scene in &SCENES {
        let boxes = scene_boxes(scene);
        let rectangles: Vec<Rectangle<[f64; 3]>> = boxes.iter().map(rectangle).collect();
        let mut group = c.benchmark_group(scene.name);
        group.throughput(Throughput::Elements(boxes.len() as u64));
        // Iterations run from milliseconds to seconds: flat sampling gives
        // the slow ones one iteration per sample instead of criterion's
        // linear ramp of 1 + 2 + ... + 10 iterations.
        group.sampling_mode(SamplingMode::Flat);
        group.sample_size(10);
        group.warm_up_time(Duration::from_secs(1));
        // Enough for the millisecond lines. The slow lines overrun it, and
        // criterion warns so, but still take their 10 one-iteration samples.
        group.measurement_time(Duration::from_secs(3));

        // The tree is dropped outside the timing, as rstar's is below.
        let mut run = |id: BenchmarkId, params: BuildParams| {
            group.bench_function(id, |b| {
                b.iter_with_large_drop(|| {
                    build(black_box(&boxes), None, &params, &|_| {}).expect("valid input")
                })
            });
        };
        run(BenchmarkId::from_parameter("moa"), params(Method::Moa, LookAhead::Levels(0)));
        for &look_ahead in scene.look_aheads {
            run(BenchmarkId::new("laa", look_ahead), params(Method::Laa, look_ahead));
        }
        run(BenchmarkId::from_parameter("vsah"), params(Method::Vsah, LookAhead::Levels(0)));
        if scene.refine {
            run(BenchmarkId::from_parameter("refine"), params(Method::Refine, LookAhead::Levels(0)));
        }

        // bulk_load consumes its input, so each iteration gets a fresh copy,
        // made outside the timing.
        group.bench_function(BenchmarkId::from_parameter("rstar"), |b| {
            b.iter_batched(|| rectangles.clone(), RTree::bulk_load, BatchSize::LargeInput)
        });
        group.finish();
    }
}

criterion_group!(benches, bench_build);
criterion_main!(benches);
