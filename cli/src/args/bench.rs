//! The benchmark commands' arguments (`bench-*`): what `mktree-bench`
//! runs, parsed here and handed over by `cmd/`.

use std::path::PathBuf;

use clap::Args;

use mktree::bulk::Method;

use super::{ImportArgs, byte_size, key_value, numbers};

/// `bench-build`'s arguments.
#[derive(Args, Debug, Clone)]
pub struct BenchBuildArgs {
    /// Scene files, or presets: tanker1, tanker2, tanker3, ship, ship:N (N objects).
    #[arg(required = true)]
    pub scenes: Vec<String>,
    /// MemPage: at most this many objects per leaf (default 100 without --block-size).
    #[arg(long, conflicts_with = "block_size")]
    pub page_objects: Option<u32>,
    /// Write each tree to a file of this block size, leaves cut to fit one
    /// block, and count its exact block reads.
    #[arg(long)]
    pub block_size: Option<u32>,
    /// Queries per query set.
    #[arg(long, default_value_t = 200)]
    pub queries: usize,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// R of MOA, LAA and refine's candidate cuts, in [0, 0.5].
    #[arg(long, default_value_t = 0.2)]
    pub rate: f64,
    /// Methods to run, comma-separated (default: all; LAA with look-ahead max).
    #[arg(long, value_delimiter = ',')]
    pub methods: Option<Vec<Method>>,
    #[arg(long)]
    pub json: bool,
    /// Write bench-build.json, bench-build.svg and bench-build.png here.
    #[arg(long)]
    pub out: Option<PathBuf>,
    #[command(flatten)]
    pub import: ImportArgs,
}

/// `bench-peers`' arguments.
#[derive(Args, Debug, Clone)]
pub struct BenchPeersArgs {
    /// Scene files, or presets: tanker1, tanker2, tanker3, ship, ship:N (N objects).
    #[arg(required = true)]
    pub scenes: Vec<String>,
    /// Queries per generated set (boxes of 1%, 5% and 20% of the extent, collisions).
    #[arg(long, default_value_t = mktree_bench::DEFAULT_QUERIES)]
    pub queries: usize,
    /// Seed of the generated query sets.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// mktree's block size and SQLite's page size, bytes (a power of two, 1024 to 65536).
    #[arg(long, default_value_t = mktree::db::DEFAULT_BLOCK_SIZE)]
    pub block_size: u32,
    /// M, the levels of detail of mktree's file (1: none, to see what the levels save).
    #[arg(long, default_value_t = mktree::db::DEFAULT_LOD_LEVELS)]
    pub lods: u8,
    /// Query boxes instead of the generated sets: one per line, x0,y0,z0,x1,y1,z1[,LABEL] in mm.
    #[arg(long)]
    pub query_file: Option<PathBuf>,
    /// Print the rows as JSON instead of tables.
    #[arg(long)]
    pub json: bool,
    /// Write bench-peers.json, bench-peers.svg and bench-peers.png here, and
    /// keep the built files (bench-peers-SCENE.mkt and .sqlite, replaced).
    #[arg(long)]
    pub out: Option<PathBuf>,
    #[command(flatten)]
    pub import: ImportArgs,
}

