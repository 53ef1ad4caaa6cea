//! Catalogs: many committed files queried as one (issue 36,
//! format-spec/catalog.md). A [`Catalog`] names each model by a key, with
//! its location (a path or a URL), root box, object count and commit; a
//! [`CatalogReader`] answers a region query by opening and querying, in
//! parallel, only the models whose root box the region may meet, and names
//! each object by its model's key and its own.
//!
//! - `file.rs`: the catalog and its JSON document.
//! - `open.rs`: where a model lies, opening it, working on many at once.
//! - `reader.rs`: opening models on demand and fanning a query out.
//! - `error.rs`: what can go wrong.
//!
//! ```
//! use mktree::catalog::{Catalog, CatalogOptions};
//! use mktree::scene::generate::{GenOptions, Preset, generate_scene};
//! use mktree::{BuildParams, CreateOptions, Database, Region};
//!
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let dir = std::env::temp_dir().join(format!("mktree-catalog-doc-{}", std::process::id()));
//! std::fs::create_dir_all(&dir)?;
//! let scene = generate_scene(&GenOptions { preset: Preset::Tanker1, objects: None, seed: 0 })?;
//! let db = Database::create(dir.join("t1.mkt"), CreateOptions::default())?;
//! let mut w = db.begin_write()?;
//! w.bulk_load(&scene, &BuildParams::default(), &|_| {})?;
//! w.commit()?;
//! drop(db);
//!
//! let catalog = Catalog::describe(&[("t1", "t1.mkt")], Some(&dir), &CatalogOptions::default())?;
//! catalog.write(dir.join("models.json"))?;
//! let reader = Catalog::read(dir.join("models.json"))?.reader(CatalogOptions::default());
//! let answer = reader.query(&Region::Box(scene.aabb()), &Default::default())?;
//! assert_eq!(answer.hits().count(), scene.len());
//! # std::fs::remove_dir_all(&dir)?;
//! # Ok(())
//! # }
//! ```

mod error;
mod file;
mod open;
mod reader;

pub use error::CatalogError;
pub use file::{Catalog, CatalogModel, MAX_CATALOG_BYTES, MAX_MODELS, VERSION};
pub use open::CatalogOptions;
pub use reader::{CatalogAnswer, CatalogHit, CatalogReader, ModelAnswer};
