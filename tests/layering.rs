//! lib.rs's "Layers": each top-level module of `src/` names only modules
//! below it (a `crate::m` path in code, comments aside), and no two
//! modules, at the top or inside one, import each other.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// Top to bottom; a module may name any module after it. `error` is the
/// crate's one error, which db's operations return and which wraps the
/// errors of the layers below; `rng` and `spill` are utilities.
const LAYERS: &[&[&str]] = &[
    &["lib"],
    &["catalog", "clash", "tiles", "redb"],
    &["render"],
    &["db"],
    &["error"],
    &["query"],
    &["tree"],
    &["lod"],
    &["bulk"],
    &["store"],
    &["scene"],
    &["geom"],
    &["rng", "spill"],
];

/// The root's re-exports that code names as `crate::Name`, by the module
/// that defines them.
const ROOT_NAMES: &[(&str, &str)] =
    &[("Error", "error"), ("Database", "db"), ("ReadTransaction", "tree"), ("Scene", "scene")];

fn rank(module: &str) -> Option<usize> {
    let module = ROOT_NAMES.iter().find(|(n, _)| *n == module).map_or(module, |(_, m)| m);
    LAYERS.iter().position(|l| l.contains(&module))
}

fn sources(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).expect("src/ lists") {
        let p = e.expect("an entry of src/").path();
        if p.is_dir() {
            sources(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// The lines of a source file that are code, before its tests.
fn code(text: &str) -> impl Iterator<Item = &str> {
    text.lines().take_while(|l| !l.contains("#[cfg(test)]")).filter(|l| !l.trim_start().starts_with("//"))
}

/// What follows each `prefix` in `line` that starts a path (not after
/// `$` or `::`): the next name.
fn after<'a>(line: &'a str, prefix: &str) -> Vec<&'a str> {
    let mut out = Vec::new();
    let mut rest = line;
    while let Some(i) = rest.find(prefix) {
        let tail = &rest[i + prefix.len()..];
        let end = tail.find(|c: char| !(c.is_ascii_alphanumeric() || c == '_')).unwrap_or(tail.len());
        let before = &rest[..i];
        let starts = !(before.ends_with('$')
            || before.ends_with("::")
            || before.ends_with(|c: char| c.is_alphanumeric() || c == '_'));
        if starts && end > 0 {
            out.push(&tail[..end]);
        }
        rest = tail;
    }
    out
}

/// The modules a source file names as `crate::m`, outside comments.
fn named(text: &str) -> Vec<String> {
    code(text).flat_map(|l| after(l, "crate::")).map(str::to_string).collect()
}

/// `(module, submodule)` of a file under src/, for files inside a module.
fn submodule(rel: &Path) -> Option<(String, String)> {
    let parts: Vec<String> =
        rel.iter().map(|p| p.to_string_lossy().trim_end_matches(".rs").to_string()).collect();
    (parts.len() >= 2 && parts[1] != "mod").then(|| (parts[0].clone(), parts[1].clone()))
}

#[test]
fn no_two_submodules_of_a_module_name_each_other() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    sources(&src, &mut files);
    let mut edges = BTreeSet::new();
    for f in &files {
        let rel = f.strip_prefix(&src).expect("under src/");
        let Some((top, sub)) = submodule(rel) else { continue };
        let text = std::fs::read_to_string(f).expect("a source file reads");
        // `super::x` names a sibling from `top/sub.rs`, and
        // `super::super::x` from a file one folder deeper.
        let depth = rel.iter().count();
        let up = if depth == 2 { "super::" } else { "super::super::" };
        let own = format!("crate::{top}::");
        for line in code(&text) {
            let siblings = after(line, up).into_iter().filter(|n| *n != "super");
            let by_path = line
                .match_indices(own.as_str())
                .map(|(i, m)| &line[i + m.len()..])
                .map(|t| &t[..t.find(|c: char| !(c.is_ascii_alphanumeric() || c == '_')).unwrap_or(t.len())]);
            for name in siblings.chain(by_path) {
                if name.chars().next().is_some_and(|c| c.is_ascii_lowercase()) && name != sub {
                    edges.insert((sub.clone(), format!("{top}/{name}"), format!("{top}/{sub}")));
                }
            }
        }
    }
    let has = |from: &str, to: &str| edges.iter().any(|(_, t, f)| f == from && t == to);
    let cycles: Vec<String> = edges
        .iter()
        .filter(|(_, to, from)| from < to && has(to, from))
        .map(|(_, to, from)| format!("{from} <-> {to}"))
        .collect();
    assert!(cycles.is_empty(), "submodules that import each other:\n{}", cycles.join("\n"));
}

#[test]
fn every_module_names_only_modules_below_it() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    sources(&src, &mut files);
    assert!(files.len() > 50, "src/ holds the crate");
    let mut faults = Vec::new();
    for f in &files {
        let rel = f.strip_prefix(&src).expect("under src/");
        let first = rel.components().next().expect("a path").as_os_str().to_string_lossy();
        let module = first.trim_end_matches(".rs").to_string();
        let Some(own) = rank(&module) else {
            faults.push(format!("{}: module `{module}` is not in lib.rs's layers", rel.display()));
            continue;
        };
        let text = std::fs::read_to_string(f).expect("a source file reads");
        for target in named(&text) {
            if target == module {
                continue;
            }
            match rank(&target) {
                Some(r) if r > own => {}
                Some(_) => {
                    faults.push(format!("{}: `{module}` names `{target}`, above or beside it", rel.display()))
                }
                None => faults.push(format!("{}: names `crate::{target}`, not a layer", rel.display())),
            }
        }
    }
    assert!(faults.is_empty(), "layering faults:\n{}", faults.join("\n"));
}

#[test]
fn the_check_sees_a_fault() {
    // The scanner itself: an upward name is found, a comment is not.
    let text = "use crate::db::ReadTransaction;\n// crate::query::walk\nlet x = $crate::geom::Aabb;\n#[cfg(test)]\nuse crate::lib;";
    assert_eq!(named(text), vec!["db".to_string()]);
    assert_eq!(after("use super::{a, b}; super::driver::Ctx; crate::super::z", "super::"), vec!["driver"]);
    assert!(rank("query") > rank("db"));
}
