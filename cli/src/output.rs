//! Printing: JSON to stdout, plain tables, query answers and view cuts
//! (as JSON or text), PNG pictures, and a build's progress bar.

use std::fs::File;
use std::io::BufWriter;
use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result};
use indicatif::{HumanDuration, ProgressBar, ProgressStyle};
use mktree::bulk::{LoadProgress, Stage, TimeLeft};
use mktree::query::{QueryAnswer, ViewCut};
use mktree::render::Image;
use mktree::store::TransferCounts;
use serde::Serialize;
use serde_json::{Value, json};

/// Prints `value` as pretty JSON.
pub fn json<T: Serialize>(value: &T) -> Result<()> {
    println!("{}", serde_json::to_string_pretty(value)?);
    Ok(())
}

/// A number with six decimals, or a dash for none (the paper's tables).
pub fn opt(x: Option<f64>) -> String {
    x.map_or_else(|| "-".to_string(), |v| format!("{v:.6}"))
}

/// Writes `x` as `{:.0}` formats it (ties to even, `-0` for a negative
/// that rounds to zero) through integer formatting where `x` is within
/// i64: the float formatter's exact digits were 8% of a clash re-run's
/// table of 1.5 million rows.
pub fn write_whole(out: &mut String, x: f64) {
    use std::fmt::Write as _;
    let r = x.round_ties_even();
    // Writing to a String cannot fail.
    let _ = if r.abs() >= 1e15 || r.is_nan() {
        write!(out, "{x:.0}")
    } else if r == 0.0 && x.is_sign_negative() {
        write!(out, "-0")
    } else {
        write!(out, "{}", r as i64)
    };
}

/// Prints rows as right-aligned columns under a header.
pub fn table(header: &[&str], rows: &[Vec<String>]) {
    table_of(header, rows.len(), |r| rows[r].iter().map(String::as_str));
}

/// [`table`] of `count` rows whose cells `row(r)` gives, so that a table of
/// 10^6 rows need not hold 10^6 vectors of strings.
pub fn table_of<'a, I: Iterator<Item = &'a str>>(header: &[&str], count: usize, row: impl Fn(usize) -> I) {
    let mut width: Vec<usize> = header.iter().map(|h| h.len()).collect();
    for r in 0..count {
        for (w, c) in width.iter_mut().zip(row(r)) {
            *w = (*w).max(c.len());
        }
    }
    // One write for the whole table: stdout flushes at every line, and a
    // clash run's table may have 10^6 rows; cells are padded in place.
    let mut text = String::new();
    let mut line = |cells: &mut dyn Iterator<Item = &str>| {
        let start = text.len();
        for (n, (c, w)) in cells.zip(&width).enumerate() {
            if n > 0 {
                text.push_str("  ");
            }
            let pad = w.saturating_sub(c.chars().count());
            text.extend(std::iter::repeat_n(' ', pad));
            text.push_str(c);
        }
        let kept = text[start..].trim_end().len();
        text.truncate(start + kept);
        text.push('\n');
    };
    line(&mut header.iter().copied());
    for r in 0..count {
        line(&mut row(r));
    }
    print!("{text}");
}

