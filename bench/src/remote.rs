//! The remote benchmark (`mktree bench-remote`, issue 36 item 7): the
//! standard query sets against a local `.mkt` file and against the same
//! file at a URL (`http(s)://`, or `s3://` on an S3-compatible server),
//! through a [`LatencyProxy`] that adds a round trip to every request.
//!
//! For each added round trip and each set, every query runs cold (a fresh
//! reader per query, whose open is counted apart) and warm (one reader
//! whose cache a first pass over the set filled, then the set again). A
//! row holds the means per query of block reads, requests, round trips,
//! bytes fetched and wall time (mean and 95th percentile), beside the
//! bytes of the blocks the local query reads. Every remote answer, its
//! objects and its block reads, must equal the local file's: a difference
//! is an error, never a row. format-spec/remote.md says what a reader
//! fetches; docs/object-storage.md quotes the figures.

use std::net::{SocketAddr, ToSocketAddrs};
use std::path::Path;
use std::time::{Duration, Instant};

use mktree::db::{Database, ReadTransaction};
use mktree::geom::Aabb;
use mktree::store::TransferCounts;
use mktree::store::device::RemoteOptions;
use serde::Serialize;

use crate::bench_peers::{QuerySet, agree, standard_sets};
use crate::error::BenchError;
use crate::peers::mktree::{Counted, exact_answer};
use crate::proxy::LatencyProxy;

/// Added round trips when none are asked for, ms.
pub const DEFAULT_LATENCIES_MS: [f64; 3] = [0.0, 20.0, 80.0];

/// The largest round trip the bench adds, ms: a minute per request
/// measures nothing a shorter one does not.
const MAX_LATENCY_MS: f64 = 60_000.0;

/// How to run the benchmark.
#[derive(Debug, Clone)]
pub struct RemoteBenchOptions {
    /// Queries per set (boxes of 1%, 5%, 20% of the extent, collisions).
    pub queries: usize,
    /// Seed of the query sets.
    pub seed: u64,
    /// Round trips the proxy adds, ms, one pass over the sets each.
    pub latencies_ms: Vec<f64>,
    /// How the remote reader reads: its cache's bound, the store's
    /// settings (an S3 endpoint is routed through the proxy), retries.
    pub remote: RemoteOptions,
}

/// Cold or warm.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Cache {
    /// A fresh reader per query: the open, then the query.
    Cold,
    /// One reader for the set, its cache filled by a first pass.
    Warm,
}

impl Cache {
    /// "cold" or "warm", as the JSON has it.
    pub fn label(&self) -> &'static str {
        match self {
            Cache::Cold => "cold",
            Cache::Warm => "warm",
        }
    }
}

/// Means per query of what a reader fetched, and how long it took.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Transfer {
    /// Range requests.
    pub requests: f64,
    /// Waits for the network (requests made together count once).
    pub round_trips: f64,
    /// Bytes received.
    pub bytes: f64,
    /// Wall time, ms.
    pub wall_ms: f64,
    /// The 95th percentile of the wall time, ms.
    pub wall_ms_p95: f64,
}

/// The local file's answers to one set: what the remote rows compare with.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LocalSet {
    /// The set's label ("box 1%", "collide +50").
    pub set: String,
    /// Queries in the set.
    pub queries: usize,
    /// Objects in the exact answer.
    pub answers: f64,
    /// Block reads.
    pub block_reads: f64,
    /// Of which node blocks.
    pub node_reads: f64,
    /// Of which geometry blocks.
    pub geometry_reads: f64,
    /// Bytes of the blocks read (block reads x block size).
    pub block_bytes: f64,
    /// Wall time of the local query, ms (the file in the system's cache).
    pub wall_ms: f64,
}

/// One added round trip, one set, cold or warm: means per query.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RemoteRow {
    /// The set's label.
    pub set: String,
    /// The round trip the proxy added, ms.
    pub latency_ms: f64,
    /// Cold or warm.
    pub cache: Cache,
    /// Queries in the set.
    pub queries: usize,
    /// Block reads: the local file's, which every answer was checked to equal.
    pub block_reads: f64,
    /// Bytes of the blocks the local query reads (block reads x block size).
    pub local_block_bytes: f64,
    /// Cold: what each open fetched (the header and slots, the meta block)
    /// and its time. None when warm.
    pub open: Option<Transfer>,
    /// What each query fetched, the open left out, and its time.
    pub query: Transfer,
    /// `query.bytes / local_block_bytes`: none when the local query reads nothing.
    pub bytes_ratio: Option<f64>,
    /// Wall time of the query with its open when cold, ms.
    pub total_ms: f64,
    /// Its 95th percentile, ms.
    pub total_ms_p95: f64,
}

