//! A read-only [`BlockDevice`] over object storage (S3 and S3-compatible
//! stores, Google Cloud Storage, Azure, plain HTTP servers, local files)
//! through the `object_store` crate: a block read is a range request, answered
//! from a bounded in-memory cache of pages when it can be. Format-spec/remote.md
//! says what a reader fetches and what it pins.
//!
//! The device pins the object it opened. Its first request (a range from the
//! start of the object, which holds the header and both slots) returns the
//! object's ETag and version, and every later request asks for that version
//! and only while the ETag matches. An object replaced under the reader then
//! fails with [`StorageError::ObjectChanged`] instead of answering from a
//! mixture of two files.

use std::collections::{BTreeMap, HashMap};
use std::io;
use std::ops::Range;
use std::sync::{Arc, Mutex, OnceLock};

use object_store::path::Path;
use object_store::{GetOptions, GetRange, ObjectStore};

use super::disk_cache::{DiskCache, DiskCacheOptions};
use super::{BlockDevice, TransferCounts};
use crate::store::StorageError;
use crate::store::format::header;

/// How an [`ObjectStoreDevice`] reads.
#[derive(Debug, Clone)]
pub struct RemoteOptions {
    /// Bytes the first request fetches from the start of the object: the
    /// header, both slots, and in a bulk-loaded file the meta block and
    /// the top of the tree (format-spec/remote.md, "Open"). Default 256
    /// KiB: 14 node blocks of 16 KiB, which spare a cold query on ship
    /// 10^6 about one round trip in three sets of four (docs/object-storage.md).
    pub open_bytes: u64,
    /// Upper bound of the in-memory cache of fetched pages, in bytes.
    /// Default 64 MiB.
    pub cache_bytes: u64,
    /// The store's settings as `object_store` names its configuration keys
    /// (for example `("aws_endpoint", "http://127.0.0.1:9000")`), applied
    /// over those of the environment (`AWS_*`, `GOOGLE_*`, `AZURE_*`).
    pub store_options: Vec<(String, String)>,
    /// Times a failed request (a server error, a dropped connection) is
    /// tried again, with exponential backoff, before the read fails.
    /// Default 3.
    pub retries: usize,
    /// How long a request is tried again at most. Default 30 s.
    pub retry_timeout: std::time::Duration,
    /// Keep fetched pages in a folder too, for later readers of the same
    /// object version in any process. Default none.
    pub disk_cache: Option<DiskCacheOptions>,
    /// Bytes the reader may add to join requests across the gaps between
    /// the blocks a round asks for (the smallest gaps first), as a share of
    /// the bytes asked for since the open: fewer requests for at most
    /// `1 + gap_share` times the bytes. Default 0.5; 0 fetches only the
    /// blocks asked for.
    pub gap_share: f64,
}

impl Default for RemoteOptions {
    fn default() -> Self {
        RemoteOptions {
            open_bytes: 256 << 10,
            cache_bytes: 64 << 20,
            store_options: Vec::new(),
            retries: 3,
            retry_timeout: std::time::Duration::from_secs(30),
            disk_cache: None,
            gap_share: 0.5,
        }
    }
}

/// A committed `.mkt` file read where it lies in object storage. Writes fail
/// with [`io::ErrorKind::ReadOnlyFilesystem`].
pub struct ObjectStoreDevice {
    store: Arc<dyn ObjectStore>,
    path: Path,
    url: String,
    size: u64,
    /// What the first answer said of the object: every later answer must
    /// say the same.
    pinned: object_store::ObjectMeta,
    /// The fetch and cache unit: the file's block size.
    page: u64,
    cache_bytes: u64,
    gap_share: f64,
    state: Mutex<Fetched>,
    disk: Option<DiskCache>,
}

impl std::fmt::Debug for ObjectStoreDevice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ObjectStoreDevice")
            .field("url", &self.url)
            .field("size", &self.size)
            .field("e_tag", &self.pinned.e_tag)
            .field("version", &self.pinned.version)
            .finish()
    }
}

