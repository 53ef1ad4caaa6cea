//! The optional on-disk cache of pages an [`ObjectStoreDevice`] fetched
//! (format-spec/remote.md, "On-disk cache"): a folder the caller names,
//! shared by the processes that read the same objects, bounded in bytes.
//! One file per page, under a folder per object version (its URL, size,
//! ETag, version and time, and a hash of the header's bytes, which every
//! commit changes), each page followed by its CRC-32 so that a
//! damaged or torn file is a miss, never a wrong byte.
//!
//! [`ObjectStoreDevice`]: super::ObjectStoreDevice

use std::fs;
use std::io::{self, Read};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::SystemTime;

/// Where an on-disk cache lies and how large it may grow.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DiskCacheOptions {
    /// The cache's folder, created if missing; shared by every object and
    /// every process that names it.
    pub dir: PathBuf,
    /// Upper bound of the bytes of its page files: past it, the pages least
    /// recently used (by file time) go first. Processes sharing the folder
    /// each keep to it as they see the folder, so it may be passed briefly.
    pub bytes: u64,
}

/// One object version's pages in the cache folder.
pub(super) struct DiskCache {
    root: PathBuf,
    dir: PathBuf,
    bound: u64,
    /// Bytes of page files in the whole folder, as last counted plus what
    /// this cache added since; counted at the first write, not at open.
    used: std::sync::OnceLock<AtomicU64>,
}

/// The file name's suffix of a page.
const PAGE: &str = "page";

impl DiskCache {
    /// The cache of the object `identity` names (its URL, size, ETag,
    /// version and time: a new version is a new folder).
    pub(super) fn open(options: &DiskCacheOptions, identity: &str) -> io::Result<DiskCache> {
        let dir = options.dir.join(format!("{:016x}", fingerprint(identity)));
        fs::create_dir_all(&dir)?;
        // Two identities with one fingerprint: the folder is the later's.
        let named = dir.join("identity");
        if fs::read_to_string(&named).ok().as_deref() != Some(identity) {
            for e in fs::read_dir(&dir)?.flatten() {
                let _ = fs::remove_file(e.path());
            }
            write_whole(&named, identity.as_bytes())?;
        }
        Ok(DiskCache {
            root: options.dir.clone(),
            dir,
            bound: options.bytes,
            used: std::sync::OnceLock::new(),
        })
    }

    fn path(&self, page: u64) -> PathBuf {
        self.dir.join(format!("{page}.{PAGE}"))
    }

    /// Page `page`, `len` bytes long, if the folder holds it whole: a file
    /// of another length, or that is not a plain file, or whose checksum
    /// fails, is removed and missed.
    pub(super) fn get(&self, page: u64, len: usize) -> Option<Vec<u8>> {
        let path = self.path(page);
        let file = fs::File::open(&path).ok()?;
        let whole = file.metadata().ok().is_some_and(|m| m.is_file() && m.len() == len as u64 + 4);
        let mut bytes = Vec::new();
        let read = whole && file.take(len as u64 + 4).read_to_end(&mut bytes).is_ok_and(|n| n == len + 4);
        let sum = bytes.get(len..).and_then(|b| <[u8; 4]>::try_from(b).ok()).map(u32::from_le_bytes);
        bytes.truncate(len);
        if !read || sum != Some(crc32fast::hash(&bytes)) {
            let _ = fs::remove_file(&path);
            return None;
        }
        // Used now: the last to be evicted.
        let _ = fs::File::options().append(true).open(&path).and_then(|f| f.set_modified(SystemTime::now()));
        Some(bytes)
    }

    /// Keeps page `page`; a failure to write leaves it uncached.
    pub(super) fn put(&self, page: u64, bytes: &[u8]) {
        let mut file = Vec::with_capacity(bytes.len() + 4);
        file.extend_from_slice(bytes);
        file.extend_from_slice(&crc32fast::hash(bytes).to_le_bytes());
        if write_whole(&self.path(page), &file).is_err() {
            return;
        }
        let counter = self.used.get_or_init(|| AtomicU64::new(folder_bytes(&self.root)));
        let used = counter.fetch_add(file.len() as u64, Ordering::Relaxed) + file.len() as u64;
        if used > self.bound {
            counter.store(evict(&self.root, self.bound), Ordering::Relaxed);
        }
    }

    /// Drops page `page` (it failed to verify).
    pub(super) fn forget(&self, page: u64) {
        let _ = fs::remove_file(self.path(page));
    }
}

/// A stable 64-bit FNV-1a hash: the folder name of an identity, the same
/// in every process and build.
fn fingerprint(identity: &str) -> u64 {
    identity.bytes().fold(0xcbf2_9ce4_8422_2325, |h, b| (h ^ u64::from(b)).wrapping_mul(0x100_0000_01b3))
}

