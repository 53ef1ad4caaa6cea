//! `mktree clash`: every pair of objects within a clearance, with the reads
//! set against the file's blocks; with the typed flags, a clash test between
//! chosen sets (docs/clash.md), grouped, as a table or JSON lines.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::io::Write;
use std::path::Path;

use anyhow::{Result, bail};
use mktree::clash::key_json::write_key_text;
use mktree::clash::{
    BcfOptions, Clash, ClashKind, ClashTest, DEFAULT_TOLERANCE, FoundBy, GroupBy, RunMode, SavedTest,
    Selector, Status, TestKind, export_bcf, group, group_ids, run_recorded, run_test, store_path,
};
use mktree::query::{ClashOptions, clash};
use serde_json::json;

use crate::args::ClashArgs;
use crate::output;

pub fn run(file: &Path, clearance: f64, lod: Option<u8>, as_json: bool) -> Result<()> {
    let db = crate::input::open_to_read(file)?;
    let r = db.begin_read()?;
    let a = clash(&r, &ClashOptions { lod, clearance }, None)?;
    let s = &a.stats;
    if as_json {
        return output::json(&json!({
            "pairs": a.pairs.iter().map(|p| [p.0, p.1]).collect::<Vec<_>>(),
            "level": a.level,
            "clearance": clearance,
            "block_reads": {
                "node": s.reads.node, "geometry": s.reads.geometry, "total": s.reads.total()
            },
            "cache_hits": s.reads.cache_hits,
            "file_blocks": a.file_blocks,
            "nodes_visited": s.nodes_visited,
            "leaves_visited": s.leaves_visited,
            "confirmed_per_level": s.confirmed,
            "rejected_per_level": s.rejected,
            "geometry_tests": s.geometry_tests,
            "triangles_tested": s.triangles_tested,
            "seconds": s.seconds,
        }));
    }
    println!("{} pairs at level {} within {clearance} mm", a.pairs.len(), a.level);
    for (x, y) in &a.pairs {
        println!("{x} {y}");
    }
    println!(
        "block reads: {} node + {} geometry = {} of the file's {} blocks; geometry tests {}; {:.1} ms",
        s.reads.node,
        s.reads.geometry,
        s.reads.total(),
        a.file_blocks,
        s.geometry_tests,
        s.seconds * 1e3
    );
    Ok(())
}

/// The test the flags state, or `None` when they state none (only --test).
fn test_of(args: &ClashArgs) -> Result<Option<ClashTest>> {
    let stated = !args.a.is_empty()
        || !args.b.is_empty()
        || args.kind.is_some()
        || args.distance.is_some()
        || args.tolerance.is_some()
        || args.touch;
    if !stated {
        return Ok(None);
    }
    let set = |v: &[String]| v.iter().map(|s| s.parse::<Selector>()).collect::<Result<Vec<_>, _>>();
    let kind = match args.kind.as_deref() {
        None if args.distance.is_some() => TestKind::Clearance,
        None | Some("hard") => TestKind::Hard,
        Some("clearance") => TestKind::Clearance,
        Some("duplicate") => TestKind::Duplicate,
        Some(other) => bail!("--type {other}: expected hard, clearance or duplicate"),
    };
    let test = ClashTest {
        a: set(&args.a)?,
        b: if args.b.is_empty() { None } else { Some(set(&args.b)?) },
        kind,
        tolerance: args.tolerance.unwrap_or(DEFAULT_TOLERANCE),
        distance: args.distance.unwrap_or(0.0),
        touch: args.touch,
    };
    test.validate()?;
    Ok(Some(test))
}

