//! Charts (plotters), as SVG and PNG, each with a title, axis labels and a
//! legend: `bench-build`'s reads per query by method and query set,
//! `bench-peers`' ratios to SQLite, `tradeoff`'s block reads against
//! precision, `bench-view`'s reads, triangles and errors per frame,
//! `bench-changes`' time per commit against the objects, `bench-remote`'s
//! time per query against the added round trip.
//!
//! The SVG names its font and leaves the glyphs to the viewer; the PNG's
//! glyphs are drawn by plotters through ab_glyph from DejaVu Sans, embedded
//! in the binary (`cli/fonts/`, its licence beside it), so a PNG looks the
//! same on every machine and needs no system font. Both lay their text out
//! with that font's metrics.

use std::path::Path;

use anyhow::{Result, anyhow};
use plotters::coord::Shift;
use plotters::prelude::*;

use mktree_bench::{LoaderBench, LoaderScene};

/// Pixels per scene panel.
const PANEL: (u32, u32) = (1100, 380);

/// `bench-build`'s chart: one panel per scene, each method's block reads
/// (or leaves visited) per query over the best of median, sah and vsah, by
/// query set, written as `svg` and `png`.
pub fn bench_build(bench: &LoaderBench, svg: &Path, png: &Path) -> Result<()> {
    let size = (PANEL.0, PANEL.1 * bench.scenes.len().max(1) as u32);
    svg_and_png!(size, svg, png, draw(bench))
}

/// Draws a chart twice, `$draw(area, args..)`: as SVG and as PNG, the
/// PNG's text in the embedded font (see the module's note on fonts).
macro_rules! svg_and_png {
    ($size:expr, $svg:expr, $png:expr, $draw:ident ( $($arg:expr),* )) => {{
        // Both backends lay text out with the font's metrics.
        $crate::chart::register_font()?;
        let svg_root = SVGBackend::new($svg, $size).into_drawing_area();
        $draw(&svg_root, $($arg,)*)?;
        svg_root.present().map_err(|e| anyhow!("writing {}: {e}", $svg.display()))?;
        let png_root = BitMapBackend::new($png, $size).into_drawing_area();
        $draw(&png_root, $($arg,)*)?;
        png_root.present().map_err(|e| anyhow!("writing {}: {e}", $png.display()))?;
        Ok(())
    }};
}
pub(crate) use svg_and_png;

/// DejaVu Sans (`cli/fonts/LICENSE-DejaVu.txt`): the PNG charts' font.
static FONT: &[u8] = include_bytes!("../fonts/DejaVuSans.ttf");

/// The family name every chart asks for.
pub const FAMILY: &str = "sans-serif";

/// Gives plotters' bitmap text the embedded font under [`FAMILY`], once
/// per process.
pub fn register_font() -> Result<()> {
    static REGISTERED: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    let ok =
        *REGISTERED.get_or_init(|| plotters::style::register_font(FAMILY, FontStyle::Normal, FONT).is_ok());
    if ok { Ok(()) } else { Err(anyhow!("the embedded chart font does not load")) }
}

/// One series of `tradeoff`'s chart: a file's (mean block reads, precision)
/// per level k.
pub struct Tradeoff {
    pub name: String,
    pub points: Vec<(f64, f64, u8)>,
}

/// `tradeoff`'s chart: block reads (x) against precision (y), a point per
/// level (labelled k in the SVG), a line per file.
pub fn tradeoff(series: &[Tradeoff], svg: &Path, png: &Path) -> Result<()> {
    svg_and_png!((900, 600), svg, png, draw_tradeoff(series))
}

