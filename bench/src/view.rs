//! `mktree bench-view`: the view query's speed against its accuracy along
//! a camera path (its chart: `mktree bench-view --out`). Per tolerance τ, the block reads and
//! the triangles a frame draws; under a block budget, the largest projected
//! error the cut had to keep; and, as the yardstick, the reads of an exact
//! frustum query (object ids only) along the same path.

use mktree::geom::{Aabb, Camera, Point, Vector};
use mktree::query::{QueryError, navigate, navigate_view};
use mktree::{QueryOptions, ReadTransaction, View, ViewCut, ViewOptions};
use serde::Serialize;

/// What `bench_view` measures and how.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewBenchOptions {
    /// The tolerances τ (pixels) to sweep.
    pub taus: Vec<f64>,
    /// The block budgets per frame to sweep, at τ = `budget_tau`.
    pub budgets: Vec<u64>,
    /// The tolerance of the budget sweep, pixels.
    pub budget_tau: f64,
    /// Blocks the pool holds (one pool per sweep point, along the whole path).
    pub cache_blocks: usize,
    /// Vertical field of view, degrees.
    pub fov_deg: f64,
    /// The viewport's height, pixels.
    pub height_px: u32,
    /// The viewport's width over its height.
    pub aspect: f64,
}

impl Default for ViewBenchOptions {
    fn default() -> Self {
        ViewBenchOptions {
            taus: vec![0.0, 1.0, 4.0, 16.0, 64.0, 256.0],
            budgets: vec![25, 50, 100, 200, 400],
            budget_tau: 1.0,
            cache_blocks: 256,
            fov_deg: 60.0,
            height_px: 720,
            aspect: 1.5,
        }
    }
}

/// Means per frame at one tolerance.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TauRow {
    /// τ, pixels.
    pub tau_px: f64,
    /// Block reads (node and geometry, cache misses).
    pub reads: f64,
    /// Triangles a picture of the cut draws: stand-ins' and exact objects'.
    pub triangles: f64,
    /// Objects shown exact.
    pub exact_objects: f64,
    /// The largest projected error of the cut, pixels (mean over frames).
    pub max_error_px: f64,
}

/// One block budget per frame.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BudgetRow {
    /// Block reads allowed per frame.
    pub budget: u64,
    /// Mean reads per frame (at most the budget).
    pub reads: f64,
    /// The largest projected error each frame had to keep, median over the path.
    pub median_error_px: f64,
}

/// `bench_view`'s answer for one file and path.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ViewBench {
    /// Frames along the path.
    pub frames: usize,
    /// The exact frustum query's reads per frame along the same path.
    pub exact_frustum_reads: f64,
    /// Per tolerance swept.
    pub taus: Vec<TauRow>,
    /// Per block budget swept.
    pub budgets: Vec<BudgetRow>,
}

/// A walk through `scene` along its x axis, as through a ship's length:
/// `steps` eyes at the scene's centre height and width, from one end to the
/// other, each looking ahead (a third of the scene's larger cross extent)
/// and slightly down. Pairs of (eye, target), mm.
pub fn flight(scene: &Aabb, steps: usize) -> Vec<(Point, Point)> {
    let e = scene.extent();
    let c = scene.center();
    let ahead = e.y.max(e.z) / 3.0;
    let (x0, x1) = (scene.min.x + ahead, (scene.max.x - ahead).max(scene.min.x + ahead));
    (0..steps)
        .map(|i| {
            let t = if steps > 1 { i as f64 / (steps - 1) as f64 } else { 0.5 };
            let eye = Point::new(x0 + t * (x1 - x0), c.y, c.z);
            (eye, eye + Vector::new(ahead, 0.0, -ahead / 10.0))
        })
        .collect()
}

/// An orbit around `scene`: `steps` eyes evenly spaced on a horizontal
/// circle about its centre, half as far again from it as its horizontal
/// half-diagonal and a quarter of that above its centre, each looking at
/// the centre: the whole scene seen from outside, far, as a viewer's first
/// frames see it. Pairs of (eye, target), mm.
pub fn orbit(scene: &Aabb, steps: usize) -> Vec<(Point, Point)> {
    let e = scene.extent();
    let c = scene.center();
    let r = 1.5 * 0.5 * e.x.hypot(e.y).max(1.0);
    (0..steps)
        .map(|i| {
            let a = std::f64::consts::TAU * i as f64 / steps.max(1) as f64;
            (Point::new(c.x + r * a.cos(), c.y + r * a.sin(), c.z + r / 4.0), c)
        })
        .collect()
}

/// The views of `path` with `opts`' lens, seeing as far as the scene reaches.
pub fn views(path: &[(Point, Point)], scene: &Aabb, opts: &ViewBenchOptions) -> Vec<View> {
    let e = scene.extent();
    let near = e.y.max(e.z).max(1.0) / 160.0;
    path.iter()
        .map(|&(eye, target)| {
            View {
                eye,
                target,
                fov_deg: opts.fov_deg,
                width_px: (f64::from(opts.height_px) * opts.aspect).round() as u32,
                height_px: opts.height_px,
                near_mm: near,
                far_mm: 2.0 * near,
            }
            .seeing_all_of(scene)
        })
        .collect()
}