/// The whole run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RemoteBench {
    /// The local file as named.
    pub file: String,
    /// The URL as named (its requests went through the proxy).
    pub url: String,
    /// Objects in the file.
    pub objects: u32,
    /// Bytes per block.
    pub block_size: u32,
    /// The tree's deepest level (root 0).
    pub depth: u32,
    /// Queries per set.
    pub queries: usize,
    /// Seed of the sets.
    pub seed: u64,
    /// The round trips added, ms.
    pub latencies_ms: Vec<f64>,
    /// The remote reader's cache bound, bytes.
    pub cache_bytes: u64,
    /// Bytes each open fetched from the start of the object.
    pub open_bytes: u64,
    /// The share of extra bytes a round could fetch to join requests.
    pub gap_share: f64,
    /// The local answers, per set.
    pub local: Vec<LocalSet>,
    /// Per added round trip, per set: cold, then warm.
    pub rows: Vec<RemoteRow>,
}

/// Runs the benchmark: `file` locally, `url` through the proxy at every
/// round trip of `options`. `progress` hears each step.
pub fn bench_remote(
    file: &Path,
    url: &str,
    options: &RemoteBenchOptions,
    progress: &dyn Fn(&str),
) -> Result<RemoteBench, BenchError> {
    check_options(options)?;
    let route = Route::of(url, &options.remote)?;
    let local_name = file.display().to_string();
    let local = Database::open_read_only(file).map_err(opening(&local_name))?;
    let local_txn = local.begin_read().map_err(opening(&local_name))?;
    let info = local_txn
        .info()
        .ok_or_else(|| BenchError::Invalid(format!("{local_name} holds no tree: nothing to query")))?;
    // Straight to the server first: a bad URL or another file fails here,
    // once, before the scene is read.
    let remote = Database::open_url(url, &options.remote).map_err(opening(url))?;
    let remote_info = remote.begin_read().map_err(opening(url))?.info();
    if remote_info.as_ref().map(|i| (i.txn, i.objects, i.file_blocks))
        != Some((info.txn, info.objects, info.file_blocks))
    {
        return Err(BenchError::Invalid(format!(
            "{url} is not the file {local_name}: its commit, objects or length differ"
        )));
    }
    drop(remote);
    progress("reading the local file's object boxes");
    let boxes = local_txn.scene()?.object_boxes();
    let sets = standard_sets(&boxes, options.queries, options.seed);
    let block = f64::from(info.block_size);
    let mut local_sets = Vec::with_capacity(sets.len());
    let mut answers = Vec::with_capacity(sets.len());
    for set in &sets {
        progress(&format!("local: {}", set.label));
        let (summary, counted) = run_local(&local_txn, set, block)?;
        local_sets.push(summary);
        answers.push(counted);
    }
    let mut rows = Vec::new();
    for &latency_ms in &options.latencies_ms {
        let proxy = LatencyProxy::start(route.upstream, Duration::from_secs_f64(latency_ms / 1e3))
            .map_err(crate::error::io("starting the latency proxy"))?;
        let (proxied, remote_options) = route.through(proxy.addr(), &options.remote);
        for ((set, want), local) in sets.iter().zip(&answers).zip(&local_sets) {
            let reader = Reader { url: &proxied, options: &remote_options, latency_ms, set, want };
            progress(&format!("{latency_ms} ms: {} cold", set.label));
            rows.push(reader.cold()?.row(set, latency_ms, local));
            progress(&format!("{latency_ms} ms: {} warm", set.label));
            rows.push(reader.warm()?.row(set, latency_ms, local));
        }
    }
    Ok(RemoteBench {
        file: local_name,
        url: url.to_string(),
        objects: info.objects,
        block_size: info.block_size,
        depth: info.depth,
        queries: options.queries,
        seed: options.seed,
        latencies_ms: options.latencies_ms.clone(),
        cache_bytes: options.remote.cache_bytes,
        open_bytes: options.remote.open_bytes,
        gap_share: options.remote.gap_share,
        local: local_sets,
        rows,
    })
}

