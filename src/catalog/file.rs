//! The catalog and its JSON document (format-spec/catalog.md): each
//! model's key, location, root box, object count and commit, checked on
//! every read, written whole.

use std::io::{Read, Write};
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::open::{CatalogOptions, in_parallel, open};
use super::{CatalogError, CatalogReader};
use crate::db::Database;
use crate::geom::Aabb;

/// The catalog version this library reads and writes.
pub const VERSION: u32 = 1;
/// The longest catalog document a reader accepts, bytes.
pub const MAX_CATALOG_BYTES: u64 = 64 << 20;
/// The most models a catalog holds.
pub const MAX_MODELS: usize = 1_000_000;
/// The longest model key, bytes.
const MAX_KEY_BYTES: usize = 255;

/// One model of a catalog: a committed file, and what decides, without
/// opening it, whether a query can meet it.
#[derive(Debug, Clone, PartialEq)]
pub struct CatalogModel {
    /// The model's key, unique in the catalog; answers qualify object keys by it.
    pub key: String,
    /// Where its file lies: a URL, or a path (relative to the catalog's folder).
    pub location: String,
    /// The tree's scene box at `commit`; `None` for a file with no tree.
    pub root_box: Option<Aabb>,
    /// Objects in the tree at `commit`.
    pub objects: u32,
    /// The commit (transaction id) described.
    pub commit: u64,
}

impl CatalogModel {
    /// Describes the committed tree of `db`, opened from `location`.
    pub fn of(key: &str, location: &str, db: &Database) -> Result<CatalogModel, CatalogError> {
        let snapshot = db.begin_read().map_err(|source| CatalogError::Model {
            model: key.to_string(),
            location: location.to_string(),
            source: Box::new(source),
        })?;
        let info = snapshot.info();
        Ok(CatalogModel {
            key: key.to_string(),
            location: location.to_string(),
            root_box: info.as_ref().map(|i| Aabb::from_array(i.scene_box)),
            objects: info.as_ref().map_or(0, |i| i.objects),
            commit: snapshot.txn(),
        })
    }
}

/// Models queried as one (format-spec/catalog.md).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Catalog {
    models: Vec<CatalogModel>,
    base: Option<PathBuf>,
}