/// Triangles a picture of `cut` draws (the cut made with shapes).
pub fn triangles(cut: &ViewCut) -> u64 {
    cut.nodes.iter().flat_map(|n| &n.shapes).map(|s| s.shape.mesh().triangle_count() as u64).sum()
}

fn mean(values: impl Iterator<Item = f64>) -> f64 {
    let (sum, n) = values.fold((0.0, 0usize), |(s, n), v| (s + v, n + 1));
    if n == 0 { 0.0 } else { sum / n as f64 }
}

fn median(mut values: Vec<f64>) -> f64 {
    values.sort_by(f64::total_cmp);
    values.get(values.len() / 2).copied().unwrap_or(0.0)
}

/// Sweeps `opts`' tolerances and budgets along `views` (one pool of
/// `opts.cache_blocks` blocks per sweep point), and runs the exact frustum
/// query along the same cameras.
pub fn bench_view(
    txn: &ReadTransaction,
    views: &[View],
    opts: &ViewBenchOptions,
) -> Result<ViewBench, QueryError> {
    let cameras: Vec<Camera> = views
        .iter()
        .map(|v| Camera {
            eye: v.eye,
            target: v.target,
            fov_deg: v.fov_deg,
            aspect: f64::from(v.width_px) / f64::from(v.height_px),
            near: v.near_mm,
            far: v.far_mm,
        })
        .collect();
    let exact = navigate(txn, &cameras, &QueryOptions::default(), opts.cache_blocks)?;
    let mut taus = Vec::new();
    for &tau in &opts.taus {
        let cuts = navigate_view(
            txn,
            views,
            &ViewOptions { tolerance_px: tau, budget: None, shapes: true },
            opts.cache_blocks,
        )?;
        taus.push(TauRow {
            tau_px: tau,
            reads: mean(cuts.iter().map(|c| c.stats.reads.total() as f64)),
            triangles: mean(cuts.iter().map(|c| triangles(c) as f64)),
            exact_objects: mean(cuts.iter().map(|c| c.exact_objects() as f64)),
            max_error_px: mean(cuts.iter().map(|c| c.max_error_px)),
        });
    }
    let mut budgets = Vec::new();
    for &budget in &opts.budgets {
        let view_opts = ViewOptions { tolerance_px: opts.budget_tau, budget: Some(budget), shapes: false };
        let cuts = navigate_view(txn, views, &view_opts, opts.cache_blocks)?;
        budgets.push(BudgetRow {
            budget,
            reads: mean(cuts.iter().map(|c| c.stats.reads.total() as f64)),
            median_error_px: median(cuts.iter().map(|c| c.max_error_px).collect()),
        });
    }
    Ok(ViewBench {
        frames: views.len(),
        exact_frustum_reads: mean(exact.iter().map(|s| s.reads.total() as f64)),
        taus,
        budgets,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_flight_runs_the_length_of_the_scene_inside_it() {
        let scene = Aabb::from_array([0.0, 0.0, 0.0, 100_000.0, 16_000.0, 15_000.0]);
        let path = flight(&scene, 5);
        assert_eq!(path.len(), 5);
        for w in path.windows(2) {
            assert!(w[1].0.x > w[0].0.x, "eyes advance along x");
        }
        for (eye, target) in &path {
            assert!(scene.contains_point(eye), "{eye:?}");
            assert!(target.x > eye.x && target.z < eye.z, "looks ahead and down");
        }
        let v = views(&path, &scene, &ViewBenchOptions::default());
        assert!(v.iter().all(|v| v.near_mm > 0.0 && v.far_mm > 2.0 * v.near_mm && v.width_px == 1080));
    }

    #[test]
    fn an_orbit_circles_the_scene_from_outside_looking_at_its_centre() {
        let scene = Aabb::from_array([0.0, 0.0, 0.0, 100_000.0, 16_000.0, 15_000.0]);
        let path = orbit(&scene, 8);
        assert_eq!(path.len(), 8);
        let c = scene.center();
        let r = (path[0].0.x - c.x).hypot(path[0].0.y - c.y);
        for (eye, target) in &path {
            assert!(!scene.contains_point(eye), "{eye:?} is outside");
            assert_eq!(*target, c);
            assert!(((eye.x - c.x).hypot(eye.y - c.y) - r).abs() < 1e-6 * r, "one radius");
            assert!(eye.z > c.z, "above the centre");
        }
        // Opposite eyes: the circle goes all the way round.
        assert!((path[0].0.x + path[4].0.x - 2.0 * c.x).abs() < 1e-6 * r);
        let v = views(&path, &scene, &ViewBenchOptions::default());
        assert!(v.iter().all(|v| v.near_mm > 0.0 && v.far_mm > 2.0 * v.near_mm));
    }

    #[test]
    fn the_median_is_the_middle_value() {
        assert_eq!(median(vec![5.0, 1.0, 3.0]), 3.0);
        assert_eq!(median(Vec::new()), 0.0);
        assert_eq!(mean([1.0, 2.0, 6.0].into_iter()), 3.0);
    }
}
