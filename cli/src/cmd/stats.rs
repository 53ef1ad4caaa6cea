//! `mktree stats`: the paper's per-level table (Tables 2-38) and totals
//! (Tables 39-44) of a tree built in memory or stored in a file.

use std::path::Path;

use anyhow::Result;
use mktree::bulk::{BuildParams, Report, TreeShape};
use serde_json::{Value, json};

use crate::args::BuildArgs;
use crate::input::{Source, tree_of};
use crate::output::{self, opt};

/// A one-line description of the parameters.
pub fn describe(p: &BuildParams) -> String {
    let leaf = match p.leaf {
        mktree::bulk::LeafRule::Objects(n) => format!("MemPage {n} objects"),
        mktree::bulk::LeafRule::Bytes { capacity } => format!("MemPage {capacity} bytes"),
    };
    let la = match p.method {
        mktree::bulk::Method::Laa => format!(", look-ahead {}", p.look_ahead),
        mktree::bulk::Method::Refine => format!(", query extent {}", p.query_extent),
        _ => String::new(),
    };
    format!("method {}, R {}, {leaf}{la}, tie-break {}", p.method, p.rate, p.tie_break)
}

pub fn run(input: &Path, build: &BuildArgs, as_json: bool) -> Result<()> {
    let (tree, source) = tree_of(input, build, true)?;
    let report = Report::of(&tree);
    let shape = TreeShape::of(&tree);
    // How far change commits moved the node layout from a fresh one.
    let drift = match &source {
        Source::File(_, drift) => drift.clone(),
        Source::Memory { .. } => None,
    };
    let (params, seconds, file) = match &source {
        Source::File(info, _) => {
            (info.params.clone().unwrap_or_else(|| build.params()), info.build_seconds, Some(info))
        }
        Source::Memory { seconds } => (build.params(), *seconds, None),
    };
    if as_json {
        let mut v = serde_json::to_value(&report)?;
        if let Value::Object(m) = &mut v {
            m.insert("build_seconds".into(), json!(seconds));
            m.insert("method".into(), json!(params.method.name()));
            m.insert("params".into(), json!(describe(&params)));
            m.insert("shape".into(), serde_json::to_value(&shape)?);
            if let Some(info) = file {
                m.insert("file".into(), serde_json::to_value(info)?);
                m.insert(
                    "file_bytes".into(),
                    json!(u64::from(info.file_blocks) * u64::from(info.block_size)),
                );
            }
            if let Some(d) = &drift {
                let mut d_json = serde_json::to_value(d)?;
                if let Value::Object(dm) = &mut d_json {
                    dm.insert("worst_ratio".into(), json!(d.worst_ratio()));
                }
                m.insert("drift".into(), d_json);
            }
        }
        return output::json(&v);
    }
    println!("{}: {}", input.display(), describe(&params));
    print_table(&report);
    println!(
        "ovAccumulated {:.6}  N_g {}  ovAverage {:.6}  depth {}  leaves {}  objects {}  build {:.3} s",
        report.ov_accumulated,
        report.grey_nodes,
        report.ov_average,
        report.depth,
        report.leaves,
        report.objects,
        seconds
    );
    if let Some(info) = file {
        println!(
            "file: {} blocks of {} bytes ({} bytes, {} free): {} node ({:.1}% full), {} geometry ({:.1}% full); txn {}",
            info.file_blocks,
            info.block_size,
            u64::from(info.file_blocks) * u64::from(info.block_size),
            info.free_blocks,
            info.node_blocks,
            100.0 * info.node_fill,
            info.geometry_blocks,
            100.0 * info.geometry_fill,
            info.txn
        );
    }
    if let Some(d) = &drift {
        let reads = |r: &[f64]| r.iter().map(|x| format!("{x:.2}")).collect::<Vec<_>>().join(" / ");
        println!(
            "layout drift: node blocks read per query (collision, 1%, 5%, 20% boxes) {} as stored, {} laid out fresh: {:.2}x at worst; {} node blocks, {} fresh, {} deep{}",
            reads(&d.stored_reads),
            reads(&d.fresh_reads),
            d.worst_ratio(),
            d.stored_node_blocks,
            d.fresh_node_blocks,
            d.node_block_depth,
            if d.worst_ratio() > 1.05 { " (mktree optimize lays it out anew)" } else { "" }
        );
    }
    Ok(())
}

/// Tables 2-38.
pub fn print_table(report: &Report) {
    let rows: Vec<Vec<String>> = report
        .levels
        .iter()
        .map(|l| {
            vec![l.level.to_string(), l.leaves.to_string(), opt(l.ov_min), opt(l.ov_min_rel), opt(l.ov_max)]
        })
        .collect();
    output::table(&["tree level", "N. leaves", "ovMin", "ovMinRel", "ovMax"], &rows);
}