/// The pages fetched so far (least recently used first out) and the counts.
#[derive(Default)]
struct Fetched {
    pages: HashMap<u64, (Arc<[u8]>, u64)>,
    by_use: BTreeMap<u64, u64>,
    tick: u64,
    bytes: u64,
    counts: TransferCounts,
    /// Pages fetched because a read asked for them, and pages fetched only
    /// to join requests across gaps: the second stays within
    /// `gap_share` of the first, over the device's life.
    asked_pages: u64,
    gap_pages: u64,
}

impl Fetched {
    fn get(&mut self, page: u64) -> Option<Arc<[u8]>> {
        self.tick += 1;
        let tick = self.tick;
        let (bytes, used) = self.pages.get_mut(&page)?;
        self.by_use.remove(used);
        *used = tick;
        self.by_use.insert(tick, page);
        Some(bytes.clone())
    }

    fn drop_page(&mut self, page: u64) {
        if let Some((gone, used)) = self.pages.remove(&page) {
            self.bytes -= gone.len() as u64;
            self.by_use.remove(&used);
        }
    }

    fn put(&mut self, page: u64, bytes: Arc<[u8]>, bound: u64) {
        self.tick += 1;
        self.bytes += bytes.len() as u64;
        if let Some((old, used)) = self.pages.insert(page, (bytes, self.tick)) {
            self.bytes -= old.len() as u64;
            self.by_use.remove(&used);
        }
        self.by_use.insert(self.tick, page);
        while self.bytes > bound {
            let Some((_, &oldest)) = self.by_use.first_key_value() else { break };
            self.drop_page(oldest);
        }
    }
}

/// The runtime every device's requests run on: one per process, so that a
/// catalog of many files does not start threads per file.
fn runtime() -> io::Result<&'static tokio::runtime::Runtime> {
    // Built once, inside the lock: two first opens at once build one.
    static RUNTIME: OnceLock<Result<tokio::runtime::Runtime, String>> = OnceLock::new();
    RUNTIME
        .get_or_init(|| {
            tokio::runtime::Builder::new_multi_thread()
                .worker_threads(2)
                .thread_name("mktree-remote")
                .enable_all()
                .build()
                .map_err(|e| e.to_string())
        })
        .as_ref()
        .map_err(|e| io::Error::other(format!("cannot start the object store's runtime: {e}")))
}

/// Runs `fut` on the shared runtime and waits for it. Spawned rather than
/// blocked on, so that a caller inside another runtime does not panic.
pub(super) fn wait<T: Send + 'static>(fut: impl Future<Output = T> + Send + 'static) -> io::Result<T> {
    let (tx, rx) = std::sync::mpsc::sync_channel(1);
    runtime()?.spawn(async move {
        // The receiver waits below; a send fails only if it is gone.
        let _ = tx.send(fut.await);
    });
    rx.recv().map_err(|_| io::Error::other("the object store's request was dropped"))
}

/// The environment's store settings (`AWS_*`, `GOOGLE_*`, `AZURE_*`), as
/// `object_store`'s configuration keys are named (lower case).
fn environment_options() -> Vec<(String, String)> {
    std::env::vars()
        .filter(|(k, _)| ["AWS_", "GOOGLE_", "AZURE_"].iter().any(|p| k.starts_with(p)))
        .map(|(k, v)| (k.to_ascii_lowercase(), v))
        .collect()
}

impl ObjectStoreDevice {
    /// Opens the object `url` names, with the store's settings from the
    /// environment and `options`: one range request from the start of the
    /// object, which pins its ETag and version.
    pub fn open(url: &str, options: &RemoteOptions) -> Result<ObjectStoreDevice, StorageError> {
        let (store, path) = store_for_url(url, options)?;
        ObjectStoreDevice::on(store, path, url, options)
    }

