//! One file per subcommand; `run` dispatches.

mod batch;
pub mod bench_build;
pub mod bench_changes;
mod bench_import;
pub mod bench_peers;
mod bench_queries;
pub mod bench_replace;
pub mod bench_view;
mod build;
mod check;
mod clash;
mod collide;
mod compact;
mod demo;
mod dump;
mod export_tiles;
mod gen_info;
mod get;
mod insert;
mod lods;
mod navigate;
mod query;
mod remove;
pub(crate) mod render;
mod serve;
mod stats;
mod sweep;
mod tradeoff;
mod verify;
mod view;

use std::path::Path;

use anyhow::{Context, Result};
use mktree::build::Hierarchy;
use mktree::db::{Database, TreeInfo, read_hierarchy};
use mktree::scene::Scene;
use mktree::scene::generate::{GenOptions, Preset, generate_scene};
use mktree::scene::import::{ImportOptions, load};
use mktree::store::StorageError;

use crate::args::{BuildArgs, Cli, Command};

pub fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Gen { preset, objects, seed, output } => gen_info::generate(&preset, objects, seed, &output),
        Command::Info { scene, json, import } => gen_info::info(&scene, &import.options(), json),
        Command::Stats { input, build, json } => stats::run(&input, &build, json),
        Command::Dump { input, build, json } => dump::run(&input, &build, json),
        Command::Sweep { scene, pages, rates, look_ahead, json, import } => {
            sweep::run(&scene, &import.options(), pages, &rates, look_ahead, json)
        }
        Command::Build { scene, output, build, lod, wait, key_names, memory, stage, json } => {
            build::run(&scene, &output, &build, &lod, build::Write { wait, key_names, memory, stage }, json)
        }
        Command::Verify { file, scene, queries, json, import } => {
            verify::run(&file, &scene, queries, &import.options(), json)
        }
        Command::Lods { file, json } => lods::table(&file, json),
        Command::Node { file, node, lod, objects, export, json } => {
            lods::node(&file, node, lod, objects, export.as_deref(), json)
        }
        Command::Query { file, aabb, sphere, frustum, level, json } => {
            query::run(&file, &query::shape(aabb, sphere, frustum)?, &level.options(), json)
        }
        Command::Collide { file, mesh, object, translate, rotate_deg, clearance, level, json, import } => {
            let query = collide::Query { mesh, object, translate, rotate_deg, clearance };
            collide::run(&file, &query, &level.options(), &import.options(), json)
        }
        Command::Clash { file, clearance, lod, json } => clash::run(&file, clearance, lod, json),
        Command::Batch { file, queries, max_line } => batch::run(&file, queries.as_deref(), max_line),
        Command::View { file, view } => view::run(&file, &view),
        Command::Export3dTiles { file, out, json } => export_tiles::run(&file, &out, json),
        Command::Serve { tiles, port, vendor } => serve::run(&tiles, port, vendor.as_deref()),
        Command::Render { file, view, node, lod, objects, output, json } => {
            let what = match (node, lod) {
                (Some(node), Some(k)) => render::What::Node { node, k, objects },
                _ => render::What::Cut,
            };
            render::run(&file, &view, what, &output, json)
        }
        Command::Navigate {
            file,
            path,
            cache_blocks,
            fov_deg,
            aspect,
            near,
            far,
            lod,
            tolerance,
            height_px,
            budget,
            json,
        } => {
            let lens = [fov_deg, aspect, near, far];
            match tolerance {
                Some(tau) => {
                    let opts = mktree::ViewOptions { tolerance_px: tau, budget, shapes: false };
                    navigate::run_view(&file, &path, cache_blocks, lens, height_px, &opts, json)
                }
                None => navigate::run(&file, &path, cache_blocks, lens, lod, json),
            }
        }
        Command::Tradeoff { files, queries, seed, out, json } => {
            tradeoff::run(&files, queries, seed, &out, json)
        }
        Command::Get { file, key, text, mesh, json } => {
            get::run(&file, &get::parse_key(&key, text)?, mesh, json)
        }
        Command::Check { file, json } => check::run(&file, json),
        Command::Compact { file, wait, json } => compact::run(&file, wait, json),
        Command::Insert { file, scene, key_names, json } => {
            insert::run_insert(&file, &scene, key_names, json)
        }
        Command::Move { file, key, text, by, json } => {
            insert::run_move(&file, &get::parse_key(&key, text)?, by, json)
        }
        Command::Remove { file, keys, text, wait, json } => {
            let keys = keys.iter().map(|k| get::parse_key(k, text)).collect::<Result<Vec<_>>>()?;
            remove::run(&file, &keys, wait, json)
        }
        Command::Demo { dir } => demo::run(&dir),
        Command::BenchQueries { files, queries, shares, seed, json } => {
            bench_queries::run(&files, queries, &shares, seed, json)
        }
        Command::BenchBuild(args) => bench_build::run(&args),
        Command::BenchPeers(args) => bench_peers::run(&args),
        Command::BenchReplace(args) => bench_replace::run(&args),
        Command::BenchChanges(args) => bench_changes::run(&args),
        Command::BenchView(args) => bench_view::run(&args),
        Command::BenchImport { files, repeat, json, import } => {
            bench_import::run(&files, repeat, &import, json)
        }
    }
}

