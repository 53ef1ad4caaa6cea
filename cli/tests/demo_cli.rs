//! Claim: `mktree demo` states each result in a sentence, and in its
//! clearance queries the levels of detail below M decide objects and save
//! block reads: the query it shows reads fewer blocks than without them,
//! and a level between 2 and M - 1 decided some of its objects. Its chart's
//! PNG has a title and axis labels.

mod common;

use common::{assert_chart_has_text, mktree};

/// The whole numbers in `line`, in order (digits only, no signs or points).
fn numbers(line: &str) -> Vec<u64> {
    line.split(|c: char| !c.is_ascii_digit()).filter(|s| !s.is_empty()).map(|s| s.parse().unwrap()).collect()
}

#[test]
fn the_demo_shows_levels_below_m_deciding_objects_and_saving_reads() {
    let dir = tempfile::tempdir().unwrap();
    let out = mktree().arg("demo").arg("--dir").arg(dir.path()).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8(out.stdout).unwrap();

    // One sentence per query set against SQLite.
    let sentences =
        text.lines().filter(|l| l.contains("of the") && l.contains("pages SQLite reads.")).count();
    assert_eq!(sentences, 4, "{text}");

    // "... found in R block reads instead of W." with R < W.
    let best = text.lines().find(|l| l.contains("The query where they saved most")).expect(&text);
    let tail = &best[best.find("found in").expect(best)..];
    let (reads, without) = match numbers(tail)[..] {
        [r, w, ..] => (r, w),
        _ => panic!("{best}"),
    };
    assert!(reads < without, "{best}");

    // The table after it: a row per level 1 ..= 5, "k, its ...  ruled out  proved".
    let rows: Vec<Vec<u64>> = text
        .lines()
        .skip_while(|l| !l.contains("level k: the object's"))
        .skip(1)
        .take_while(|l| !l.trim().is_empty())
        .map(numbers)
        .collect();
    assert_eq!(rows.len(), 5, "{text}");
    let decided_between: u64 = rows[1..4].iter().map(|r| r[r.len() - 2] + r[r.len() - 1]).sum();
    assert!(decided_between > 0, "no level between 2 and M - 1 decided an object:\n{text}");

    assert_chart_has_text(&dir.path().join("tradeoff.png"));
}
