//! The redb backend against mktree's own file on generated scenes: block
//! reads, redb's page reads, time per query and file sizes, as a Markdown
//! table (`src/redb_backend.rs`).
//!
//! ```sh
//! cargo run --release -p mktree-bench --features redb --example bench_redb -- tanker2 tanker3 ship:100000
//! ```

use mktree::scene::generate::{GenOptions, Preset, generate_scene};
use mktree_bench::{bench_redb, redb_table};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dir = tempfile::tempdir()?;
    let mut rows = Vec::new();
    for arg in std::env::args().skip(1) {
        let (name, objects) = match arg.split_once(':') {
            Some((n, o)) => (n.to_string(), Some(o.parse()?)),
            None => (arg.clone(), None),
        };
        let preset = Preset::ALL.into_iter().find(|p| p.name() == name).ok_or(format!("no preset {name}"))?;
        let scene = generate_scene(&GenOptions { preset, objects, seed: 0 })?;
        rows.extend(bench_redb(&arg, &scene, 200, 0, dir.path(), &|s| eprintln!("{s}"))?);
        print!("{}", redb_table(&rows));
    }
    Ok(())
}
