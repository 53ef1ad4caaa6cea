//! Where a model's file lies (a URL or a path relative to the catalog's
//! folder) and opening it to read, with the settings a catalog reader
//! shares among its models; and running work on many models at once.

use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

use super::CatalogError;
use crate::db::Database;
use crate::store::device::is_remote_url;

/// How a catalog reader opens and queries its models.
#[derive(Debug, Clone)]
pub struct CatalogOptions {
    /// Models opened or queried at once (at least 1). Default 16: the work
    /// is mostly waiting for storage, so more threads than cores pay.
    pub concurrency: usize,
    /// How models at URLs are read: cache bound, store settings, retries.
    #[cfg(feature = "object-store")]
    pub remote: crate::store::device::RemoteOptions,
}

impl Default for CatalogOptions {
    fn default() -> CatalogOptions {
        CatalogOptions {
            concurrency: 16,
            #[cfg(feature = "object-store")]
            remote: crate::store::device::RemoteOptions::default(),
        }
    }
}

/// Where a location names a file: a URL as written, a relative path under
/// `base`.
pub(super) enum Place {
    Url(String),
    File(PathBuf),
}

pub(super) fn place(location: &str, base: Option<&Path>) -> Place {
    if is_remote_url(location) {
        return Place::Url(location.to_string());
    }
    let path = Path::new(location);
    match base {
        Some(dir) if path.is_relative() => Place::File(dir.join(path)),
        _ => Place::File(path.to_path_buf()),
    }
}

/// Opens model `key`'s file to read.
#[cfg_attr(
    not(feature = "object-store"),
    expect(unused_variables, reason = "options only set how URLs are read")
)]
pub(super) fn open(
    key: &str,
    location: &str,
    base: Option<&Path>,
    options: &CatalogOptions,
) -> Result<Database, CatalogError> {
    let failed = |source| CatalogError::Model {
        model: key.to_string(),
        location: location.to_string(),
        source: Box::new(source),
    };
    match place(location, base) {
        Place::File(path) => Database::open_read_only(path).map_err(failed),
        #[cfg(feature = "object-store")]
        Place::Url(url) => Database::open_url(&url, &options.remote).map_err(failed),
        #[cfg(not(feature = "object-store"))]
        Place::Url(url) => Err(CatalogError::NoRemote { model: key.to_string(), location: url }),
    }
}

/// `work(i)` for every `i < n`, on at most `width` threads; the results in
/// order of `i`.
pub(super) fn in_parallel<T: Send>(n: usize, width: usize, work: impl Fn(usize) -> T + Sync) -> Vec<T> {
    let width = width.clamp(1, n.max(1));
    if width == 1 {
        return (0..n).map(work).collect();
    }
    let next = AtomicUsize::new(0);
    let done: Vec<Mutex<Option<T>>> = (0..n).map(|_| Mutex::new(None)).collect();
    std::thread::scope(|s| {
        for _ in 0..width {
            s.spawn(|| {
                loop {
                    let i = next.fetch_add(1, Ordering::Relaxed);
                    if i >= n {
                        break;
                    }
                    let result = work(i);
                    *done[i].lock().unwrap_or_else(|p| p.into_inner()) = Some(result);
                }
            });
        }
    });
    // A worker that panicked has ended the scope above with its panic.
    done.into_iter()
        .map(|m| m.into_inner().unwrap_or_else(|p| p.into_inner()).expect("every index ran"))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn work_runs_once_per_index_in_order() {
        for width in [1, 2, 7, 100] {
            let out = in_parallel(23, width, |i| i * i);
            assert_eq!(out, (0..23).map(|i| i * i).collect::<Vec<_>>());
        }
        assert!(in_parallel(0, 4, |i| i).is_empty());
    }

    #[test]
    fn relative_paths_lie_under_the_catalog_and_urls_stay_as_written() {
        let base = Path::new("/data/models");
        assert!(matches!(place("a.mkt", Some(base)), Place::File(p) if p == base.join("a.mkt")));
        assert!(matches!(place("/x/a.mkt", Some(base)), Place::File(p) if p == Path::new("/x/a.mkt")));
        assert!(matches!(place("s3://b/a.mkt", Some(base)), Place::Url(u) if u == "s3://b/a.mkt"));
        assert!(matches!(place("a.mkt", None), Place::File(p) if p == Path::new("a.mkt")));
    }
}