/// `mktree clash FILE --a .. --b .. --type ..`: a typed clash test; with
/// --test, run as the named test and recorded with statuses.
pub fn typed(file: &Path, args: &ClashArgs, as_json: bool) -> Result<()> {
    let test = test_of(args)?;
    let mut group_by = args.group.as_deref().map(str::parse::<GroupBy>).transpose()?;
    let db = crate::input::open_to_read(file)?;
    let r = db.begin_read()?;
    let Some(name) = &args.test else {
        // No set or type stated (only --group or --bcf): the whole file, hard clashes.
        let test = test.unwrap_or_default();
        let run = run_test(&r, &test)?;
        let groups = grouped(&run.clashes, group_by.unwrap_or_default(), args, as_json);
        bcf(&r, args, &run.clashes, None, &groups.groups, None)?;
        return print(&run.clashes, None, run.txn, &run.stats, None, &groups, as_json);
    };
    let path = args.store.clone().unwrap_or_else(|| store_path(file));
    // Held from the load to the save: a status another process sets
    // meanwhile waits, rather than being written over.
    let lock = crate::input::lock_store(&path)?;
    let mut store = lock.load()?;
    if let Some(t) = &test {
        let saved = SavedTest { test: t.clone(), group: group_by.unwrap_or_default() };
        store.tests.insert(name.clone(), saved);
    }
    if group_by.is_none() {
        group_by = store.tests.get(name).map(|s| s.group);
    }
    let rec = run_recorded(&r, &mut store, name, None, !args.full)?;
    lock.save(&store)?;
    drop(lock);
    let tracked = store.runs.remove(name).map(|run| run.tracked).unwrap_or_default();
    drop(store);
    let statuses: Vec<Status> = tracked.iter().map(|t| t.status).collect();
    let groups = grouped(&tracked, group_by.unwrap_or_default(), args, as_json);
    bcf(&r, args, &tracked, Some(&statuses), &groups.groups, Some(name))?;
    print(&tracked, Some(&statuses), rec.txn, &rec.stats, Some(&rec.mode), &groups, as_json)
}

/// The grouping of a run, as far as the output needs it.
struct Grouped {
    /// Each clash's group number.
    ids: Vec<usize>,
    /// How many groups.
    count: usize,
    /// Every group with its name, members and place, for JSON and BCF;
    /// none for a table (a re-run on 10^6 objects spent a sixth of its
    /// time making 1.5 million named groups it did not print).
    groups: Vec<mktree::clash::Group>,
}

fn grouped<C: AsRef<Clash>>(clashes: &[C], by: GroupBy, args: &ClashArgs, as_json: bool) -> Grouped {
    if as_json || args.bcf.is_some() {
        let groups = group(clashes, by);
        let mut ids = vec![0; clashes.len()];
        for g in &groups {
            for &m in &g.members {
                ids[m] = g.id;
            }
        }
        Grouped { ids, count: groups.len(), groups }
    } else {
        let ids = group_ids(clashes, by);
        let count = ids.iter().max().map_or(0, |&m| m + 1);
        Grouped { ids, count, groups: Vec::new() }
    }
}

/// Writes the BCF export --bcf asks for.
fn bcf<C: AsRef<Clash>>(
    r: &mktree::ReadTransaction,
    args: &ClashArgs,
    clashes: &[C],
    statuses: Option<&[Status]>,
    groups: &[mktree::clash::Group],
    label: Option<&str>,
) -> Result<()> {
    let Some(out) = &args.bcf else { return Ok(()) };
    let opts = BcfOptions { label: label.map(str::to_string), ..Default::default() };
    let bytes = export_bcf(r, clashes, statuses, groups, &opts)?;
    std::fs::write(out, bytes).map_err(|e| anyhow::anyhow!("{}: {e}", out.display()))?;
    Ok(())
}