    /// Opens `path` in a store the caller built (any `object_store`
    /// implementation); `name` is what errors call it.
    pub fn on(
        store: Arc<dyn ObjectStore>,
        path: Path,
        name: &str,
        options: &RemoteOptions,
    ) -> Result<ObjectStoreDevice, StorageError> {
        let first = options.open_bytes.max(header::PREFIX_LEN as u64);
        let get = {
            let (store, path) = (store.clone(), path.clone());
            let options = GetOptions { range: Some(GetRange::Bounded(0..first)), ..GetOptions::default() };
            async move {
                let result = store.get_opts(&path, options).await?;
                let meta = result.meta.clone();
                let range = result.range.clone();
                Ok::<_, object_store::Error>((meta, range, result.bytes().await?))
            }
        };
        let (meta, range, bytes) = match wait(get)? {
            Ok(got) => got,
            Err(e) => {
                // An empty object has no byte 0 to range from, and stores
                // say so in their own words: its size tells.
                let (store, path) = (store.clone(), path.clone());
                let empty = matches!(wait(async move { store.head(&path).await }), Ok(Ok(m)) if m.size == 0);
                return Err(if empty { StorageError::NotMktree } else { remote(name, e.to_string()) });
            }
        };
        if range.start != 0 || range.end - range.start != bytes.len() as u64 {
            return Err(remote(name, format!("asked for bytes 0..{first}, the store answered {range:?}")));
        }
        // The block size is in the header; a file with none is refused by
        // the database's open, which reads the same bytes from the cache.
        let page = header::decode_prefix(&bytes)
            .map(|(block_size, _)| u64::from(block_size))
            .unwrap_or(header::PREFIX_LEN as u64);
        let mut fetched = Fetched {
            counts: TransferCounts { requests: 1, bytes: bytes.len() as u64, round_trips: 1 },
            ..Fetched::default()
        };
        // Whole pages only, and the object's last one, which may be short.
        for (i, chunk) in bytes.chunks(page as usize).enumerate() {
            let at = i as u64 * page;
            if chunk.len() as u64 == page || at + chunk.len() as u64 == meta.size {
                fetched.put(i as u64, Arc::from(chunk), options.cache_bytes);
            }
        }
        let disk = match &options.disk_cache {
            Some(d) => {
                // The header's bytes (both commit slots) tell two commits of
                // one size apart where the store's ETag and time do not.
                let header = &bytes[..bytes.len().min(header::PREFIX_LEN)];
                let identity = format!(
                    "{name} {} {:?} {:?} {} {:08x}",
                    meta.size,
                    meta.e_tag,
                    meta.version,
                    meta.last_modified,
                    crc32fast::hash(header)
                );
                let cache = DiskCache::open(d, &identity)
                    .map_err(|error| StorageError::Open { path: d.dir.clone(), error })?;
                Some(cache)
            }
            None => None,
        };
        Ok(ObjectStoreDevice {
            store,
            path,
            url: name.to_string(),
            size: meta.size,
            pinned: meta,
            page,
            cache_bytes: options.cache_bytes,
            gap_share: options.gap_share,
            state: Mutex::new(fetched),
            disk,
        })
    }

    /// The URL (or name) the device was opened with.
    pub fn url(&self) -> &str {
        &self.url
    }

    /// The object's ETag as the store gave it at open, when it has one.
    pub fn e_tag(&self) -> Option<&str> {
        self.pinned.e_tag.as_deref()
    }