fn check_options(options: &RemoteBenchOptions) -> Result<(), BenchError> {
    if options.queries == 0 {
        return Err(BenchError::Invalid("queries per set must be at least 1".into()));
    }
    if options.latencies_ms.is_empty() {
        return Err(BenchError::Invalid("no added round trip to measure (--latency)".into()));
    }
    if let Some(bad) = options.latencies_ms.iter().find(|l| !(0.0..=MAX_LATENCY_MS).contains(*l)) {
        return Err(BenchError::Invalid(format!(
            "an added round trip of {bad} ms: each is between 0 and {MAX_LATENCY_MS} ms"
        )));
    }
    let gap = options.remote.gap_share;
    if !(0.0..=16.0).contains(&gap) {
        return Err(BenchError::Invalid(format!("a gap share of {gap}: it is between 0 and 16")));
    }
    Ok(())
}

/// `BenchError::Open` for `target`.
fn opening(target: &str) -> impl Fn(mktree::store::StorageError) -> BenchError + '_ {
    move |source| BenchError::Open { target: target.to_string(), source }
}

/// The local answers to `set`: their means, and each query's answer.
fn run_local(
    txn: &ReadTransaction,
    set: &QuerySet,
    block: f64,
) -> Result<(LocalSet, Vec<Counted>), BenchError> {
    let mut answers = Vec::with_capacity(set.boxes.len());
    let mut ms = 0.0;
    for q in &set.boxes {
        let started = Instant::now();
        answers.push(exact_answer(txn, q)?);
        ms += started.elapsed().as_secs_f64() * 1e3;
    }
    let n = set.boxes.len().max(1) as f64;
    let mean = |f: fn(&Counted) -> u64| answers.iter().map(|a| f(a) as f64).sum::<f64>() / n;
    let block_reads = mean(|a| a.reads.total);
    let summary = LocalSet {
        set: set.label.clone(),
        queries: set.boxes.len(),
        answers: mean(|a| a.objects.len() as u64),
        block_reads,
        node_reads: mean(|a| a.reads.node),
        geometry_reads: mean(|a| a.reads.geometry),
        block_bytes: block_reads * block,
        wall_ms: ms / n,
    };
    Ok((summary, answers))
}

/// Where a URL's requests go, and how to send them through a proxy.
struct Route {
    /// The server's address.
    upstream: SocketAddr,
    /// The URL as given.
    url: url::Url,
    /// For `s3://`, the endpoint the requests go to; for `http(s)://`, the URL itself.
    endpoint: Option<url::Url>,
}

impl Route {
    /// The route of `url`: an `http(s)://` URL's host, or the endpoint of
    /// an `s3://` URL's S3-compatible store (the store options' last
    /// `aws_endpoint`, else the environment's `AWS_ENDPOINT`).
    fn of(url: &str, options: &RemoteOptions) -> Result<Route, BenchError> {
        let bad = |reason: String| BenchError::Url { url: url.to_string(), reason };
        let parsed = url::Url::parse(url).map_err(|e| bad(format!("not a URL: {e}")))?;
        let endpoint = match parsed.scheme() {
            "http" | "https" => None,
            "s3" | "s3a" => {
                let text = s3_endpoint(options).ok_or_else(|| {
                    bad("an S3 URL is routed through the latency proxy by its store's endpoint: \
                         set AWS_ENDPOINT or --store-option aws_endpoint=http://HOST:PORT"
                        .into())
                })?;
                Some(
                    url::Url::parse(&text)
                        .map_err(|e| bad(format!("the endpoint {text:?} is not a URL: {e}")))?,
                )
            }
            other => {
                return Err(bad(format!(
                    "the latency proxy routes http://, https:// and s3:// URLs, not {other}://"
                )));
            }
        };
        let server = endpoint.as_ref().unwrap_or(&parsed);
        let upstream = match (server.host_str(), server.port_or_known_default()) {
            (Some(host), Some(port)) => (host.trim_start_matches('[').trim_end_matches(']'), port)
                .to_socket_addrs()
                .map_err(|e| bad(format!("cannot resolve {host}: {e}")))?
                .next()
                .ok_or_else(|| bad(format!("{host} has no address")))?,
            _ => return Err(bad(format!("{server} names no server"))),
        };
        Ok(Route { upstream, url: parsed, endpoint })
    }

