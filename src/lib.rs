//! # mktree
//!
//! A persistent spatial index for very large 3D scenes (ship, plant and
//! building models of thousands to millions of triangle-mesh objects), after
//! the MKtree (Multiresolution Kd-tree) of Franquesa-Niubó and Brunet: a
//! binary bounding-volume hierarchy bulk-loaded from the whole scene, with
//! coarser bounds of the objects (levels of detail) stored in the leaves
//! where they pay, in a transactional file of fixed-size blocks whose reads
//! every query counts.
//!
//! # Start here
//!
//! - [`Database`] is the file: [`Database::create`], [`Database::open`],
//!   [`Database::open_read_only`]. Any number of processes may open one
//!   file; one of them writes at a time.
//! - [`Database::begin_write`] gives a [`WriteTransaction`]: load a whole
//!   [`Scene`] with [`WriteTransaction::bulk_load`], or change objects by
//!   their [`Key`] with [`WriteTransaction::insert`],
//!   [`WriteTransaction::update`] and [`WriteTransaction::remove`]; then
//!   [`WriteTransaction::commit`] (atomic: the old tree or the new one).
//! - [`Database::begin_read`] gives a [`ReadTransaction`], a snapshot that
//!   no later commit changes. Its queries: [`ReadTransaction::query_box`]
//!   and [`ReadTransaction::select`] (any [`Region`], one hit at a time),
//!   [`ReadTransaction::nearest`], [`ReadTransaction::ray`],
//!   [`ReadTransaction::view`], [`ReadTransaction::get`] by key; and in
//!   [`query`], [`query::collide`] (a posed mesh) and [`query::clash`] (the
//!   tree against itself). Each answer carries the blocks it read.
//!
//! ```
//! use mktree::{Aabb, BuildParams, CreateOptions, Database, QueryOptions, Region};
//! use mktree::scene::generate::{GenOptions, Preset, generate_scene};
//!
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! // A generated scene of 222 objects; `scene::import::load` reads OBJ, STL and glTF.
//! let scene = generate_scene(&GenOptions { preset: Preset::Tanker1, objects: None, seed: 0 })?;
//! let dir = std::env::temp_dir().join(format!("mktree-doc-{}", std::process::id()));
//! std::fs::create_dir_all(&dir)?;
//! let db = Database::create(dir.join("t1.mkt"), CreateOptions::default())?;
//!
//! let mut w = db.begin_write()?;
//! w.bulk_load(&scene, &BuildParams::default(), &|_| {})?;
//! w.commit()?;
//!
//! let r = db.begin_read()?;
//! let everything = r.query_box(&scene.aabb())?;
//! assert_eq!(everything.objects.len(), scene.len());
//! let corner = r.query_box(&Aabb::from_array([0.0, 0.0, 0.0, 500.0, 500.0, 500.0]))?;
//! println!("{} objects in the corner, {} block reads", corner.objects.len(), corner.stats.reads.total());
//!
//! // The same traversal, lazily: stop early and only the blocks read so far are read.
//! let region = Region::Box(scene.aabb());
//! let mut hits = r.select(&region, &QueryOptions::default(), None)?;
//! let first = hits.next().expect("the scene's box meets every object")?;
//! assert!(everything.objects.contains(&first.object));
//! # drop(hits);
//! # drop((r, db));
//! # std::fs::remove_dir_all(&dir)?;
//! # Ok(())
//! # }
//! ```
//!
//! # Layers
//!
//! Each module uses only those below it, in this order: [`catalog`] (many
//! files queried as one), [`tiles`] and [`clash`] (3D Tiles, typed clash
//! tests), over [`render`] (pictures), over
//! [`db`] (the database: opening, transactions, the commit protocol,
//! check, the bulk load's writer in `db/load/` and change commits in
//! `db/write/`), over [`query`] (every query family, one traversal), over
//! `tree` (a snapshot's verified, counted block reads and what its records
//! and meta block say; [`ReadTransaction`] lives here, and `db` only opens
//! and ends it), over [`lod`] (levels of detail), over [`bulk`] (the bulk
//! loaders and the in-memory hierarchy), over [`store`] (blocks, pager,
//! format records), over [`scene`] (objects, import, generator), over
//! [`geom`] (boxes and exact tests). The crate's [`Error`] sits between db
//! and query: db's operations return it, and it wraps the errors of the
//! layers below. The transaction lends the load pipeline and the change
//! commits allocation and owns the commit protocol (format-spec/commit.md).
//! `tests/layering.rs` holds the code to this order.
//!
//! The storage format is specified in the repository's `format-spec/`. Its
//! machinery (the pager, record formats and walks, the read model, the
//! voxel codec, the clash store's layout, the brute-force oracles) is
//! public only with the `internals` feature, which the CLI, the benches,
//! the fuzz targets and the tests turn on.

// The one exception is the byte-range locks of src/store/lock.rs (fcntl).
#![deny(unsafe_code)]
#![deny(missing_docs)]

pub use bulk::{BuildParams, LeafRule, Method};
pub use catalog::{Catalog, CatalogError};
pub use clash::{Clash, ClashError, ClashKind, ClashRun, ClashTest, GroupBy, Selector, TestKind};
pub use db::{
    ChangeStats, CheckReport, Compaction, CreateOptions, Database, LayoutDrift, ReadTransaction, TreeInfo,
    WriteTransaction, check,
};
pub use error::Error;
pub use geom::{Aabb, Point, Ray, Vector};
pub use lod::LodParams;
pub use query::{
    Hit, Near, QueryAnswer, QueryOptions, RayHit, Region, Selection, View, ViewCut, ViewOptions,
};
pub use scene::{Key, KeyError, Mesh, Object, ObjectId, Scene};
pub use store::StorageError;
pub use store::format::change_log::{ChangeKind, LoggedChange};

/// The README's examples run as doctests.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
struct ReadmeDoctests;

/// Re-exports public only with the `internals` feature (the fuzz targets'
/// bodies, the tests, the benches and the CLI); crate-visible otherwise, so
/// an embedder's surface holds no stage of the engine's own machinery.
macro_rules! internal_use {
    ($($tree:tt)*) => {
        #[cfg(feature = "internals")]
        pub use $($tree)*;
        #[cfg(not(feature = "internals"))]
        #[allow(unused_imports)]
        pub(crate) use $($tree)*;
    };
}

pub mod bulk;
pub mod catalog;
pub mod clash;
pub mod db;
mod error;
pub mod geom;
pub mod lod;
pub mod query;
#[cfg(feature = "redb")]
pub mod redb;
pub mod render;
mod rng;
pub mod scene;
mod spill;
pub mod store;
pub mod tiles;
mod tree;