/// A progress bar per stage, with the time left (on stderr, hidden when
/// not a terminal): object visits while the tree is built, then the units
/// of each later stage of the bulk load.
pub fn progress_bar() -> ProgressBar {
    let pb = ProgressBar::new(0);
    pb.set_style(
        ProgressStyle::with_template("{spinner} {prefix:>8} [{bar:40}] {pos}/{len} ({elapsed}) {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    pb.set_prefix(Stage::Tree.name());
    pb
}

/// Shows report `p` of the bar's stage on `pb`, with the time left that
/// `clock` tells.
pub fn show_progress(pb: &ProgressBar, clock: &mut TimeLeft, p: &LoadProgress) {
    let left = clock.observe(p, Instant::now());
    pb.set_length(p.total);
    pb.set_position(p.done);
    pb.set_message(left.map(|t| format!("{:#} left", HumanDuration(t))).unwrap_or_default());
}

/// An answer's JSON: the CLI contract's keys, then the traversal's statistics.
pub fn answer_json(a: &QueryAnswer) -> Value {
    let s = &a.stats;
    json!({
        "objects": a.objects,
        "keys": a.keys,
        "maybe": a.maybe,
        "unexplored_nodes": a.unexplored_nodes,
        "level": a.level,
        "level_reached": a.level_reached,
        "block_reads": {
            "node": s.reads.node, "geometry": s.reads.geometry, "total": s.reads.total()
        },
        "cache_hits": s.reads.cache_hits,
        "nodes_visited": s.nodes_visited,
        "leaves_visited": s.leaves_visited,
        "confirmed_per_level": s.confirmed,
        "rejected_per_level": s.rejected,
        "subtrees_pruned": s.pruned,
        "geometry_tests": s.geometry_tests,
        "triangles_tested": s.triangles_tested,
        "decided": a.decided,
        "seconds": s.seconds,
    })
}

/// Prints an answer as JSON or two lines of text.
pub fn print_answer(a: &QueryAnswer, as_json: bool) -> Result<()> {
    if as_json {
        return json(&answer_json(a));
    }
    let s = &a.stats;
    println!(
        "{} objects at level {}: {:?}",
        a.objects.len(),
        a.level,
        a.objects.iter().map(|o| o.0).collect::<Vec<_>>()
    );
    if a.level_reached < a.level || !a.maybe.is_empty() || a.unexplored_nodes > 0 {
        println!(
            "budget reached: level {} reached, {} maybe {:?}, {} subtrees unexplored",
            a.level_reached,
            a.maybe.len(),
            a.maybe.iter().map(|o| o.0).collect::<Vec<_>>(),
            a.unexplored_nodes
        );
    }
    println!(
        "block reads: {} node + {} geometry = {}; {} nodes, {} leaves; {:.3} ms",
        s.reads.node,
        s.reads.geometry,
        s.reads.total(),
        s.nodes_visited,
        s.leaves_visited,
        s.seconds * 1e3
    );
    println!(
        "decided per level k = 1 ..: confirmed {:?}, rejected {:?}; {} subtrees pruned; geometry read for {}",
        s.confirmed, s.rejected, s.pruned, s.geometry_tests
    );
    Ok(())
}

/// One line of what a step fetched from object storage.
pub fn transfer_line(step: &str, t: &TransferCounts) -> String {
    format!("fetched for {step}: {} requests, {} bytes, {} round trips", t.requests, t.bytes, t.round_trips)
}

/// A cut as JSON.
pub fn cut_json(cut: &ViewCut) -> Value {
    let pieces: Vec<Value> = cut
        .nodes
        .iter()
        .map(|n| {
            json!({
                "node": n.node.id, "parent": n.node.parent, "child": n.node.child,
                "level": n.level, "bound": n.bound, "aabb": n.aabb.to_array(),
                "objects": n.objects, "eps_mm": n.eps_mm, "distance_mm": n.distance_mm, "error_px": n.error_px,
            })
        })
        .collect();
    let r = &cut.stats.reads;
    json!({
        "pieces": pieces,
        "piece_count": cut.nodes.len(),
        "exact_objects": cut.exact_objects(),
        "max_error_px": cut.max_error_px,
        "tolerance_px": cut.tolerance_px,
        "budget": cut.budget,
        "block_reads": { "node": r.node, "geometry": r.geometry, "total": r.total() },
        "cache_hits": r.cache_hits,
        "seconds": cut.stats.seconds,
    })
}

/// Writes `img` as an 8-bit RGB PNG.
pub fn write_png(img: &Image, out: &Path) -> Result<()> {
    let f = File::create(out).with_context(|| format!("creating {}", out.display()))?;
    let mut enc = png::Encoder::new(BufWriter::new(f), img.width, img.height);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    let mut w = enc.write_header().with_context(|| format!("writing {}", out.display()))?;
    w.write_image_data(&img.rgb).with_context(|| format!("writing {}", out.display()))?;
    w.finish().with_context(|| format!("writing {}", out.display()))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    #[test]
    fn write_whole_writes_what_the_float_formatter_writes() {
        let mut values =
            vec![0.0, -0.0, 0.5, -0.5, 1.5, 2.5, -2.5, 0.49999999999999994, -0.3, 1e15, -1e15, 9.9e14];
        values.extend([
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            4503599627370495.5,
            1e300,
            f64::MIN_POSITIVE,
        ]);
        let mut s = 0x9e37_79b9_7f4a_7c15u64;
        for _ in 0..100_000 {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            let scale = 10f64.powi((s % 17) as i32 - 2);
            let x = (s >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0;
            values.push(x * scale);
            values.push((x * scale * 2.0).round() / 2.0);
        }
        for x in values {
            let mut got = String::new();
            super::write_whole(&mut got, x);
            assert_eq!(got, format!("{x:.0}"), "{x:e}");
        }
    }
}