    /// The URL and options whose requests go to the proxy at `proxy`.
    fn through(&self, proxy: SocketAddr, options: &RemoteOptions) -> (String, RemoteOptions) {
        let mut options = options.clone();
        let at = |u: &url::Url| -> String {
            let mut u = u.clone();
            // A URL with a host takes another host and port (the proxy's).
            let _ = u.set_ip_host(proxy.ip());
            let _ = u.set_port(Some(proxy.port()));
            u.to_string()
        };
        match &self.endpoint {
            None => (at(&self.url), options),
            Some(endpoint) => {
                // Applied last, over the environment's and the caller's.
                options
                    .store_options
                    .push(("aws_endpoint".into(), at(endpoint).trim_end_matches('/').into()));
                (self.url.to_string(), options)
            }
        }
    }
}

/// The S3 endpoint the store would use: the last of the options' endpoint
/// keys, else the environment's (object_store's names for it).
fn s3_endpoint(options: &RemoteOptions) -> Option<String> {
    const KEYS: [&str; 4] = ["aws_endpoint", "aws_endpoint_url", "endpoint", "endpoint_url"];
    let given =
        options.store_options.iter().rev().find(|(k, _)| KEYS.contains(&k.to_ascii_lowercase().as_str()));
    given
        .map(|(_, v)| v.clone())
        .or_else(|| ["AWS_ENDPOINT", "AWS_ENDPOINT_URL"].iter().find_map(|k| std::env::var(k).ok()))
}

/// One set read through the proxy at one round trip.
struct Reader<'a> {
    url: &'a str,
    options: &'a RemoteOptions,
    latency_ms: f64,
    set: &'a QuerySet,
    /// The local answers, query by query.
    want: &'a [Counted],
}

/// Per query of a set: what the open and the query fetched, and their times.
struct Samples {
    open: Option<Vec<(TransferCounts, f64)>>,
    query: Vec<(TransferCounts, f64)>,
}

impl Reader<'_> {
    /// Each query on a reader of its own.
    fn cold(&self) -> Result<Samples, BenchError> {
        let (mut opens, mut queries) = (Vec::new(), Vec::new());
        for (i, q) in self.set.boxes.iter().enumerate() {
            let started = Instant::now();
            let db = Database::open_url(self.url, self.options).map_err(opening(self.url))?;
            let txn = db.begin_read().map_err(opening(self.url))?;
            let open_ms = started.elapsed().as_secs_f64() * 1e3;
            let opened = counts(&db);
            let (fetched, ms) = self.query(&db, &txn, i, q, Cache::Cold)?;
            opens.push((opened, open_ms));
            queries.push((fetched.since(&opened), ms));
        }
        Ok(Samples { open: Some(opens), query: queries })
    }

    /// One reader: a pass over the set fills its cache, the next is measured.
    fn warm(&self) -> Result<Samples, BenchError> {
        let db = Database::open_url(self.url, self.options).map_err(opening(self.url))?;
        let txn = db.begin_read().map_err(opening(self.url))?;
        for (i, q) in self.set.boxes.iter().enumerate() {
            self.query(&db, &txn, i, q, Cache::Warm)?;
        }
        let mut queries = Vec::with_capacity(self.set.boxes.len());
        for (i, q) in self.set.boxes.iter().enumerate() {
            let before = counts(&db);
            let (fetched, ms) = self.query(&db, &txn, i, q, Cache::Warm)?;
            queries.push((fetched.since(&before), ms));
        }
        Ok(Samples { open: None, query: queries })
    }

    /// Query `i` of the set, checked against the local answer: the
    /// reader's counts after it, and its wall time in ms.
    fn query(
        &self,
        db: &Database,
        txn: &ReadTransaction,
        i: usize,
        q: &Aabb,
        cache: Cache,
    ) -> Result<(TransferCounts, f64), BenchError> {
        let started = Instant::now();
        let got = exact_answer(txn, q)?;
        let ms = started.elapsed().as_secs_f64() * 1e3;
        let at =
            format!("{}, query {i} {q:?} ({}, {} ms added)", self.set.label, cache.label(), self.latency_ms);
        let want = self.want.get(i).ok_or_else(|| BenchError::Invalid(format!("{at}: no local answer")))?;
        agree(&at, ("the local file", &want.objects), ("the URL", &got.objects))?;
        if got.reads != want.reads {
            return Err(BenchError::Mismatch(format!(
                "block reads differ on {at}: the local file {:?}, the URL {:?}",
                want.reads, got.reads
            )));
        }
        Ok((counts(db), ms))
    }
}