    /// The object's version as the store gave it at open, when the store
    /// keeps versions.
    pub fn version(&self) -> Option<&str> {
        self.pinned.version.as_deref()
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Fetched> {
        // A panic while holding the lock leaves whole pages and counts behind.
        self.state.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Fetches the byte ranges `ranges` concurrently, in one round trip.
    fn fetch(&self, ranges: Vec<Range<u64>>) -> io::Result<Vec<bytes::Bytes>> {
        let options = GetOptions {
            // A weak ETag never passes If-Match (RFC 9110): it is compared
            // with each answer's instead, below.
            if_match: self.pinned.e_tag.clone().filter(|t| !t.starts_with("W/")),
            version: self.pinned.version.clone(),
            ..GetOptions::default()
        };
        let (store, path) = (self.store.clone(), self.path.clone());
        let asked = ranges.clone();
        let got = wait(async move {
            let each = ranges.into_iter().map(|r| {
                let options = GetOptions { range: Some(GetRange::Bounded(r)), ..options.clone() };
                let (store, path) = (store.clone(), path.clone());
                async move {
                    let result = store.get_opts(&path, options).await?;
                    let meta = result.meta.clone();
                    Ok::<_, object_store::Error>((meta, result.bytes().await?))
                }
            });
            futures::future::try_join_all(each).await
        })?;
        let got = got.map_err(|e| match e {
            object_store::Error::Precondition { .. } | object_store::Error::NotFound { .. } => {
                io::Error::other(Changed { url: self.url.clone() })
            }
            e => io::Error::other(Failed { url: self.url.clone(), detail: one_line(&e.to_string()) }),
        })?;
        let mut out = Vec::with_capacity(got.len());
        for ((meta, bytes), range) in got.into_iter().zip(&asked) {
            // A server that ignores If-Match, or gives no ETag, still names
            // the object's size, ETag and time with each answer.
            let pinned = &self.pinned;
            if (meta.size, &meta.e_tag, meta.last_modified)
                != (pinned.size, &pinned.e_tag, pinned.last_modified)
            {
                return Err(io::Error::other(Changed { url: self.url.clone() }));
            }
            if bytes.len() as u64 != range.end - range.start {
                let detail = format!("asked for bytes {range:?}, received {}", bytes.len());
                return Err(io::Error::other(Failed { url: self.url.clone(), detail }));
            }
            out.push(bytes);
        }
        Ok(out)
    }
}

/// The object changed (or went) after the device pinned it: carried in the
/// `io::Error` of a read, and turned into [`StorageError::ObjectChanged`].
#[derive(Debug)]
pub(crate) struct Changed {
    pub(crate) url: String,
}

impl std::fmt::Display for Changed {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} changed after it was opened", self.url)
    }
}

impl std::error::Error for Changed {}

/// The store `url` names, with the environment's settings and `options`';
/// the object's path in it.
pub(super) fn store_for_url(
    url: &str,
    options: &RemoteOptions,
) -> Result<(Arc<dyn ObjectStore>, Path), StorageError> {
    let parsed = url::Url::parse(url).map_err(|e| remote(url, format!("not a URL: {e}")))?;
    let mut settings = environment_options();
    settings.extend(options.store_options.iter().cloned());
    store_for(&parsed, &settings, options).map_err(|e| remote(url, e.to_string()))
}

/// The store `url` names, with `settings` (configuration keys the store
/// does not know are left out, as `object_store::parse_url_opts` does) and
/// `options`' retries; the object's path in it.
fn store_for(
    url: &url::Url,
    settings: &[(String, String)],
    options: &RemoteOptions,
) -> object_store::Result<(Arc<dyn ObjectStore>, Path)> {
    use object_store::ObjectStoreScheme as Scheme;
    let retry = object_store::RetryConfig {
        max_retries: options.retries,
        retry_timeout: options.retry_timeout,
        ..object_store::RetryConfig::default()
    };
    // A builder with every setting it has a key for, and the retries.
    macro_rules! built {
        ($builder:expr) => {{
            let b = settings.iter().fold($builder, |b, (k, v)| match k.parse() {
                Ok(key) => b.with_config(key, v.as_str()),
                Err(_) => b,
            });
            Arc::new(b.with_retry(retry.clone()).build()?)
        }};
    }
    let (scheme, path) = Scheme::parse(url)?;
    let whole = url.to_string();
    let store: Arc<dyn ObjectStore> = match scheme {
        Scheme::Local => Arc::new(object_store::local::LocalFileSystem::new()),
        Scheme::AmazonS3 => built!(object_store::aws::AmazonS3Builder::new().with_url(whole)),
        Scheme::GoogleCloudStorage => {
            built!(object_store::gcp::GoogleCloudStorageBuilder::new().with_url(whole))
        }
        Scheme::MicrosoftAzure => built!(object_store::azure::MicrosoftAzureBuilder::new().with_url(whole)),
        Scheme::Http => built!(
            object_store::http::HttpBuilder::new()
                .with_url(&url[..url::Position::BeforePath])
                // A URL that names plain HTTP asks for it.
                .with_config(object_store::ClientConfigKey::AllowHttp, (url.scheme() == "http").to_string())
        ),
        other => {
            return Err(object_store::Error::NotSupported {
                source: format!("{other:?} is not a store a file can be read from here").into(),
            });
        }
    };
    Ok((store, path))
}