/// Reads a scene, printing the zero-area triangle warning to stderr.
pub fn read_scene(path: &Path, options: &ImportOptions) -> Result<Scene> {
    let imported = load(path, options)?;
    warn_degenerate(imported.degenerate_triangles);
    release_freed_memory();
    Ok(imported.scene)
}

/// The folder `file` is in, where spill files beside it go.
pub fn folder_of(file: &Path) -> &Path {
    match file.parent() {
        Some(dir) if !dir.as_os_str().is_empty() => dir,
        _ => Path::new("."),
    }
}

/// Warns on stderr about zero-area triangles an import kept.
pub fn warn_degenerate(triangles: usize) {
    if triangles > 0 {
        eprintln!("mktree: warning: {triangles} zero-area triangles kept");
    }
}

/// Hands the import's freed buffers back to the system. The parallel
/// importers free them in the allocator's per-thread arenas, where glibc
/// keeps them and the build's later allocations, mostly on other arenas,
/// do not reuse them: without this, ship 10^6 peaks 0.3 GB higher.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
pub fn release_freed_memory() {
    // SAFETY: malloc_trim only returns free pages of the allocator's
    // arenas to the system; it touches no live allocation.
    unsafe {
        libc::malloc_trim(0);
    }
}

#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
pub fn release_freed_memory() {}

/// The process's peak resident memory so far (the kernel's VmHWM), where
/// the system tells it.
pub fn peak_rss_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find_map(|l| l.strip_prefix("VmHWM:"))?;
    let kb: u64 = line.trim().strip_suffix("kB")?.trim().parse().ok()?;
    Some(kb * 1024)
}

/// A scene named on the command line: a scene file, or else a preset of
/// the generator (`tanker1`, ..., `ship`, `ship:N` for N objects, seed 0).
pub fn scene_or_preset(arg: &str, options: &ImportOptions) -> Result<Scene> {
    scene_or_seeded_preset(arg, options, 0)
}

/// [`scene_or_preset`] with the generator's seed.
pub fn scene_or_seeded_preset(arg: &str, options: &ImportOptions, seed: u64) -> Result<Scene> {
    let path = Path::new(arg);
    if path.exists() {
        return read_scene(path, options);
    }
    let (name, objects) = match arg.split_once(':') {
        Some((name, n)) => {
            (name, Some(n.parse::<u64>().with_context(|| format!("{arg}: {n:?} is not a count"))?))
        }
        None => (arg, None),
    };
    let preset = name.parse::<Preset>().with_context(|| format!("{arg} is neither a file nor a preset"))?;
    Ok(generate_scene(&GenOptions { preset, objects, seed })?)
}

/// Opens an .mkt file to read, printing what opening noticed (a damaged
/// slot copy, an interrupted transaction) to stderr.
pub fn open_to_read(path: &Path) -> Result<Database> {
    let db = Database::open_read_only(path).map_err(|e| opening(e, path))?;
    for w in db.warnings() {
        eprintln!("warning: {}: {w}", path.display());
    }
    Ok(db)
}

/// An error opening `path` to read or change its tree, naming the file
/// unless the error already does; a scene file passed where an .mkt file
/// belongs gets the `build` command that makes one.
pub fn opening(e: StorageError, path: &Path) -> anyhow::Error {
    match e {
        StorageError::Open { .. } => e.into(),
        StorageError::NotMktree => anyhow::anyhow!("{}", not_mktree(path)),
        // A scene shorter than a header is refused as truncated before its
        // magic number is read.
        StorageError::Truncated { .. } if is_scene_path(path) && !is_mkt(path) => {
            anyhow::anyhow!("{}", not_mktree(path))
        }
        e => anyhow::Error::new(e).context(format!("opening {}", path.display())),
    }
}

/// Why `path` cannot be opened as an MKtree file, and what to do instead:
/// a scene (by its extension) is built first; anything else is named.
fn not_mktree(path: &Path) -> String {
    if is_scene_path(path) {
        let mkt = path.with_extension("mkt");
        format!(
            "{} is a scene, not an MKtree file: build it first with `mktree build {} -o {}`",
            path.display(),
            path.display(),
            mkt.display()
        )
    } else {
        format!(
            "{} is not an MKtree file (bad magic number): `mktree build SCENE -o FILE.mkt` makes one",
            path.display()
        )
    }
}

/// True when `path` names a scene file by its extension (OBJ, STL, glTF).
fn is_scene_path(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| ["obj", "stl", "gltf", "glb"].iter().any(|s| e.eq_ignore_ascii_case(s)))
}

/// True when `path` is an .mkt file (by its magic number).
pub fn is_mkt(path: &Path) -> bool {
    mktree::db::is_mktree_file(path)
}

/// The tree of an .mkt file, or of a scene built in memory with `build`,
/// with the file's info or the build time.
pub fn tree_of(input: &Path, build: &BuildArgs) -> Result<(Hierarchy, Source)> {
    if is_mkt(input) {
        let db = open_to_read(input)?;
        let r = db.begin_read()?;
        let info = r.info().context("the file holds no tree")?;
        Ok((read_hierarchy(&r)?, Source::File(Box::new(info))))
    } else {
        let scene = read_scene(input, &build.import.options())?;
        let started = std::time::Instant::now();
        let tree = crate::cmd::build::build_in_memory(&scene, build)?;
        Ok((tree, Source::Memory { seconds: started.elapsed().as_secs_f64() }))
    }
}

/// Where a tree came from.
pub enum Source {
    File(Box<TreeInfo>),
    Memory { seconds: f64 },
}