/// What a remote reader fetched since it opened (a local one: nothing).
fn counts(db: &Database) -> TransferCounts {
    db.transfer_counts().unwrap_or_default()
}

impl Samples {
    fn row(&self, set: &QuerySet, latency_ms: f64, local: &LocalSet) -> RemoteRow {
        let query = means(&self.query);
        let open = self.open.as_deref().map(means);
        // With its open, when cold.
        let totals: Vec<f64> = match &self.open {
            Some(open) => self.query.iter().zip(open).map(|(q, o)| q.1 + o.1).collect(),
            None => self.query.iter().map(|q| q.1).collect(),
        };
        RemoteRow {
            set: set.label.clone(),
            latency_ms,
            cache: if self.open.is_some() { Cache::Cold } else { Cache::Warm },
            queries: self.query.len(),
            block_reads: local.block_reads,
            local_block_bytes: local.block_bytes,
            open,
            query,
            bytes_ratio: (local.block_bytes > 0.0).then(|| query.bytes / local.block_bytes),
            total_ms: mean(&totals),
            total_ms_p95: p95(&totals),
        }
    }
}

fn means(samples: &[(TransferCounts, f64)]) -> Transfer {
    let each =
        |f: fn(&TransferCounts) -> u64| mean(&samples.iter().map(|s| f(&s.0) as f64).collect::<Vec<_>>());
    let ms: Vec<f64> = samples.iter().map(|s| s.1).collect();
    Transfer {
        requests: each(|c| c.requests),
        round_trips: each(|c| c.round_trips),
        bytes: each(|c| c.bytes),
        wall_ms: mean(&ms),
        wall_ms_p95: p95(&ms),
    }
}

fn mean(xs: &[f64]) -> f64 {
    xs.iter().sum::<f64>() / xs.len().max(1) as f64
}

/// The 95th percentile by nearest rank: the smallest value at least 95% of
/// the values do not exceed (0 for none).
fn p95(xs: &[f64]) -> f64 {
    let mut sorted = xs.to_vec();
    sorted.sort_by(f64::total_cmp);
    let rank = (sorted.len() as f64 * 0.95).ceil() as usize;
    sorted.get(rank.saturating_sub(1)).copied().unwrap_or(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_95th_percentile_is_a_value_by_nearest_rank() {
        let xs: Vec<f64> = (1..=20).map(f64::from).rev().collect();
        assert_eq!(p95(&xs), 19.0);
        assert_eq!(p95(&[3.0]), 3.0);
        assert_eq!(p95(&[]), 0.0);
        assert_eq!(mean(&[1.0, 2.0, 6.0]), 3.0);
    }

    #[test]
    fn an_http_url_is_sent_to_the_proxy_and_an_s3_endpoint_too() {
        let options = RemoteOptions::default();
        let route = Route::of("http://127.0.0.1:9/files/ship.mkt", &options).unwrap();
        assert_eq!(route.upstream, "127.0.0.1:9".parse().unwrap());
        let proxy: SocketAddr = "127.0.0.1:4000".parse().unwrap();
        assert_eq!(route.through(proxy, &options).0, "http://127.0.0.1:4000/files/ship.mkt");

        let s3 = RemoteOptions {
            store_options: vec![("aws_endpoint".into(), "http://127.0.0.1:5000".into())],
            ..RemoteOptions::default()
        };
        let route = Route::of("s3://models/ship.mkt", &s3).unwrap();
        assert_eq!(route.upstream, "127.0.0.1:5000".parse().unwrap());
        let (url, through) = route.through(proxy, &s3);
        assert_eq!(url, "s3://models/ship.mkt");
        assert_eq!(
            through.store_options.last().unwrap(),
            &("aws_endpoint".into(), "http://127.0.0.1:4000".into())
        );
    }

    #[test]
    fn urls_the_proxy_cannot_route_are_refused_with_a_reason() {
        let options = RemoteOptions::default();
        for (url, reason) in [("not a url", "not a URL"), ("gs://bucket/ship.mkt", "not gs://")] {
            let e = Route::of(url, &options).err().map(|e| e.to_string()).unwrap_or_default();
            assert!(e.contains(reason), "{url}: {e}");
        }
    }
}