/// `bench-remote`'s arguments.
#[derive(Args, Debug, Clone)]
pub struct BenchRemoteArgs {
    /// The .mkt file on this machine.
    pub file: PathBuf,
    /// The same file at a URL: http(s)://HOST:PORT/PATH, or s3://BUCKET/KEY on an S3-compatible store (its endpoint from AWS_ENDPOINT or --store-option aws_endpoint=URL).
    pub url: String,
    /// Queries per set (boxes of 1%, 5% and 20% of the extent, collisions).
    #[arg(long, default_value_t = 20)]
    pub queries: usize,
    /// Seed of the query sets.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Round trips the proxy adds, ms, comma-separated: one pass over the sets each.
    #[arg(long, value_delimiter = ',', default_values_t = mktree_bench::DEFAULT_LATENCIES_MS)]
    pub latency: Vec<f64>,
    /// The remote reader's cache bound (K, M, G suffixes): warm reads hit it.
    #[arg(long, value_parser = byte_size, default_value = "64M")]
    pub cache_bytes: u64,
    /// Bytes an open fetches from the start of the object in its one request (K, M suffixes): the header, the meta block and the top of the tree.
    #[arg(long, value_parser = byte_size, default_value = "256K")]
    pub open_bytes: u64,
    /// Bytes a round of fetches may add, as a share of those it needs, to join requests across gaps (0 fetches only the blocks read).
    #[arg(long, default_value_t = 0.5)]
    pub gap_share: f64,
    /// A store setting KEY=VALUE as object_store names it (aws_endpoint, aws_allow_http, aws_region, ...), over the environment's; repeatable.
    #[arg(long = "store-option", value_parser = key_value)]
    pub store_options: Vec<(String, String)>,
    /// Print the result as JSON instead of tables.
    #[arg(long)]
    pub json: bool,
    /// Write bench-remote.json, bench-remote.svg and bench-remote.png here.
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// `bench-replace`'s arguments.
#[derive(Args, Debug, Clone)]
pub struct BenchReplaceArgs {
    /// Scene A: a file, or a preset (tanker1, tanker2, tanker3, ship, ship:N).
    pub scene: String,
    /// Scene B, which replaces A; by default A's preset with seed 1.
    #[arg(long)]
    pub revision: Option<String>,
    /// Objects replaced per write transaction, as a share of the scene.
    #[arg(long, default_value_t = 0.05)]
    pub batch: f64,
    /// Queries per generated set (boxes of 1%, 5% and 20% of the extent, collisions).
    #[arg(long, default_value_t = 100)]
    pub queries: usize,
    /// Seed of the replacement order and the query sets.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Where the files are built (removed afterwards).
    #[arg(long, default_value = ".")]
    pub dir: PathBuf,
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub import: ImportArgs,
}

/// `bench-changes`' arguments.
#[derive(Args, Debug, Clone)]
pub struct BenchChangesArgs {
    /// Scenes: files, or presets (tanker1, tanker2, tanker3, ship, ship:N).
    #[arg(required = true)]
    pub scenes: Vec<String>,
    /// Single-object commits of each kind: insert, move, remove.
    #[arg(long, default_value_t = 200)]
    pub singles: usize,
    /// Changes in the one mixed commit.
    #[arg(long, default_value_t = 1000)]
    pub batch: usize,
    /// Queries per generated set, run on the changed file and a fresh load.
    #[arg(long, default_value_t = 100)]
    pub queries: usize,
    /// Seed of the changes and the query sets.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Where the files are built (removed afterwards).
    #[arg(long, default_value = ".")]
    pub dir: PathBuf,
    /// Also draw the median time per single-object commit against the
    /// scenes' objects, a line per engine and kind, as PATH.svg and PATH.png.
    #[arg(long, value_name = "PATH")]
    pub chart: Option<PathBuf>,
    /// Leave out the two-process stream (a writer process's single-object
    /// moves while a reader process queries).
    #[arg(long)]
    pub no_stream: bool,
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub import: ImportArgs,
}

/// `bench-changes-worker`'s arguments: one side of the stream.
#[derive(Args, Debug, Clone)]
pub struct StreamWorkerArgs {
    /// mktree or sqlite.
    #[arg(long)]
    pub engine: String,
    /// writer or reader.
    #[arg(long)]
    pub role: String,
    #[arg(long)]
    pub file: PathBuf,
    /// Objects' integer keys lie below this.
    #[arg(long)]
    pub keys: u64,
    /// The writer's commits.
    #[arg(long)]
    pub commits: usize,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// The scene's box: x0,y0,z0,x1,y1,z1 (mm).
    #[arg(long, value_parser = numbers::<6>, allow_hyphen_values = true)]
    pub extent: [f64; 6],
    /// The reader stops once this file exists.
    #[arg(long)]
    pub stop: PathBuf,
}

/// `bench-view`'s walks.
#[derive(clap::ValueEnum, Debug, Clone, Copy, PartialEq, Eq)]
pub enum Walk {
    /// Through the scene along its x axis, looking ahead and slightly down.
    Length,
    /// Round the scene from outside, looking at its centre.
    Orbit,
}

/// `bench-view`'s arguments.
#[derive(Args, Debug, Clone)]
pub struct BenchViewArgs {
    /// .mkt files (each walked through along its scene's x axis, or orbited).
    #[arg(required = true)]
    pub files: Vec<PathBuf>,
    /// Frames along the walk.
    #[arg(long, default_value_t = 20)]
    pub steps: usize,
    /// The walk: `length` (through the scene along x, looking ahead) or
    /// `orbit` (round it from outside, looking at its centre).
    #[arg(long, value_enum, default_value_t = Walk::Length)]
    pub walk: Walk,
    /// Blocks the pool holds.
    #[arg(long, default_value_t = 256)]
    pub cache_blocks: usize,
    /// The tolerances τ to sweep, pixels, comma-separated (`--taus 1,16`).
    #[arg(long, value_delimiter = ',', default_values_t = [0.0, 1.0, 4.0, 16.0, 64.0, 256.0])]
    pub taus: Vec<f64>,
    /// The block budgets per frame to sweep (at τ = 1 px), comma-separated (`--budgets 50,100`).
    #[arg(long, value_delimiter = ',', default_values_t = [25, 50, 100, 200, 400])]
    pub budgets: Vec<u64>,
    /// The viewport's height in pixels (its width is 1.5 times that).
    #[arg(long, default_value_t = 720)]
    pub height_px: u32,
    /// Where bench-view.json, the chart (bench-view.svg, .png) and the frame strips
    /// (frames-NAME.png: the scene's middle section at each tau, 480 x 320 px) go.
    #[arg(long, default_value = ".")]
    pub out: PathBuf,
    #[arg(long)]
    pub json: bool,
}