/// A request failed after its retries (a server error, a dropped or short
/// answer): carried in the `io::Error` of a read, and turned into
/// [`StorageError::Remote`].
#[derive(Debug)]
pub(crate) struct Failed {
    pub(crate) url: String,
    pub(crate) detail: String,
}

impl std::fmt::Display for Failed {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.url, self.detail)
    }
}

impl std::error::Error for Failed {}

pub(super) fn remote(url: &str, detail: String) -> StorageError {
    StorageError::Remote { url: url.to_string(), detail: one_line(&detail) }
}

/// A store's message on one line: servers put pages of HTML in theirs.
fn one_line(text: &str) -> String {
    text.split_whitespace().collect::<Vec<_>>().join(" ")
}

impl ObjectStoreDevice {
    /// Pages `pages` (ascending), from the cache or fetched together:
    /// adjacent missing pages make one request, and all requests go out at
    /// once, one round trip.
    fn pages(&self, pages: impl Iterator<Item = u64>) -> io::Result<HashMap<u64, Arc<[u8]>>> {
        let mut have: HashMap<u64, Arc<[u8]>> = HashMap::new();
        let mut absent: Vec<u64> = Vec::new();
        {
            let mut state = self.lock();
            for p in pages {
                match state.get(p) {
                    Some(bytes) => {
                        have.insert(p, bytes);
                    }
                    None => absent.push(p),
                }
            }
        }
        // The folder's pages, read outside the lock.
        if let Some(disk) = &self.disk {
            let found: Vec<(u64, Arc<[u8]>)> =
                absent.iter().filter_map(|&p| Some((p, Arc::from(disk.get(p, self.page_len(p))?)))).collect();
            let mut state = self.lock();
            for (p, bytes) in found {
                have.insert(p, bytes.clone());
                state.put(p, bytes, self.cache_bytes);
            }
        }
        let mut missing: Vec<Range<u64>> = Vec::new();
        for p in absent.into_iter().filter(|p| !have.contains_key(p)) {
            match missing.last_mut() {
                Some(run) if run.end == p => run.end = p + 1,
                Some(run) if run.end > p => {}
                _ => missing.push(p..p + 1),
            }
        }
        if missing.is_empty() {
            return Ok(have);
        }
        let missing = {
            let asked: u64 = missing.iter().map(|r| r.end - r.start).sum();
            let mut state = self.lock();
            state.asked_pages += asked;
            // Credit a round leaves unspent serves a later one.
            let allowed = if self.gap_share.is_finite() && self.gap_share > 0.0 {
                (state.asked_pages as f64 * self.gap_share) as u64
            } else {
                0
            };
            let (joined, spent) = join_across_gaps(missing, allowed.saturating_sub(state.gap_pages));
            state.gap_pages += spent;
            joined
        };
        let byte_ranges: Vec<Range<u64>> =
            missing.iter().map(|r| r.start * self.page..(r.end * self.page).min(self.size)).collect();
        let got = self.fetch(byte_ranges)?;
        let mut fresh = Vec::new();
        let mut state = self.lock();
        state.counts.requests += got.len() as u64;
        state.counts.round_trips += 1;
        for (run, bytes) in missing.iter().zip(got) {
            state.counts.bytes += bytes.len() as u64;
            for (i, p) in (run.start..run.end).enumerate() {
                let from = i * self.page as usize;
                let to = (from + self.page as usize).min(bytes.len());
                let page: Arc<[u8]> = Arc::from(&bytes[from..to]);
                fresh.push((p, page.clone()));
                have.insert(p, page.clone());
                state.put(p, page, self.cache_bytes);
            }
        }
        drop(state);
        // Written to the folder outside the lock: other reads go on.
        if let Some(disk) = &self.disk {
            for (p, page) in fresh {
                disk.put(p, &page);
            }
        }
        Ok(have)
    }

