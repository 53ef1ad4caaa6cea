//! What subcommands read: scenes (files or generator presets), .mkt files
//! (opened with errors that say what to do), and trees, from a file or
//! built in memory.

use std::path::Path;
use std::sync::{Mutex, PoisonError};

use anyhow::{Context, Result};
use mktree::bulk::{BuildProgress, Hierarchy, TimeLeft, build};
use mktree::db::{Database, LayoutDrift, TreeInfo, read_hierarchy, read_tree_and_drift};
use mktree::scene::Scene;
use mktree::scene::generate::{GenOptions, Preset, generate_scene};
use mktree::scene::import::{ImportOptions, load};
use mktree::store::StorageError;
use mktree::store::device::{RemoteOptions, is_remote_url};

use crate::args::BuildArgs;
use crate::memory::release_freed_memory;

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
    let db = match path.to_str().filter(|name| is_remote_url(name)) {
        Some(url) => Database::open_url(url, &RemoteOptions::default()).map_err(|e| opening(e, path))?,
        None => Database::open_read_only(path).map_err(|e| opening(e, path))?,
    };
    for w in db.warnings() {
        eprintln!("warning: {}: {w}", path.display());
    }
    Ok(db)
}

/// The clash store at `path`, locked for a writer; says so on stderr
/// when it waits for another process that holds it.
pub fn lock_store(path: &Path) -> Result<mktree::clash::StoreLock> {
    use mktree::clash::StoreLock;
    if let Some(lock) = StoreLock::try_acquire(path)? {
        return Ok(lock);
    }
    eprintln!("waiting for another process writing {}", path.display());
    Ok(StoreLock::acquire(path)?)
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

/// True when `path` is an .mkt file (by its magic number), or a URL, which
/// only an .mkt file is read from.
pub fn is_mkt(path: &Path) -> bool {
    path.to_str().is_some_and(is_remote_url) || mktree::db::is_mktree_file(path)
}

/// The tree of an .mkt file, or of a scene built in memory with `build`,
/// with the file's info or the build time; a file's layout drift too when
/// `drift` asks (from the same read of its node blocks).
pub fn tree_of(input: &Path, build: &BuildArgs, drift: bool) -> Result<(Hierarchy, Source)> {
    if is_mkt(input) {
        let db = open_to_read(input)?;
        let r = db.begin_read()?;
        let info = Box::new(r.info().context("the file holds no tree")?);
        if drift {
            let (tree, drift) = read_tree_and_drift(&r)?;
            return Ok((tree, Source::File(info, drift)));
        }
        Ok((read_hierarchy(&r)?, Source::File(info, None)))
    } else {
        let scene = read_scene(input, &build.import.options())?;
        let started = std::time::Instant::now();
        let tree = build_in_memory(&scene, build)?;
        Ok((tree, Source::Memory { seconds: started.elapsed().as_secs_f64() }))
    }
}

/// Where a tree came from.
pub enum Source {
    /// A file's info, and its layout drift when asked for.
    File(Box<TreeInfo>, Option<LayoutDrift>),
    Memory {
        seconds: f64,
    },
}

/// Builds the tree of `scene` in memory, with a progress bar.
pub fn build_in_memory(scene: &Scene, args: &BuildArgs) -> Result<Hierarchy> {
    let sizes: Vec<u64> = scene.objects().iter().map(|o| mktree::bulk::object_bytes(&o.mesh)).collect();
    let pb = crate::output::progress_bar();
    let clock = Mutex::new(TimeLeft::new());
    let tree = build(&scene.object_boxes(), Some(&sizes), &args.params(), &|p: BuildProgress| {
        let mut clock = clock.lock().unwrap_or_else(PoisonError::into_inner);
        crate::output::show_progress(&pb, &mut clock, &p.as_stage())
    })?;
    pb.finish_and_clear();
    Ok(tree)
}

/// A key as typed: [`mktree::Key::parse`] (an integer only when written as one,
/// digits alone: `+5` and `05` are text), or its bytes when `bytes`.
///
/// A key that is not UTF-8 is read as the importers read a name that is
/// not (each bad sequence one U+FFFD), so `--key-names` keys are reached
/// by the names they came from.
pub fn parse_key(text: &std::ffi::OsStr, bytes: bool) -> Result<mktree::Key> {
    let text = text.to_string_lossy();
    Ok(if bytes { mktree::Key::bytes(text.as_bytes())? } else { mktree::Key::parse(&text)? })
}