/// The document's version, read before the rest so that another version
/// is named rather than refused for its fields.
#[derive(Deserialize)]
struct Version {
    mktree_catalog: u32,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Document {
    mktree_catalog: u32,
    models: Vec<Entry>,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Entry {
    key: String,
    location: String,
    root_box: Option<[f64; 6]>,
    objects: u32,
    commit: u64,
}

fn invalid(why: impl Into<String>) -> CatalogError {
    CatalogError::Invalid(why.into())
}

impl Catalog {
    /// A catalog of `models`, whose relative paths lie under `base`;
    /// checked by the document's rules.
    pub fn new(models: Vec<CatalogModel>, base: Option<PathBuf>) -> Result<Catalog, CatalogError> {
        if models.len() > MAX_MODELS {
            return Err(invalid(format!("{} models (at most {MAX_MODELS})", models.len())));
        }
        let mut keys = std::collections::HashSet::with_capacity(models.len());
        for m in &models {
            check_model(m)?;
            if !keys.insert(m.key.as_str()) {
                return Err(invalid(format!("model key {:?} appears twice", m.key)));
            }
        }
        Ok(Catalog { models, base })
    }

    /// Opens each `(key, location)` (in parallel) and describes its
    /// committed tree; relative paths lie under `base`.
    pub fn describe(
        entries: &[(&str, &str)],
        base: Option<&Path>,
        options: &CatalogOptions,
    ) -> Result<Catalog, CatalogError> {
        let models = in_parallel(entries.len(), options.concurrency, |i| {
            let (key, location) = entries[i];
            CatalogModel::of(key, location, &open(key, location, base, options)?)
        });
        Catalog::new(models.into_iter().collect::<Result<_, _>>()?, base.map(Path::to_path_buf))
    }

    /// The models, in the catalog's order.
    pub fn models(&self) -> &[CatalogModel] {
        &self.models
    }

    /// The folder relative paths lie under.
    pub fn base(&self) -> Option<&Path> {
        self.base.as_deref()
    }

    /// Parses a catalog document; relative paths lie under `base`.
    pub fn from_json(text: &[u8], base: Option<PathBuf>) -> Result<Catalog, CatalogError> {
        if text.len() as u64 > MAX_CATALOG_BYTES {
            return Err(invalid(format!("{} bytes (at most {MAX_CATALOG_BYTES})", text.len())));
        }
        let version: Version =
            serde_json::from_slice(text).map_err(|e| invalid(format!("not a catalog: {e}")))?;
        if version.mktree_catalog != VERSION {
            return Err(invalid(format!(
                "version {} (this library reads version {VERSION})",
                version.mktree_catalog
            )));
        }
        let doc: Document = serde_json::from_slice(text).map_err(|e| invalid(e.to_string()))?;
        let models = doc
            .models
            .into_iter()
            .map(|e| CatalogModel {
                key: e.key,
                location: e.location,
                root_box: e.root_box.map(Aabb::from_array),
                objects: e.objects,
                commit: e.commit,
            })
            .collect();
        Catalog::new(models, base)
    }

    /// The catalog's document.
    pub fn to_json(&self) -> String {
        let doc = Document {
            mktree_catalog: VERSION,
            models: self
                .models
                .iter()
                .map(|m| Entry {
                    key: m.key.clone(),
                    location: m.location.clone(),
                    root_box: m.root_box.as_ref().map(Aabb::to_array),
                    objects: m.objects,
                    commit: m.commit,
                })
                .collect(),
        };
        // Plain strings and finite numbers (checked by `new`) always serialize.
        serde_json::to_string_pretty(&doc).expect("a catalog serializes") + "\n"
    }

    /// Reads the catalog at `path`; relative paths lie in its folder.
    pub fn read(path: impl AsRef<Path>) -> Result<Catalog, CatalogError> {
        let path = path.as_ref();
        let io = |source| CatalogError::Io { path: path.display().to_string(), source };
        let mut text = Vec::new();
        // One byte past the bound tells a document that is too long.
        std::fs::File::open(path)
            .map_err(io)?
            .take(MAX_CATALOG_BYTES + 1)
            .read_to_end(&mut text)
            .map_err(io)?;
        let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
        Catalog::from_json(&text, Some(base))
    }

    /// Writes the catalog to `path` whole: a reader finds the old document
    /// or the new one.
    pub fn write(&self, path: impl AsRef<Path>) -> Result<(), CatalogError> {
        let path = path.as_ref();
        let io = |source| CatalogError::Io { path: path.display().to_string(), source };
        let name = path.file_name().ok_or_else(|| io(std::io::Error::other("not a file name")))?;
        // Unique to this process and call: two writers never share one.
        static CALLS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
        let call = CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let mut temporary = name.to_os_string();
        temporary.push(format!(".{}.{call}.tmp", std::process::id()));
        let temporary = path.with_file_name(temporary);
        let written = (|| {
            let mut f = std::fs::File::create(&temporary)?;
            f.write_all(self.to_json().as_bytes())?;
            f.sync_all()?;
            std::fs::rename(&temporary, path)
        })();
        if written.is_err() {
            let _ = std::fs::remove_file(&temporary);
        }
        written.map_err(io)
    }

    /// A reader of the catalog's models, which opens each when a query
    /// first needs it.
    pub fn reader(self, options: CatalogOptions) -> CatalogReader {
        CatalogReader::new(self, options)
    }
}

fn check_model(m: &CatalogModel) -> Result<(), CatalogError> {
    if m.key.is_empty() || m.key.len() > MAX_KEY_BYTES || m.key.chars().any(char::is_control) {
        return Err(invalid(format!(
            "model key {:?}: 1 to {MAX_KEY_BYTES} bytes without control characters",
            m.key
        )));
    }
    if m.location.is_empty() {
        return Err(invalid(format!("model {:?} has no location", m.key)));
    }
    match &m.root_box {
        Some(b) => {
            let a = b.to_array();
            if a.iter().any(|v| !v.is_finite()) || (0..3).any(|i| a[i] > a[i + 3]) {
                return Err(invalid(format!(
                    "model {:?}: root box {a:?} is not a finite, ordered box",
                    m.key
                )));
            }
        }
        None if m.objects > 0 => {
            return Err(invalid(format!("model {:?} has {} objects and no root box", m.key, m.objects)));
        }
        None => {}
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;

    fn model(key: &str, b: Option<[f64; 6]>) -> CatalogModel {
        CatalogModel {
            key: key.to_string(),
            location: format!("{key}.mkt"),
            root_box: b.map(Aabb::from_array),
            objects: u32::from(b.is_some()) * 7,
            commit: 3,
        }
    }

    #[test]
    fn documents_break_no_rule_unnoticed() {
        let ok = br#"{"mktree_catalog":1,"models":[{"key":"a","location":"a.mkt","root_box":[0,0,0,1,1,1],"objects":2,"commit":1}]}"#;
        assert_eq!(Catalog::from_json(ok, None).expect("valid").models().len(), 1);
        let refused: [(&[u8], &str); 7] = [
            (br#"{"mktree_catalog":2,"models":[]}"#, "version 2"),
            (br#"{"models":[]}"#, "not a catalog"),
            (br#"{"mktree_catalog":1,"models":[],"extra":0}"#, "extra"),
            (
                br#"{"mktree_catalog":1,"models":[{"key":"a","location":"a","root_box":[1,0,0,0,1,1],"objects":1,"commit":1}]}"#,
                "ordered",
            ),
            (
                br#"{"mktree_catalog":1,"models":[{"key":"","location":"a","root_box":null,"objects":0,"commit":1}]}"#,
                "model key",
            ),
            (
                br#"{"mktree_catalog":1,"models":[{"key":"a","location":"a","root_box":null,"objects":5,"commit":1}]}"#,
                "no root box",
            ),
            (b"[1,2", "not a catalog"),
        ];
        for (text, why) in refused {
            let e = Catalog::from_json(text, None).expect_err("refused").to_string();
            assert!(e.contains(why), "{e} lacks {why:?}");
        }
        let twice = Catalog::new(vec![model("a", None), model("a", None)], None);
        assert!(twice.expect_err("duplicate").to_string().contains("twice"));
    }

    #[test]
    fn a_document_longer_than_the_bound_is_refused_before_parsing() {
        let long = vec![b' '; MAX_CATALOG_BYTES as usize + 1];
        assert!(Catalog::from_json(&long, None).expect_err("too long").to_string().contains("bytes"));
    }

    proptest! {
        #[test]
        fn a_written_catalog_reads_back_equal(
            boxes in proptest::collection::vec(
                proptest::option::of(proptest::array::uniform6(-1e9f64..1e9)), 0..20),
        ) {
            let models: Vec<CatalogModel> = boxes
                .iter()
                .enumerate()
                .map(|(i, b)| {
                    let b = b.map(|a| {
                        let lo = [a[0].min(a[3]), a[1].min(a[4]), a[2].min(a[5])];
                        let hi = [a[0].max(a[3]), a[1].max(a[4]), a[2].max(a[5])];
                        [lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]]
                    });
                    model(&format!("model {i}"), b)
                })
                .collect();
            let catalog = Catalog::new(models, None).expect("valid");
            let back = Catalog::from_json(catalog.to_json().as_bytes(), None).expect("reads back");
            prop_assert_eq!(back, catalog);
        }
    }
}