    /// The length of page `p` of the object: a page, or the last one's rest.
    fn page_len(&self, p: u64) -> usize {
        usize::try_from(self.page.min(self.size.saturating_sub(p * self.page))).unwrap_or(0)
    }

    /// The pages `span` covers, when it lies in the object.
    fn pages_of(&self, span: &Range<u64>) -> Option<Range<u64>> {
        (span.start < span.end && span.end <= self.size)
            .then(|| span.start / self.page..(span.end - 1) / self.page + 1)
    }
}

/// `runs` (ascending, apart) joined across their smallest gaps while the
/// pages the gaps add stay within `budget`; returns the runs and the pages
/// added.
fn join_across_gaps(runs: Vec<Range<u64>>, budget: u64) -> (Vec<Range<u64>>, u64) {
    let mut gaps: Vec<(u64, usize)> =
        runs.windows(2).enumerate().map(|(i, w)| (w[1].start - w[0].end, i)).collect();
    gaps.sort_unstable();
    let mut join = vec![false; runs.len()];
    let mut spent = 0u64;
    for (gap, i) in gaps {
        if spent + gap > budget {
            break;
        }
        spent += gap;
        join[i] = true;
    }
    let mut out: Vec<Range<u64>> = Vec::with_capacity(runs.len());
    for (i, run) in runs.into_iter().enumerate() {
        match out.last_mut() {
            Some(last) if i > 0 && join[i - 1] => last.end = run.end,
            _ => out.push(run),
        }
    }
    (out, spent)
}

impl BlockDevice for ObjectStoreDevice {
    fn read_at(&self, offset: u64, buf: &mut [u8]) -> io::Result<()> {
        if buf.is_empty() {
            return Ok(());
        }
        let span = offset..offset.saturating_add(buf.len() as u64);
        let pages = self
            .pages_of(&span)
            .ok_or_else(|| io::Error::new(io::ErrorKind::UnexpectedEof, "read past the end of the object"))?;
        let have = self.pages(pages)?;
        let mut at = offset;
        let mut out = 0usize;
        while out < buf.len() {
            let p = at / self.page;
            let within = (at - p * self.page) as usize;
            let page = have.get(&p).ok_or_else(|| io::Error::other("a fetched page is missing"))?;
            let n = (page.len().saturating_sub(within)).min(buf.len() - out);
            if n == 0 {
                return Err(io::Error::new(io::ErrorKind::UnexpectedEof, "a short page inside the object"));
            }
            buf[out..out + n].copy_from_slice(&page[within..within + n]);
            out += n;
            at += n as u64;
        }
        Ok(())
    }

    fn fetch_ahead(&self, spans: &[Range<u64>]) -> bool {
        let mut pages: Vec<u64> = spans.iter().filter_map(|s| self.pages_of(s)).flatten().collect();
        pages.sort_unstable();
        pages.dedup();
        // Pages fetched ahead must stay until they are read: at most half
        // the cache, the rest keeps what the query holds.
        let room = usize::try_from(self.cache_bytes / self.page / 2).unwrap_or(usize::MAX);
        let all = pages.len() <= room;
        pages.truncate(room);
        // A failure is for the read that follows to report.
        self.pages(pages.into_iter()).is_ok() && all
    }

    fn forget(&self, span: Range<u64>) {
        if let Some(pages) = self.pages_of(&span) {
            let mut state = self.lock();
            for p in pages {
                state.drop_page(p);
                if let Some(disk) = &self.disk {
                    disk.forget(p);
                }
            }
        }
    }