fn draw_tradeoff<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, series: &[Tradeoff]) -> Result<()> {
    root.fill(&WHITE).map_err(failed)?;
    let x_max = series.iter().flat_map(|s| s.points.iter().map(|p| p.0)).fold(1.0f64, f64::max) * 1.1;
    let mut builder = ChartBuilder::on(root);
    builder
        .margin(16)
        .caption("speed against accuracy: collision queries at each level k", (FAMILY, 18))
        .x_label_area_size(40)
        .y_label_area_size(56);
    // Precision from a little below the lowest point, so levels that
    // differ by a percent are told apart.
    let y_min = series.iter().flat_map(|s| s.points.iter().map(|p| p.1)).fold(1.0f64, f64::min);
    let y_lo = (((y_min - 0.02) * 50.0).floor() / 50.0).max(0.0);
    let y_hi = 1.0 + (1.0 - y_lo) * 0.05;
    let mut chart = builder.build_cartesian_2d(0.0..x_max, y_lo..y_hi).map_err(failed)?;
    chart.configure_mesh().x_desc("mean block reads per query").y_desc("precision").draw().map_err(failed)?;
    for (i, s) in series.iter().enumerate() {
        let colour = Palette99::pick(i).to_rgba();
        let line = s.points.iter().map(|p| (p.0, p.1));
        chart
            .draw_series(LineSeries::new(line, colour.stroke_width(2)))
            .map_err(failed)?
            .label(s.name.clone())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], colour.stroke_width(2)));
        let labels = s.points.iter().map(|&(x, y, k)| Text::new(format!("k{k}"), (x, y), (FAMILY, 13)));
        chart.draw_series(labels).map_err(failed)?;
        chart
            .draw_series(s.points.iter().map(|&(x, y, _)| Circle::new((x, y), 4, colour.filled())))
            .map_err(failed)?;
    }
    legend(&mut chart, SeriesLabelPosition::LowerRight)
}

/// One line of `bench-changes`' chart: an engine's kind of commit, its
/// (objects, median ms per commit) per scene.
pub struct CommitSeries {
    pub name: String,
    pub points: Vec<(f64, f64)>,
}

/// `bench-changes`' chart: the median time of a single-object commit (y,
/// log) against the scene's objects (x, log), a line per engine and kind.
pub fn commit_times(series: &[CommitSeries], svg: &Path, png: &Path) -> Result<()> {
    svg_and_png!((900, 600), svg, png, draw_commit_times(series))
}

fn draw_commit_times<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    series: &[CommitSeries],
) -> Result<()> {
    root.fill(&WHITE).map_err(failed)?;
    let points = || series.iter().flat_map(|s| s.points.iter().copied());
    let (x_lo, x_hi) = points().fold((f64::MAX, f64::MIN_POSITIVE), |(lo, hi), p| (lo.min(p.0), hi.max(p.0)));
    let (y_lo, y_hi) = points().fold((f64::MAX, f64::MIN_POSITIVE), |(lo, hi), p| (lo.min(p.1), hi.max(p.1)));
    if !(x_lo.is_finite() && x_lo > 0.0 && y_lo.is_finite() && y_lo > 0.0) {
        return Err(anyhow!("no commit times to draw"));
    }
    let mut builder = ChartBuilder::on(root);
    builder
        .margin(16)
        .caption("time per single-object commit against the scene's objects", (FAMILY, 18))
        .x_label_area_size(40)
        .y_label_area_size(56);
    let mut chart = builder
        .build_cartesian_2d((x_lo / 1.5..x_hi * 1.5).log_scale(), (y_lo / 1.5..y_hi * 1.5).log_scale())
        .map_err(failed)?;
    chart
        .configure_mesh()
        .x_desc("objects")
        .y_desc("median ms per commit")
        .x_labels(6)
        .x_label_formatter(&|x| format!("{x:.0}"))
        .y_label_formatter(&|y| format!("{y:.2}"))
        .draw()
        .map_err(failed)?;
    marked_lines(&mut chart, series.iter().map(|s| (s.name.as_str(), s.points.as_slice())))?;
    legend(&mut chart, SeriesLabelPosition::UpperLeft)
}

/// One line of `bench-remote`'s chart: a query set's (added round trip
/// in ms, mean ms per query).
pub struct LatencySeries {
    pub name: String,
    pub points: Vec<(f64, f64)>,
}