/// Prints clashes (with their statuses, when recorded) of the run on
/// commit `txn` grouped by `by`: JSON lines then a summary line, or a
/// table then counts by type and status.
#[allow(clippy::too_many_arguments)]
fn print<C: AsRef<Clash>>(
    clashes: &[C],
    statuses: Option<&[Status]>,
    txn: u64,
    stats: &mktree::clash::RunStats,
    mode: Option<&RunMode>,
    grouped: &Grouped,
    as_json: bool,
) -> Result<()> {
    let (group_of, groups) = (&grouped.ids, &grouped.groups);
    let status = |i: usize| statuses.map(|s| s[i].name());
    let mut counts: BTreeMap<(&str, &str), usize> = BTreeMap::new();
    for (i, c) in clashes.iter().map(AsRef::as_ref).enumerate() {
        *counts.entry((c.kind.name(), status(i).unwrap_or("-"))).or_default() += 1;
    }
    let out = std::io::stdout();
    let mut out = std::io::BufWriter::new(out.lock());
    if as_json {
        // Written straight from the clash, not through a JSON value: a
        // value's map of owned strings per row was 15% of an IFC re-run.
        #[derive(serde::Serialize)]
        struct Row<'a> {
            #[serde(flatten)]
            clash: &'a Clash,
            group: usize,
            status: Option<&'a str>,
        }
        for (i, clash) in clashes.iter().map(AsRef::as_ref).enumerate() {
            serde_json::to_writer(&mut out, &Row { clash, group: group_of[i], status: status(i) })?;
            out.write_all(b"\n")?;
        }
        #[derive(serde::Serialize)]
        struct Count<'a> {
            #[serde(rename = "type")]
            kind: &'a str,
            status: &'a str,
            clashes: usize,
        }
        #[derive(serde::Serialize)]
        struct GroupRow<'a> {
            id: usize,
            name: &'a str,
            clashes: usize,
            point: [f64; 3],
        }
        #[derive(serde::Serialize)]
        struct Summary<'a> {
            txn: u64,
            clashes: usize,
            groups: Vec<GroupRow<'a>>,
            by_type_status: Vec<Count<'a>>,
            mode: Option<&'a RunMode>,
            stats: &'a mktree::clash::RunStats,
        }
        let summary = Summary {
            txn,
            clashes: clashes.len(),
            groups: groups
                .iter()
                .map(|g| GroupRow {
                    id: g.id,
                    name: &g.name,
                    clashes: g.members.len(),
                    point: [g.point.x, g.point.y, g.point.z],
                })
                .collect(),
            by_type_status: counts
                .iter()
                .map(|(&(kind, status), &clashes)| Count { kind, status, clashes })
                .collect(),
            mode,
            stats,
        };
        #[derive(serde::Serialize)]
        struct Line<'a> {
            summary: Summary<'a>,
        }
        serde_json::to_writer(&mut out, &Line { summary })?;
        out.write_all(b"\n")?;
        return Ok(out.flush()?);
    }
    // The cells in one buffer, each row's seven ending at `ends`: a run on
    // 10^6 objects has over a million rows.
    let mut cells = String::new();
    let mut ends: Vec<usize> = Vec::with_capacity(clashes.len() * 7);
    for (i, c) in clashes.iter().map(AsRef::as_ref).enumerate() {
        let measure = if c.kind == ClashKind::Clearance { c.distance } else { c.depth };
        write!(cells, "{}", group_of[i])?;
        ends.push(cells.len());
        cells.push_str(status(i).unwrap_or("-"));
        ends.push(cells.len());
        cells.push_str(c.kind.name());
        ends.push(cells.len());
        for key in [&c.a, &c.b] {
            write_key_text(&mut cells, key);
            ends.push(cells.len());
        }
        write!(cells, "{measure:.3}")?;
        ends.push(cells.len());
        for (k, x) in [c.point.x, c.point.y, c.point.z].into_iter().enumerate() {
            if k > 0 {
                cells.push(' ');
            }
            output::write_whole(&mut cells, x);
        }
        ends.push(cells.len());
    }
    drop(out);
    let cell = |k: usize| &cells[if k == 0 { 0 } else { ends[k - 1] }..ends[k]];
    let header = ["group", "status", "type", "a", "b", "depth/distance mm", "point"];
    output::table_of(&header, clashes.len(), |r| (7 * r..7 * r + 7).map(cell));
    println!();
    let rows: Vec<Vec<String>> =
        counts.iter().map(|((t, s), n)| vec![t.to_string(), s.to_string(), n.to_string()]).collect();
    output::table(&["type", "status", "clashes"], &rows);
    let s = stats;
    let how = match mode {
        Some(RunMode::Incremental { by, changed, removed, kept }) => {
            let by = match by {
                FoundBy::Log => "the change log",
                FoundBy::Fingerprints => "fingerprints",
            };
            format!("; incremental ({by}): {changed} changed, {removed} removed, {kept} clashes kept")
        }
        Some(RunMode::Full { why }) => format!("; full ({why})"),
        None => String::new(),
    };
    println!(
        "{} clashes in {} groups on commit {}; A {} and B {} of {}, {} candidate pairs, {} meshes read ({} held at most); \
         {:.1} ms (list {:.1}, read {:.1}, measure {:.1}){how}",
        clashes.len(),
        grouped.count,
        txn,
        s.in_a,
        s.in_b,
        if s.listed == s.objects {
            format!("{} objects", s.objects)
        } else {
            format!("the {} objects near a change (of {})", s.listed, s.objects)
        },
        s.candidates,
        s.meshes_read,
        s.peak_meshes,
        s.seconds * 1e3,
        s.list_seconds * 1e3,
        s.read_seconds * 1e3,
        s.measure_seconds * 1e3
    );
    Ok(())
}