    fn write_at(&self, _offset: u64, _data: &[u8]) -> io::Result<()> {
        Err(read_only())
    }

    fn sync(&self) -> io::Result<()> {
        Err(read_only())
    }

    fn len(&self) -> io::Result<u64> {
        Ok(self.size)
    }

    fn set_len(&self, _len: u64) -> io::Result<()> {
        Err(read_only())
    }

    fn transfer_counts(&self) -> Option<TransferCounts> {
        Some(self.lock().counts)
    }
}

fn read_only() -> io::Error {
    io::Error::new(io::ErrorKind::ReadOnlyFilesystem, "an object store is read only here")
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// The page cache holds at most its bound (a page larger than the
        /// bound is not kept), counts exactly the bytes it holds, and keeps
        /// one use mark per page, whatever the puts, gets and drops.
        #[test]
        fn the_page_cache_keeps_its_bound_and_its_count(
            ops in prop::collection::vec((0u8..3, 0u64..12, 1usize..40), 1..200),
            bound in 0u64..200,
        ) {
            let mut f = Fetched::default();
            for (op, page, len) in ops {
                match op {
                    0 => f.put(page, Arc::from(vec![page as u8; len]), bound),
                    1 => {
                        if let Some(bytes) = f.get(page) {
                            prop_assert!(bytes.iter().all(|&b| b == page as u8));
                        }
                    }
                    _ => f.drop_page(page),
                }
                prop_assert!(f.bytes <= bound);
                prop_assert_eq!(f.bytes, f.pages.values().map(|(b, _)| b.len() as u64).sum::<u64>());
                prop_assert_eq!(f.by_use.len(), f.pages.len());
            }
        }

        /// Joining runs across gaps covers every page asked for, adds at
        /// most the budget and says how many, keeps the runs ascending and
        /// apart, and takes a smaller gap before a larger one.
        #[test]
        fn joined_runs_cover_the_pages_within_the_share(
            steps in prop::collection::vec((1u64..20, 1u64..6), 1..40),
            budget in 0u64..60,
        ) {
            let mut runs = Vec::new();
            let mut at = 0;
            for (gap, len) in steps {
                at += gap;
                runs.push(at..at + len);
                at += len;
            }
            let (joined, spent) = join_across_gaps(runs.clone(), budget);
            let count = |rs: &[Range<u64>]| rs.iter().map(|r| r.end - r.start).sum::<u64>();
            let (needed, fetched) = (count(&runs), count(&joined));
            prop_assert_eq!(fetched - needed, spent);
            prop_assert!(spent <= budget);
            prop_assert!(joined.windows(2).all(|w| w[0].end < w[1].start));
            for r in &runs {
                prop_assert!(joined.iter().any(|j| j.start <= r.start && r.end <= j.end));
            }
            let gaps = |rs: &[Range<u64>]| rs.windows(2).map(|w| w[1].start - w[0].end).collect::<Vec<_>>();
            let (left, all) = (gaps(&joined), gaps(&runs));
            if let Some(&smallest_left) = left.iter().min() {
                // Every gap joined was no larger than every gap left.
                let joined_gaps = all.len() - left.len();
                let mut sorted = all.clone();
                sorted.sort_unstable();
                prop_assert!(sorted[..joined_gaps].iter().all(|&g| g <= smallest_left));
            }
        }
    }

    #[test]
    fn no_budget_joins_nothing() {
        let runs = vec![0..1, 2..3, 10..12];
        assert_eq!(join_across_gaps(runs.clone(), 0), (runs.clone(), 0));
        // A budget of 2 takes the gap of 1 only; 8 takes both.
        assert_eq!(join_across_gaps(runs.clone(), 2), (vec![0..3, 10..12], 1));
        let (all, spent) = join_across_gaps(runs, 8);
        assert_eq!((all.len(), all.first(), spent), (1, Some(&(0..12)), 8));
    }
}