/// `bench-remote`'s chart, two panels side by side: the mean wall time per
/// query against the round trip the proxy added, a line per query set;
/// cold (each query with its own open) left, warm right.
pub fn bench_remote(cold: &[LatencySeries], warm: &[LatencySeries], svg: &Path, png: &Path) -> Result<()> {
    svg_and_png!((1400, 520), svg, png, draw_bench_remote(cold, warm))
}

fn draw_bench_remote<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    cold: &[LatencySeries],
    warm: &[LatencySeries],
) -> Result<()> {
    root.fill(&WHITE).map_err(failed)?;
    let panels = root.split_evenly((1, 2));
    let captions = [
        "cold: a fresh reader per query, open included",
        "warm: one reader, its cache filled by a first pass",
    ];
    for ((area, caption), series) in panels.iter().zip(captions).zip([cold, warm]) {
        let points = || series.iter().flat_map(|s| s.points.iter().copied());
        // Axes from 0, so that the slope reads as the time per added round trip.
        let x_max = points().map(|p| p.0).fold(1.0f64, f64::max) * 1.05;
        let y_max = points().map(|p| p.1).fold(1.0f64, f64::max) * 1.25;
        let mut builder = ChartBuilder::on(area);
        builder.margin(14).caption(caption, (FAMILY, 17)).x_label_area_size(40).y_label_area_size(64);
        let mut chart = builder.build_cartesian_2d(0.0..x_max, 0.0..y_max).map_err(failed)?;
        chart
            .configure_mesh()
            .x_desc("round trip added, ms")
            .y_desc("mean wall time per query, ms")
            .draw()
            .map_err(failed)?;
        marked_lines(&mut chart, series.iter().map(|s| (s.name.as_str(), s.points.as_slice())))?;
        legend(&mut chart, SeriesLabelPosition::UpperLeft)?;
    }
    Ok(())
}

/// One line per `(name, points)`, its points marked, a colour each,
/// labelled for the legend.
fn marked_lines<'a, 'b, DB, X, Y>(
    chart: &mut ChartContext<'a, DB, Cartesian2d<X, Y>>,
    lines: impl Iterator<Item = (&'b str, &'b [(f64, f64)])>,
) -> Result<()>
where
    DB: DrawingBackend + 'a,
    X: Ranged<ValueType = f64>,
    Y: Ranged<ValueType = f64>,
{
    for (i, (name, points)) in lines.enumerate() {
        let colour = Palette99::pick(i).to_rgba();
        chart
            .draw_series(LineSeries::new(points.iter().copied(), colour.stroke_width(2)))
            .map_err(failed)?
            .label(name)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], colour.stroke_width(2)));
        chart.draw_series(points.iter().map(|&p| Circle::new(p, 4, colour.filled()))).map_err(failed)?;
    }
    Ok(())
}

/// The chart's legend of labelled series, boxed at `position`.
fn legend<'a, DB: DrawingBackend + 'a, X: Ranged, Y: Ranged>(
    chart: &mut ChartContext<'a, DB, Cartesian2d<X, Y>>,
    position: SeriesLabelPosition,
) -> Result<()> {
    chart
        .configure_series_labels()
        .position(position)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
        .map_err(failed)
}

pub fn failed(e: impl std::fmt::Display) -> anyhow::Error {
    anyhow!("drawing the chart: {e}")
}

fn draw<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, bench: &LoaderBench) -> Result<()> {
    root.fill(&WHITE).map_err(failed)?;
    let panels = root.split_evenly((bench.scenes.len().max(1), 1));
    for (area, scene) in panels.iter().zip(&bench.scenes) {
        panel(area, scene, bench.block_size.is_some())?;
    }
    Ok(())
}

