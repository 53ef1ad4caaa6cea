//! Claim: the README's command table lists every subcommand of the binary,
//! and no command the binary lacks; the file format version the README
//! names is the one a new file is written with (`format_version`, header
//! offset 8, format-spec/header.md) and the newest in
//! format-spec/versions.md; and the README stays a short first read (at
//! most 250 lines) whose links to the repository's pages all resolve.

mod common;

use std::collections::BTreeSet;
use std::path::Path;

use common::mktree;

fn repo_file(path: &str) -> String {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    std::fs::read_to_string(root.join(path)).unwrap_or_else(|e| panic!("{path}: {e}"))
}

/// The subcommands `mktree --help` lists, less `help`.
fn subcommands() -> BTreeSet<String> {
    let out = mktree().arg("--help").output().unwrap();
    assert!(out.status.success());
    let help = String::from_utf8(out.stdout).unwrap();
    let listed = help.split("Commands:").nth(1).expect("a Commands: section").split("\n\n").next().unwrap();
    listed
        .lines()
        .filter_map(|l| l.split_whitespace().next())
        .filter(|name| *name != "help")
        .map(str::to_string)
        .collect()
}

/// The first word of each row of the README's table headed `| command |`.
fn readme_commands(readme: &str) -> BTreeSet<String> {
    let table = readme.split("| command |").nth(1).expect("a table headed | command |");
    table
        .lines()
        .skip(2)
        .take_while(|l| l.starts_with('|'))
        .map(|row| {
            let cell = row.trim_start_matches('|').trim_start().trim_start_matches('`');
            cell.split(|c: char| c.is_whitespace() || c == '`').next().unwrap().to_string()
        })
        .collect()
}

#[test]
fn the_readme_command_table_lists_every_subcommand() {
    let (binary, readme) = (subcommands(), readme_commands(&repo_file("README.md")));
    assert!(binary.len() > 20, "{binary:?}");
    let missing: Vec<_> = binary.difference(&readme).collect();
    let stale: Vec<_> = readme.difference(&binary).collect();
    assert!(missing.is_empty() && stale.is_empty(), "README lacks {missing:?}; lists unknown {stale:?}");
}

/// Every number N in "format is version N" or "format version N".
fn versions_named(text: &str) -> Vec<u32> {
    let mut found = Vec::new();
    for phrase in ["format is version ", "format version "] {
        for (at, _) in text.match_indices(phrase) {
            let digits: String = text[at + phrase.len()..].chars().take_while(char::is_ascii_digit).collect();
            found.push(digits.parse().unwrap_or_else(|_| panic!("no number after {phrase:?}")));
        }
    }
    found
}

#[test]
fn the_readme_names_the_format_version_files_are_written_with() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("new.mkt");
    drop(mktree::db::Database::create(&path, mktree::db::CreateOptions::default()).unwrap());
    let header = std::fs::read(&path).unwrap();
    let written = u32::from_le_bytes(header[8..12].try_into().unwrap());

    let named = versions_named(&repo_file("README.md"));
    assert!(!named.is_empty(), "the README names no format version");
    assert!(named.iter().all(|&v| v == written), "README names {named:?}; files are version {written}");

    // versions.md's table ends with the newest version.
    let spec = repo_file("format-spec/versions.md");
    let newest = spec
        .lines()
        .filter_map(|l| l.strip_prefix("| ")?.split(' ').next()?.parse::<u32>().ok())
        .max()
        .expect("versions.md has a table of versions");
    assert_eq!(newest, written, "format-spec/versions.md's newest version");
}

#[test]
fn the_readme_is_short_and_its_links_resolve() {
    let readme = repo_file("README.md");
    let lines = readme.lines().count();
    assert!(lines <= 250, "README.md has {lines} lines; move the detail into docs/");
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut links = 0;
    for (at, _) in readme.match_indices("](") {
        let target = readme[at + 2..].split(')').next().unwrap();
        if target.starts_with("http") || target.starts_with('#') {
            continue;
        }
        let file = target.split('#').next().unwrap();
        assert!(root.join(file).exists(), "README links to {target}, which is not in the repository");
        links += 1;
    }
    assert!(links >= 10, "the README links to {links} pages; where to go next?");
}