/// Writes `path` whole: a temporary file renamed over it, so a reader of
/// the folder never sees half a file under its name.
fn write_whole(path: &Path, bytes: &[u8]) -> io::Result<()> {
    // Unique to this process and call: two threads never share one.
    static CALLS: AtomicU64 = AtomicU64::new(0);
    let call = CALLS.fetch_add(1, Ordering::Relaxed);
    let mut temporary = path.as_os_str().to_os_string();
    temporary.push(format!(".{}.{call}.tmp", std::process::id()));
    let temporary = PathBuf::from(temporary);
    let written = fs::write(&temporary, bytes).and_then(|()| fs::rename(&temporary, path));
    if written.is_err() {
        let _ = fs::remove_file(&temporary);
    }
    written
}

/// The page files of every object in `root`: (path, bytes, time).
fn page_files(root: &Path) -> Vec<(PathBuf, u64, SystemTime)> {
    let Ok(objects) = fs::read_dir(root) else { return Vec::new() };
    objects
        .flatten()
        .filter_map(|o| fs::read_dir(o.path()).ok())
        .flat_map(|pages| pages.flatten())
        .filter(|p| p.path().extension().is_some_and(|x| x == PAGE))
        .filter_map(|p| {
            let m = p.metadata().ok()?;
            Some((p.path(), m.len(), m.modified().unwrap_or(SystemTime::UNIX_EPOCH)))
        })
        .collect()
}

fn folder_bytes(root: &Path) -> u64 {
    page_files(root).iter().map(|f| f.1).sum()
}

/// Removes the least recently used page files of `root` until they take
/// at most 3/4 of `bound` (so that eviction is not run on every page);
/// the bytes left.
fn evict(root: &Path, bound: u64) -> u64 {
    let mut files = page_files(root);
    files.sort_unstable_by_key(|f| f.2);
    let mut used: u64 = files.iter().map(|f| f.1).sum();
    let target = bound / 4 * 3;
    for (path, len, _) in files {
        if used <= target {
            break;
        }
        if fs::remove_file(&path).is_ok() {
            used -= len;
        }
    }
    used
}

#[cfg(test)]
mod tests {
    use super::*;

    fn options(dir: &Path, bytes: u64) -> DiskCacheOptions {
        DiskCacheOptions { dir: dir.to_path_buf(), bytes }
    }

    #[test]
    fn a_page_reads_back_as_written_and_a_damaged_one_is_a_miss() {
        let dir = tempfile::tempdir().expect("tempdir");
        let cache =
            DiskCache::open(&options(dir.path(), 1 << 20), "http://h/a.mkt 100 \"e1\"").expect("open");
        cache.put(3, b"sixteen bytes!!!");
        assert_eq!(cache.get(3, 16).as_deref(), Some(&b"sixteen bytes!!!"[..]));
        assert_eq!(cache.get(3, 15), None, "a page of another length is a miss");
        cache.put(3, b"sixteen bytes!!!");
        assert_eq!(cache.get(4, 16), None);
        let path = cache.path(3);
        let mut bytes = fs::read(&path).expect("page file");
        bytes[0] ^= 1;
        fs::write(&path, &bytes).expect("damage");
        assert_eq!(cache.get(3, 16), None);
        assert!(!path.exists(), "a damaged page is removed");
        cache.put(5, b"x");
        cache.forget(5);
        assert_eq!(cache.get(5, 1), None);
    }

    #[test]
    fn another_version_of_the_object_reads_none_of_the_old_pages() {
        let dir = tempfile::tempdir().expect("tempdir");
        let old = DiskCache::open(&options(dir.path(), 1 << 20), "http://h/a.mkt 100 \"e1\"").expect("open");
        old.put(0, b"old");
        let new = DiskCache::open(&options(dir.path(), 1 << 20), "http://h/a.mkt 100 \"e2\"").expect("open");
        assert_eq!(new.get(0, 3), None);
        let again =
            DiskCache::open(&options(dir.path(), 1 << 20), "http://h/a.mkt 100 \"e1\"").expect("open");
        assert_eq!(again.get(0, 3).as_deref(), Some(&b"old"[..]));
    }

    #[test]
    fn the_folder_keeps_to_its_bound_dropping_the_least_recently_used() {
        let dir = tempfile::tempdir().expect("tempdir");
        // Ten pages of 1,000 bytes (1,004 with the checksum) in a bound of 5,000.
        let cache = DiskCache::open(&options(dir.path(), 5_000), "s3://b/k 1 v").expect("open");
        let page = vec![7u8; 1_000];
        for p in 0..10 {
            cache.put(p, &page);
            // File times must differ for the order to be seen.
            let t = SystemTime::UNIX_EPOCH + std::time::Duration::from_secs(1_000_000 + p);
            fs::File::options()
                .append(true)
                .open(cache.path(p))
                .and_then(|f| f.set_modified(t))
                .expect("time");
        }
        assert!(folder_bytes(dir.path()) <= 5_000, "{} bytes", folder_bytes(dir.path()));
        assert!(cache.get(9, 1_000).is_some(), "the newest page stays");
        assert!(cache.get(0, 1_000).is_none(), "the oldest page went");
    }
}