/// One scene: a line per method across the query sets.
fn panel<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, scene: &LoaderScene, reads: bool) -> Result<()> {
    let labels: Vec<String> = scene
        .methods
        .first()
        .map(|m| m.queries.iter().map(|q| q.query.clone()).collect())
        .unwrap_or_default();
    let lines: Vec<(&str, Vec<(f64, f64)>)> = scene
        .methods
        .iter()
        .map(|m| {
            let points = m
                .queries
                .iter()
                .enumerate()
                .filter_map(|(i, q)| q.ratio_to_best_reference.map(|r| (i as f64, r)))
                .collect();
            (m.method, points)
        })
        .collect();
    let (lo, hi) = lines
        .iter()
        .flat_map(|(_, p)| p.iter().map(|&(_, y)| y))
        .fold((0.9f64, 1.1f64), |(lo, hi), y| (lo.min(y), hi.max(y)));
    let (lo, hi) = (lo - 0.05 * (hi - lo), hi + 0.05 * (hi - lo));
    let what = if reads { "block reads" } else { "leaves visited" };
    let panel = RatioPanel {
        caption: format!("{}: {what} per query / best of median, sah, vsah", scene.scene),
        x_desc: "query set",
        y_desc: format!("{what} / best reference's"),
        sets: &labels,
        lines,
        y: lo..hi,
        rules: vec![(1.0, BLACK.mix(0.6)), (0.9, RED.mix(0.4))],
    };
    ratio_panel(area, &panel)
}

/// One panel of ratios by query set: a line per series, horizontal rules at
/// reference ratios, the legend upper right.
pub struct RatioPanel<'a> {
    pub caption: String,
    pub x_desc: &'a str,
    pub y_desc: String,
    /// The query sets' names, one per x position.
    pub sets: &'a [String],
    /// Per series: its name and (set index, ratio) points.
    pub lines: Vec<(&'a str, Vec<(f64, f64)>)>,
    pub y: std::ops::Range<f64>,
    pub rules: Vec<(f64, RGBAColor)>,
}

pub fn ratio_panel<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, p: &RatioPanel) -> Result<()> {
    let mut builder = ChartBuilder::on(area);
    builder
        .margin(12)
        .caption(&p.caption, (FAMILY, 18))
        .x_label_area_size(44)
        .y_label_area_size(64)
        .right_y_label_area_size(90);
    let sets = p.sets.len().max(1) as f64;
    let mut chart = builder.build_cartesian_2d(-0.5f64..sets - 0.5, p.y.clone()).map_err(failed)?;
    let fmt = |x: &f64| p.sets.get(x.round() as usize).cloned().unwrap_or_default();
    chart
        .configure_mesh()
        .x_labels(p.sets.len())
        .disable_x_mesh()
        .x_label_formatter(&fmt)
        .y_label_formatter(&|y| format!("{y:.2}"))
        .x_desc(p.x_desc)
        .y_desc(p.y_desc.as_str())
        .draw()
        .map_err(failed)?;
    for &(level, colour) in &p.rules {
        chart
            .draw_series(LineSeries::new([(-0.5, level), (sets - 0.5, level)], colour.stroke_width(1)))
            .map_err(failed)?;
    }
    for (i, (name, points)) in p.lines.iter().enumerate() {
        let colour = Palette99::pick(i).to_rgba();
        chart
            .draw_series(LineSeries::new(points.iter().copied(), colour.stroke_width(2)))
            .map_err(failed)?
            .label(*name)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], colour.stroke_width(2)));
        chart.draw_series(points.iter().map(|&p| Circle::new(p, 3, colour.filled()))).map_err(failed)?;
    }
    legend(&mut chart, SeriesLabelPosition::UpperRight)
}

/// `bench-view`'s chart, three panels side by side: block reads per frame
/// against τ (each file's exact frustum query as a dashed line), triangles
/// drawn per frame against τ, and the error kept against the block budget.
/// Axes are log-scaled (τ = 0 is drawn at 0.5 px).
pub fn bench_view(results: &[(String, mktree_bench::ViewBench)], svg: &Path, png: &Path) -> Result<()> {
    svg_and_png!((1500, 460), svg, png, draw_bench_view(results))
}

