//! lib.rs's "Layers": each top-level module of `src/` names only modules
//! below it (a `crate::m` path in code, comments aside), so no two modules
//! import each other.

use std::path::{Path, PathBuf};

/// Top to bottom; a module may name any module after it. `error` is the
/// crate's one error, which db's operations return and which wraps the
/// errors of the layers below; `rng` and `spill` are utilities.
const LAYERS: &[&[&str]] = &[
    &["lib"],
    &["clash", "tiles", "redb"],
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

/// The modules a source file names as `crate::m`, outside comments.
fn named(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    for line in text.lines().filter(|l| !l.trim_start().starts_with("//")) {
        let mut rest = line;
        while let Some(i) = rest.find("crate::") {
            let after = &rest[i + "crate::".len()..];
            let name: String = after.chars().take_while(|c| c.is_ascii_alphanumeric() || *c == '_').collect();
            // `mktree::crate::` cannot occur; `$crate::` (macros) and
            // `parry3d_f64::…` are not this crate's modules.
            let before = &rest[..i];
            if !before.ends_with('$') && !before.ends_with("::") && !name.is_empty() {
                out.push(name);
            }
            rest = after;
        }
    }
    out
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
    let text = "use crate::db::ReadTransaction;\n// crate::query::walk\nlet x = $crate::geom::Aabb;";
    assert_eq!(named(text), vec!["db".to_string()]);
    assert!(rank("query") > rank("db"));
}
