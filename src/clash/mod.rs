//! Clash detection as engineers use it (docs/clash.md): typed tests
//! between chosen sets, with tolerances, grouped results, statuses across
//! revisions and BCF export. Over [`db`](crate::db) and
//! [`query`](crate::query), as [`render`](crate::render) is.
//!
//! - `select.rs`: the sets A and B, by key, name or payload field globs.
//! - `test.rs`: a test (type, tolerance, distance) and a clash.
//! - `run.rs`: a run on a snapshot: candidate boxes, meshes, measures
//!   (`geom::solid`).
//! - `group.rs`: groups by proximity, A object or key prefix.
//! - `status.rs`: New, Active, Resolved across runs; Reviewed and
//!   Approved, set by a person, persist.
//! - `store/`: saved tests and recorded runs in a sidecar file
//!   (format-spec/clash-store.md), changed by one writer at a time
//!   (`store/lock.rs`).
//! - `incremental.rs`: a re-run measures only pairs with a changed object.
//! - `bcf.rs` and `zip.rs` (feature `bcf`): BCF 3.0 export, a topic per
//!   group with a viewpoint, components and a snapshot.
//! - `key_json.rs`: how keys are written in JSON.
//!
//! ```
//! use mktree::clash::{ClashTest, TestKind, run_test};
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! # let dir = std::env::temp_dir().join(format!("mktree-clash-doc-{}", std::process::id()));
//! # std::fs::create_dir_all(&dir)?;
//! # let scene = mktree::scene::generate::generate_scene(&mktree::scene::generate::GenOptions {
//! #     preset: mktree::scene::generate::Preset::Tanker1, objects: None, seed: 0 })?;
//! # let db = mktree::Database::create(dir.join("t.mkt"), Default::default())?;
//! # let mut w = db.begin_write()?;
//! # w.bulk_load(&scene, &Default::default(), &|_| {})?;
//! # w.commit()?;
//! let r = db.begin_read()?;
//! let test = ClashTest {
//!     a: vec!["name:pipe*".parse()?],
//!     b: Some(vec!["all".parse()?]),
//!     kind: TestKind::Clearance,
//!     distance: 50.0,
//!     ..Default::default()
//! };
//! let run = run_test(&r, &test)?;
//! for c in &run.clashes {
//!     println!("{} {} {} depth {} distance {}", c.a, c.b, c.kind.name(), c.depth, c.distance);
//! }
//! # drop((r, db));
//! # std::fs::remove_dir_all(&dir)?;
//! # Ok(())
//! # }
//! ```

#[cfg(feature = "bcf")]
mod bcf;
mod error;
mod group;
mod incremental;
pub mod key_json;
mod run;
mod select;
mod status;
mod store;
mod test;
#[cfg(feature = "bcf")]
mod zip;

#[cfg(feature = "bcf")]
pub use bcf::{BcfOptions, COLOUR_A, COLOUR_B, MAX_TOPICS, export_bcf};
pub use error::ClashError;
pub use group::{Group, GroupBy, group, group_ids};
pub use incremental::{FoundBy, Recorded, RunMode, rerun, run_recorded};
pub use run::{AT_D, ClashRun, RunStats, measure, run_test};
pub use select::{Candidate, MAX_SELECTOR, Selector, glob, in_set};
pub use status::{Status, Tracked, set_status, update};
pub use store::{ClashStore, StoreLock, lock_path, store_path};
internal_use!(store::{
    Fingerprint, HEADER_LEN, MAGIC, MAX_STORE_BYTES, OLDEST_VERSION, RecordedRun, SavedTest, VERSION,
});
#[cfg(feature = "internals")]
pub use store::envelope;
pub use test::{Clash, ClashKind, ClashTest, DEFAULT_TOLERANCE, MAX_DISTANCE, MAX_NAME, TestKind};