fn draw_bench_view<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    results: &[(String, mktree_bench::ViewBench)],
) -> Result<()> {
    root.fill(&WHITE).map_err(failed)?;
    let panels = root.split_evenly((1, 3));
    let tau_x = |t: f64| t.max(0.5);
    let tau_max =
        results.iter().flat_map(|(_, b)| b.taus.iter().map(|t| tau_x(t.tau_px))).fold(1.0, f64::max);
    let budget_max =
        results.iter().flat_map(|(_, b)| b.budgets.iter().map(|r| r.budget as f64)).fold(2.0, f64::max);
    type Series = Vec<(f64, f64)>;
    let per_file: Vec<(Series, Series, Series, f64)> = results
        .iter()
        .map(|(_, b)| {
            (
                b.taus.iter().map(|t| (tau_x(t.tau_px), t.reads.max(0.1))).collect(),
                b.taus.iter().map(|t| (tau_x(t.tau_px), t.triangles.max(1.0))).collect(),
                b.budgets.iter().map(|r| (r.budget as f64, r.median_error_px.max(0.1))).collect(),
                b.exact_frustum_reads.max(0.1),
            )
        })
        .collect();
    let top =
        |pick: fn(&(Series, Series, Series, f64)) -> f64| per_file.iter().map(pick).fold(1.0, f64::max) * 2.0;
    let reads_max = top(|f| f.0.iter().map(|p| p.1).fold(f.3, f64::max));
    let triangles_max = top(|f| f.1.iter().map(|p| p.1).fold(1.0, f64::max));
    let error_max = top(|f| f.2.iter().map(|p| p.1).fold(1.0, f64::max));
    let specs: [(&str, &str, &str, f64, f64); 3] = [
        ("block reads per frame", "tolerance tau, px", "reads", tau_max, reads_max),
        ("triangles drawn per frame", "tolerance tau, px", "triangles", tau_max, triangles_max),
        (
            "error kept under a budget (tau = 1 px)",
            "block budget per frame",
            "median largest error, px",
            budget_max,
            error_max,
        ),
    ];
    for (p, (panel, (caption, x_desc, y_desc, x_max, y_max))) in panels.iter().zip(specs).enumerate() {
        let mut builder = ChartBuilder::on(panel);
        builder.margin(14).caption(caption, (FAMILY, 16)).x_label_area_size(40).y_label_area_size(64);
        let x_min = if p == 2 { 1.0 } else { 0.5 };
        let mut chart = builder
            .build_cartesian_2d((x_min..x_max * 1.5).log_scale(), (0.1..y_max).log_scale())
            .map_err(failed)?;
        chart.configure_mesh().x_desc(x_desc).y_desc(y_desc).draw().map_err(failed)?;
        for (i, ((name, _), file)) in results.iter().zip(&per_file).enumerate() {
            let colour = Palette99::pick(i).to_rgba();
            let points = match p {
                0 => &file.0,
                1 => &file.1,
                _ => &file.2,
            };
            chart
                .draw_series(LineSeries::new(points.iter().copied(), colour.stroke_width(2)))
                .map_err(failed)?
                .label(name.clone())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], colour.stroke_width(2)));
            chart
                .draw_series(points.iter().map(|&(x, y)| Circle::new((x, y), 3, colour.filled())))
                .map_err(failed)?;
            if p == 0 {
                // The exact frustum query: dashes across the panel.
                let dashes = (0..12).map(|d| {
                    let at = |s: f64| x_min * (x_max * 1.5 / x_min).powf(s);
                    PathElement::new(
                        vec![(at(d as f64 / 12.0), file.3), (at((d as f64 + 0.5) / 12.0), file.3)],
                        colour,
                    )
                });
                chart.draw_series(dashes).map_err(failed)?;
            }
        }
        legend(&mut chart, SeriesLabelPosition::UpperRight)?;
    }
    Ok(())
}
