//! Command-line arguments (clap), turned into library options here and nowhere else.

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand};
use mktree::bulk::{BuildParams, LeafRule, LookAhead, Method, QueryExtent, TieBreak};
use mktree::geom::{Aabb, Point};
use mktree::{View, ViewOptions};

mod bench;
pub use bench::*;

#[derive(Parser, Debug)]
#[command(
    name = "mktree",
    version,
    about = "MKtree: a paged spatial index with levels of detail for large 3D scenes"
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Generate a scene as OBJ: a ship-outfitting preset (tanker1, tanker2, tanker3, ship) or a process plant (plant).
    Gen {
        preset: String,
        /// Number of objects (ship: 100 to 10,000,000).
        #[arg(long)]
        objects: Option<u64>,
        #[arg(long, default_value_t = 0)]
        seed: u64,
        #[arg(short = 'o', long = "output")]
        output: PathBuf,
    },
    /// Print a scene's counts, extent and size distributions.
    Info {
        scene: PathBuf,
        #[arg(long)]
        json: bool,
        #[command(flatten)]
        import: ImportArgs,
    },
    /// Build in memory (or read a .mkt file) and print the paper's per-level table and totals; for a
    /// file also its blocks and how far change commits moved its layout from a fresh one.
    Stats {
        input: PathBuf,
        #[command(flatten)]
        build: BuildArgs,
        #[arg(long)]
        json: bool,
    },
    /// Every node of the tree as JSON.
    Dump {
        input: PathBuf,
        #[command(flatten)]
        build: BuildArgs,
        #[arg(long)]
        json: bool,
    },
    /// The grid of the paper's Tables 39-44: MOA and LAA over R and MemPage.
    Sweep {
        scene: PathBuf,
        /// MemPage values, comma-separated (default: 10,20,30 below 1,000 objects, else 100,200,500).
        #[arg(long, value_delimiter = ',')]
        pages: Option<Vec<u32>>,
        /// R values, comma-separated.
        #[arg(long, value_delimiter = ',', default_values_t = vec![0.01, 0.2, 0.3])]
        rates: Vec<f64>,
        /// LAA's look-ahead level in the grid.
        #[arg(long, default_value = "max")]
        look_ahead: LookAhead,
        #[arg(long)]
        json: bool,
        #[command(flatten)]
        import: ImportArgs,
    },
    /// Bulk-load a scene into an .mkt file in one write transaction.
    ///
    /// Reads the scene (OBJ, a folder of STL/OBJ files, or glTF; an OBJ
    /// larger than half of --memory is staged on disk), builds the tree by
    /// --method (refine unless asked), computes each object's bounds at
    /// levels 2 .. M-1 and keeps only those the read model says save more
    /// reads than they cost, writes the geometry blocks, node blocks and key
    /// index, then commits: the file holds the old tree or the new one,
    /// never a mix. An existing file keeps its block size and M.
    Build {
        /// The scene: an OBJ file, a folder of STL/OBJ files, or glTF (.gltf, .glb).
        scene: PathBuf,
        /// The .mkt file: created, or its tree replaced.
        #[arg(short = 'o', long = "output")]
        output: PathBuf,
        #[command(flatten)]
        build: BuildArgs,
        #[command(flatten)]
        lod: LodArgs,
        /// If another process is writing the file, wait for it instead of failing.
        #[arg(long)]
        wait: bool,
        /// Key each object by its name (names must then be unique); by default an
        /// object's key is its id, its position in the input.
        #[arg(long)]
        key_names: bool,
        /// Memory the build may use (e.g. 4G, 512M): an OBJ file larger than
        /// half of it is staged on disk beside the output, meshes in a spill
        /// file, instead of read whole; a scene whose tree would still not
        /// fit is refused before the build. At least 64M: the OBJ reader alone
        /// keeps up to 64 MB of vertices.
        #[arg(long, value_parser = memory_size, default_value = "4G")]
        memory: u64,
        /// Stage an OBJ file on disk whatever its size, as one larger than
        /// half of --memory is (the same file results).
        #[arg(long)]
        stage: bool,
        #[arg(long)]
        json: bool,
    },
    /// Check a file's exact answers against its scene, read in one streaming
    /// pass: box and collision queries around objects spread over the ids.
    Verify {
        file: PathBuf,
        /// The scene the file was built from.
        scene: PathBuf,
        /// Box queries, and as many collision queries.
        #[arg(long, default_value_t = 50)]
        queries: u32,
        #[arg(long)]
        json: bool,
        #[command(flatten)]
        import: ImportArgs,
    },
    /// Per level of detail: faces at the root (b and B), eps, measured error, bytes and blocks.
    Lods {
        file: PathBuf,
        #[arg(long)]
        json: bool,
    },
    /// One node's b(S_n,k) (or B(S_n,k) with --objects): faces, bytes, eps, predicted and actual reads.
    Node {
        file: PathBuf,
        /// Node id (preorder, root 0).
        node: u32,
        /// Level k, 1 ..= M.
        #[arg(long)]
        lod: u8,
        /// B(S_n,k), the per-object bounds, instead of b(S_n,k).
        #[arg(long)]
        objects: bool,
        /// Write the bound as OBJ, one `o` per stored piece.
        #[arg(long)]
        export: Option<PathBuf>,
        #[arg(long)]
        json: bool,
    },
    /// Objects that meet a box, sphere or view frustum at level k (exact at M), with the block reads it took.
    Query {
        file: PathBuf,
        #[command(flatten)]
        shape: ShapeArgs,
        #[command(flatten)]
        level: LevelArgs,
        #[arg(long)]
        json: bool,
    },
    /// Objects colliding with (or within --clearance of) a posed query object.
    #[command(group = clap::ArgGroup::new("query").required(true).multiple(false))]
    Collide {
        file: PathBuf,
        /// The query object: a scene file (OBJ, STL, glTF; all its objects as one mesh).
        #[arg(long, group = "query")]
        mesh: Option<PathBuf>,
        /// The query object: object ID of the file's own scene (left out of the answer).
        #[arg(long, group = "query")]
        object: Option<u32>,
        /// Translation x,y,z in mm.
        #[arg(long, value_parser = numbers::<3>, allow_hyphen_values = true, default_value = "0,0,0")]
        translate: [f64; 3],
        /// Rotations about x, then y, then z, in degrees, about the object's box centre.
        #[arg(long, value_parser = numbers::<3>, allow_hyphen_values = true, default_value = "0,0,0")]
        rotate_deg: [f64; 3],
        /// d in mm: objects within d collide.
        #[arg(long, default_value_t = 0.0)]
        clearance: f64,
        #[command(flatten)]
        level: LevelArgs,
        #[arg(long)]
        json: bool,
        #[command(flatten)]
        import: ImportArgs,
    },
    /// Every pair of objects that intersect or come within --clearance, by the tree against itself;
    /// with --a, --b, --type or --test, a typed clash test between chosen sets (docs/clash.md).
    Clash {
        file: PathBuf,
        /// d in mm (the untyped run).
        #[arg(long, default_value_t = 0.0)]
        clearance: f64,
        /// Level k, 1 ..= M (default M: exact; the untyped run).
        #[arg(long)]
        lod: Option<u8>,
        /// JSON: one line per clash, then a summary line (the untyped run: one JSON answer).
        #[arg(long)]
        json: bool,
        #[command(flatten)]
        typed: ClashArgs,
    },
    /// Catalogs: many .mkt files (paths or URLs) queried as one (format-spec/catalog.md).
    Catalog {
        #[command(subcommand)]
        action: CatalogAction,
    },
    /// Statuses of a recorded clash test: list them, or set Reviewed, Approved or Active on a pair.
    ClashStatus {
        file: PathBuf,
        /// The recorded test's name.
        #[arg(long)]
        test: String,
        /// The pair's keys (with --set).
        #[arg(long)]
        a: Option<String>,
        #[arg(long)]
        b: Option<String>,
        /// Only clashes of this type (hard, clearance, touch, duplicate).
        #[arg(long = "type")]
        kind: Option<String>,
        /// The status to set: reviewed, approved, or active.
        #[arg(long)]
        set: Option<String>,
        /// Keys are text, even when they look like integers.
        #[arg(long)]
        text: bool,
        /// The status store (default FILE.clash beside the file).
        #[arg(long)]
        store: Option<PathBuf>,
        #[arg(long)]
        json: bool,
    },
    /// Many queries and changes in one process: one JSON request per line (stdin, or --queries), one JSON answer per line; changes commit one per line, or --commit-every N together.
    Batch {
        file: PathBuf,
        /// Read the requests from this file instead of stdin.
        #[arg(long)]
        queries: Option<PathBuf>,
        /// The longest request line, bytes (e.g. 64K, 1M): a longer line
        /// gets an error answer and is skipped, never held in memory.
        #[arg(long, value_parser = byte_size, default_value = "1M")]
        max_line: u64,
        /// Write lines per commit: every N changes commit together (the
        /// last ones when the input ends).
        #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u64).range(1..))]
        commit_every: u64,
        /// If another process is writing the file, wait for it instead of failing.
        #[arg(long)]
        wait: bool,
    },
    /// The view's cut through the levels of detail: (node, level) pieces front to back, as JSON.
    View {
        file: PathBuf,
        #[command(flatten)]
        view: ViewArgs,
    },
    /// The tree as a 3D Tiles 1.1 tileset: tileset.json (one tile per node, REPLACE) and one .glb per tile.
    #[command(name = "export-3dtiles")]
    Export3dTiles {
        file: PathBuf,
        /// The directory to write (created if missing).
        out: PathBuf,
        #[arg(long)]
        json: bool,
    },
    /// Serves an exported tileset and a page that shows it (three.js, 3DTilesRendererJS) on 127.0.0.1.
    Serve {
        /// The directory `export-3dtiles` wrote.
        tiles: PathBuf,
        /// The port (0: any free one; the address is printed).
        #[arg(long, default_value_t = 8080)]
        port: u16,
        /// The page's npm packages (default: the checkout's viewer/node_modules, from viewer/install.sh).
        #[arg(long)]
        vendor: Option<PathBuf>,
    },
    /// A picture (PNG) of the view's cut, coloured by level; or with --node, one node's level of detail.
    Render {
        file: PathBuf,
        #[command(flatten)]
        view: ViewArgs,
        /// Draw node N's level --lod instead of the cut: b(S_n,k), or with --objects B(S_n,k).
        #[arg(long, requires = "lod")]
        node: Option<u32>,
        /// With --node: the level k, 1 ..= M.
        #[arg(long, requires = "node")]
        lod: Option<u8>,
        /// With --node: each object's bound B(S_n,k) rather than their union b(S_n,k).
        #[arg(long, requires = "node")]
        objects: bool,
        #[arg(short, long)]
        output: PathBuf,
        #[arg(long)]
        json: bool,
    },
    /// Frustum queries along a camera path with an LRU pool kept across steps: reads and hits per step.
    Navigate {
        file: PathBuf,
        /// CSV, one camera per line: ex,ey,ez,tx,ty,tz (mm).
        #[arg(long)]
        path: PathBuf,
        /// Blocks the pool holds.
        #[arg(long)]
        cache_blocks: usize,
        /// Vertical field of view, degrees.
        #[arg(long, default_value_t = 60.0)]
        fov_deg: f64,
        #[arg(long, default_value_t = 1.5)]
        aspect: f64,
        /// Near distance, mm.
        #[arg(long, default_value_t = 100.0)]
        near: f64,
        /// Far distance, mm.
        #[arg(long, default_value_t = 10_000.0)]
        far: f64,
        /// Level k, 1 ..= M (default M: exact).
        #[arg(long, conflicts_with = "tolerance")]
        lod: Option<u8>,
        /// τ in pixels: each step's view cut (stand-ins whose error projects to at most τ) instead of an exact frustum query.
        #[arg(long)]
        tolerance: Option<f64>,
        /// With --tolerance: the viewport's height in pixels (its width is height x aspect).
        #[arg(long, default_value_t = 720)]
        height_px: u32,
        /// With --tolerance: at most this many block reads per step.
        #[arg(long, requires = "tolerance")]
        budget: Option<u64>,
        #[arg(long)]
        json: bool,
    },
    /// The same random collision queries at every level: block reads, time and precision; a chart (SVG, PNG).
    Tradeoff {
        #[arg(required = true)]
        files: Vec<PathBuf>,
        #[arg(long, default_value_t = 100)]
        queries: usize,
        #[arg(long, default_value_t = 0)]
        seed: u64,
        /// Directory for tradeoff.svg and tradeoff.png.
        #[arg(long, default_value = ".")]
        out: PathBuf,
        #[arg(long)]
        json: bool,
    },
    /// One object by its key, through the key index: id, box, payload and the block reads.
    Get {
        file: PathBuf,
        /// The key: an integer (digits alone: 5, not +5 or 05), or text (with
        /// --text, or when it is not such an integer).
        #[arg(long)]
        key: std::ffi::OsString,
        /// Take the key as text even when it reads as a number.
        #[arg(long)]
        text: bool,
        /// Also read the object's exact mesh (its leaf and geometry blocks).
        #[arg(long)]
        mesh: bool,
        #[arg(long)]
        json: bool,
    },
    /// Deletes objects by key in one transaction (all or none), refitting the tree.
    Remove {
        file: PathBuf,
        /// The keys: integers (digits alone: 5, not +5 or 05), or text (with
        /// --text, or when not such an integer).
        #[arg(long = "key", required = true)]
        keys: Vec<std::ffi::OsString>,
        /// Take the keys as text even when they read as numbers.
        #[arg(long)]
        text: bool,
        /// If another process is writing the file, wait for it instead of failing.
        #[arg(long)]
        wait: bool,
        #[arg(long)]
        json: bool,
    },
    /// Adds a scene's objects (OBJ, STL, glTF) to a file in one transaction,
    /// written copy on write: the changed leaves and their paths only.
    Insert {
        file: PathBuf,
        scene: PathBuf,
        /// Key each object by its name (else by the next integer keys).
        #[arg(long)]
        key_names: bool,
        #[arg(long)]
        json: bool,
    },
    /// Moves one object by an offset, written copy on write.
    Move {
        file: PathBuf,
        /// The key: an integer (digits alone: 5, not +5 or 05), or text (with
        /// --text, or when it is not such an integer).
        #[arg(long)]
        key: std::ffi::OsString,
        /// Take the key as text even when it reads as a number.
        #[arg(long)]
        text: bool,
        /// The offset in mm: dx,dy,dz.
        #[arg(long, value_parser = numbers::<3>, allow_hyphen_values = true)]
        by: [f64; 3],
        #[arg(long)]
        json: bool,
    },
    /// Upload the file at its last commit as one object (s3://, gs://, az://, file://), for readers elsewhere.
    Publish {
        file: PathBuf,
        /// Where: the object's URL; the store's settings and credentials come from the environment.
        url: String,
        #[arg(long)]
        json: bool,
    },
    /// Give the file's free blocks back: rewrite the tree low and cut the free end.
    Compact {
        file: PathBuf,
        /// If another process is writing the file, wait for it instead of failing.
        #[arg(long)]
        wait: bool,
        #[arg(long)]
        json: bool,
    },
    /// Lay a changed tree out anew as a bulk load of its objects would (change
    /// commits leave loose boxes, split subtrees and moved leaves); levels of
    /// detail are computed again.
    Optimize {
        file: PathBuf,
        /// If another process is writing the file, wait for it instead of failing.
        #[arg(long)]
        wait: bool,
        #[arg(long)]
        json: bool,
    },
    /// Verify every checksum and structural rule; exit 1 on any fault.
    Check {
        file: PathBuf,
        #[arg(long)]
        json: bool,
    },
    /// The same random box queries against each file: mean block reads, answers and time.
    BenchQueries {
        #[arg(required = true)]
        files: Vec<PathBuf>,
        #[arg(long, default_value_t = 100)]
        queries: usize,
        /// Box sides as shares of the scene extent, comma-separated.
        #[arg(long, value_delimiter = ',', default_values_t = vec![0.01, 0.05, 0.2])]
        shares: Vec<f64>,
        #[arg(long, default_value_t = 0)]
        seed: u64,
        #[arg(long)]
        json: bool,
    },
    /// Every bulk loader on the same scenes and queries: leaves visited (and
    /// block reads with --block-size) per query for boxes, cubes and collisions.
    BenchBuild(BenchBuildArgs),
    /// mktree against SQLite's R*Tree with geometry blobs (and rstar): reads per query, file sizes, warm time.
    BenchPeers(BenchPeersArgs),
    /// A local .mkt file against the same file at a URL (http(s):// or s3://) through a proxy that adds round trips: requests, bytes, round trips and wall time per query, cold and warm.
    BenchRemote(BenchRemoteArgs),
    /// A scene replaced by another object by object (deletes and inserts in
    /// write transactions): box-query reads against a fresh bulk load, and compact.
    BenchReplace(BenchReplaceArgs),
    /// Change commits (inserts, moves, removals, one at a time and many in
    /// one) on mktree and on SQLite's R*Tree plus blobs, in the same run.
    BenchChanges(BenchChangesArgs),
    /// One process of bench-changes' stream (run by bench-changes itself).
    #[command(hide = true)]
    BenchChangesWorker(StreamWorkerArgs),
    /// The view query along a walk through each file: reads and triangles per frame against tau, error under a block budget, exact frustum reads; a chart and frame strips.
    BenchView(BenchViewArgs),
    /// Import alone, timed: each scene read --repeat times; triangles and megabytes per second of the fastest run.
    BenchImport {
        #[arg(required = true)]
        files: Vec<PathBuf>,
        #[arg(long, default_value_t = 3)]
        repeat: usize,
        #[arg(long)]
        json: bool,
        #[command(flatten)]
        import: ImportArgs,
    },
    /// The first command to run: tanker2 against SQLite, levels of detail deciding clearance queries, a speed-accuracy chart.
    ///
    /// Generates tanker2 (3,900 objects) and, in a few seconds, prints one
    /// sentence per result: (1) the default file against SQLite's R*Tree
    /// with a table of geometry blobs on the same 100 queries per set,
    /// block reads per exact answer and per box filter, and both files'
    /// sizes; (2) a file of five levels (box, cuberille, voxel sets of 100
    /// and 25 mm, exact), bounds stored where they pay: 100 clearance
    /// queries (objects within 200 mm of a moved object) answered with and
    /// without the levels below M and in the default file, and the query
    /// where the levels saved most, decided level by level; (3) `tradeoff`
    /// on both files: block reads and precision at each level, also drawn
    /// as tradeoff.svg and tradeoff.png. The files stay in --dir.
    Demo {
        /// Where the files and the chart go.
        #[arg(long, default_value = "mktree-demo")]
        dir: PathBuf,
    },
}

/// A camera, its viewport and the view's tolerance.
#[derive(Args, Debug, Clone)]
pub struct ViewArgs {
    /// Eye x,y,z and target x,y,z in mm; up is +z (default: the whole scene, or node, from above its front left).
    #[arg(long, value_parser = numbers::<6>, allow_hyphen_values = true)]
    pub camera: Option<[f64; 6]>,
    /// Vertical field of view, degrees.
    #[arg(long, default_value_t = 60.0)]
    pub fov_deg: f64,
    #[arg(long, default_value_t = 1280)]
    pub width_px: u32,
    #[arg(long, default_value_t = 720)]
    pub height_px: u32,
    /// Near distance, mm.
    #[arg(long, default_value_t = 100.0)]
    pub near: f64,
    /// Far distance, mm (default: the scene's farthest corner).
    #[arg(long)]
    pub far: Option<f64>,
    /// τ, pixels: the largest projected error of a stand-in (0: exact everywhere).
    #[arg(long, default_value_t = 1.0)]
    pub tolerance: f64,
    /// Read at most this many blocks: the best cut that fits, coarser far away.
    #[arg(long)]
    pub budget: Option<u64>,
}

impl ViewArgs {
    /// The camera (default: framing `scene`), its far distance
    /// defaulting to `scene`'s farthest corner.
    pub fn view(&self, scene: &Aabb) -> View {
        let Some(c) = self.camera else {
            let v = mktree::render::framing(scene, self.width_px, self.height_px, self.fov_deg);
            let v = View { near_mm: self.near.min(v.near_mm), ..v };
            return match self.far {
                Some(far) => View { far_mm: far, ..v },
                None => v.seeing_all_of(scene),
            };
        };
        let view = View {
            eye: Point::new(c[0], c[1], c[2]),
            target: Point::new(c[3], c[4], c[5]),
            fov_deg: self.fov_deg,
            width_px: self.width_px,
            height_px: self.height_px,
            near_mm: self.near,
            far_mm: self.far.unwrap_or(0.0),
        };
        if self.far.is_some() { view } else { view.seeing_all_of(scene) }
    }

    /// The view query's options: tolerance and budget.
    pub fn view_options(&self, shapes: bool) -> ViewOptions {
        ViewOptions { tolerance_px: self.tolerance, budget: self.budget, shapes }
    }
}

/// The level and block budget of a query.
#[derive(Args, Debug, Clone)]
pub struct LevelArgs {
    /// Level k, 1 ..= M (default M: the exact answer; below M a superset).
    #[arg(long)]
    pub lod: Option<u8>,
    /// Read at most this many blocks; what is left unrefined is reported as maybe.
    #[arg(long)]
    pub budget: Option<u64>,
}

impl LevelArgs {
    pub fn options(&self) -> mktree::query::QueryOptions {
        mktree::query::QueryOptions { lod: self.lod, budget: self.budget, ..Default::default() }
    }
}

/// What `mktree catalog` does.
#[derive(Subcommand, Debug)]
pub enum CatalogAction {
    /// Describe files into a catalog: each model's root box, object count and commit.
    Create {
        /// The catalog to write (JSON; replaced whole).
        output: PathBuf,
        /// The models: KEY=LOCATION, or LOCATION (keyed by its file stem); a path or a URL.
        #[arg(required = true)]
        models: Vec<String>,
        #[arg(long)]
        json: bool,
    },
    /// The models of a catalog.
    Show {
        catalog: PathBuf,
        #[arg(long)]
        json: bool,
    },
    /// A box, sphere or frustum query over every model whose root box it may meet, in parallel.
    Query {
        catalog: PathBuf,
        #[command(flatten)]
        shape: ShapeArgs,
        #[command(flatten)]
        level: LevelArgs,
        /// Models opened and queried at once.
        #[arg(long, default_value_t = 16)]
        concurrency: usize,
        #[arg(long)]
        json: bool,
    },
}

/// A query's shape: exactly one of a box, a sphere and a frustum.
#[derive(Args, Debug, Clone)]
#[group(required = true, multiple = false)]
pub struct ShapeArgs {
    /// x0,y0,z0,x1,y1,z1 in mm, x0 <= x1, y0 <= y1, z0 <= z1, each in
    /// [-2^53, 2^53] (the library's rule, as in `batch`).
    #[arg(long = "box", value_parser = numbers::<6>, allow_hyphen_values = true)]
    pub aabb: Option<[f64; 6]>,
    /// x,y,z,r in mm.
    #[arg(long, value_parser = numbers::<4>, allow_hyphen_values = true)]
    pub sphere: Option<[f64; 4]>,
    /// A camera: eye x,y,z, target x,y,z, vertical fov (degrees), aspect, near, far (mm); up is +z.
    #[arg(long, value_parser = numbers::<10>, allow_hyphen_values = true)]
    pub frustum: Option<[f64; 10]>,
}

/// Levels of detail of a new tree.
#[derive(Args, Debug, Clone)]
pub struct LodArgs {
    /// M, the levels of detail of a new file: 1 the box, 2 the cuberille (a
    /// grid of at most 4,096 cells over the object), 3 .. M-1 voxel sets
    /// (the surface's cells at one lattice size each, eps_k), M the exact
    /// triangles [default: 4]. A bound is stored only where it pays.
    #[arg(long)]
    pub lods: Option<u8>,
    /// eps_k of the voxel levels 3 .. M-1 in mm, coarse to fine, comma-separated (default: from the median object's sides).
    #[arg(long, value_delimiter = ',')]
    pub lod_eps: Option<Vec<f64>>,
    /// Store every object's bound at every level below M, whether it pays or not.
    #[arg(long)]
    pub lod_store_all: bool,
    /// Store no group bounds b(S_n,k) (format-spec/group.md): the tree as
    /// format version 7 laid it out, to compare.
    #[arg(long)]
    pub no_group_bounds: bool,
}

impl LodArgs {
    pub fn params(&self) -> mktree::lod::LodParams {
        mktree::lod::LodParams {
            eps: self.lod_eps.clone(),
            store_all: self.lod_store_all,
            group_bounds: !self.no_group_bounds,
            ..mktree::lod::LodParams::default()
        }
    }
}

/// Options for reading scenes.
#[derive(Args, Debug, Clone)]
pub struct ImportArgs {
    /// glTF scale to millimetres (glTF is metres by specification).
    #[arg(long, default_value_t = 1000.0)]
    pub gltf_scale: f64,
}

impl ImportArgs {
    pub fn options(&self) -> mktree::scene::import::ImportOptions {
        mktree::scene::import::ImportOptions { gltf_scale: self.gltf_scale }
    }
}

/// Every bulk-loading option.
#[derive(Args, Debug, Clone)]
pub struct BuildArgs {
    /// Splitting method: refine (the default: fewest block reads measured,
    /// docs/build-methods.md), moa, laa, median, hilbert, sah, vsah.
    #[arg(long, default_value = "refine")]
    pub method: Method,
    /// R, in [0, 0.5].
    #[arg(long, default_value_t = 0.2)]
    pub rate: f64,
    /// MemPage: at most this many objects per leaf.
    #[arg(long, conflicts_with = "leaf_bytes")]
    pub page_objects: Option<u32>,
    /// Block size in bytes. For `build`, the file's block size; without
    /// --page-objects, leaves are also cut so their geometry fits one block.
    #[arg(long)]
    pub block_size: Option<u32>,
    /// Leaf capacity in bytes of geometry (in-memory builds only).
    #[arg(long)]
    pub leaf_bytes: Option<u64>,
    /// LAA: look-ahead level, a number or max.
    #[arg(long, default_value = "2")]
    pub look_ahead: LookAhead,
    /// Which of equally good cuts wins: first-found (the paper), widest-gap, most-balanced.
    #[arg(long, default_value = "first-found")]
    pub tie_break: TieBreak,
    /// refine: the query extent q its cost model is tuned for, in mm: one
    /// side, three (x,y,z), or auto (the mean object extent + 100 mm).
    #[arg(long, default_value = "auto")]
    pub query_extent: QueryExtent,
    #[command(flatten)]
    pub import: ImportArgs,
}

impl BuildArgs {
    /// The block size a file gets: the flag, or the library default.
    pub fn block_size(&self) -> u32 {
        self.block_size.unwrap_or(mktree::db::DEFAULT_BLOCK_SIZE)
    }

    /// The library's parameters. The leaf rule: MemPage objects if given, else
    /// bytes (explicit, or what a geometry block holds).
    pub fn params(&self) -> BuildParams {
        let leaf = match (self.page_objects, self.leaf_bytes) {
            (Some(n), _) => LeafRule::Objects(n),
            (None, Some(b)) => LeafRule::Bytes { capacity: b },
            (None, None) => BuildParams::for_blocks(self.block_size()).leaf,
        };
        BuildParams {
            method: self.method,
            rate: self.rate,
            leaf,
            look_ahead: self.look_ahead,
            tie_break: self.tie_break,
            query_extent: self.query_extent,
        }
    }
}

/// N comma-separated finite numbers.
fn numbers<const N: usize>(s: &str) -> Result<[f64; N], String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>().map_err(|_| format!("{x:?} is not a number")))
        .collect::<Result<_, _>>()?;
    let a: [f64; N] = v.try_into().map_err(|v: Vec<f64>| format!("{N} numbers expected, got {}", v.len()))?;
    if a.iter().any(|x| !x.is_finite()) {
        return Err("numbers must be finite".into());
    }
    Ok(a)
}

/// The least `build --memory`: the OBJ reader keeps up to 64 MB of
/// vertices however the scene is read, so less would be a promise broken.
const MIN_MEMORY: u64 = 64 << 20;

/// A `--memory` size: [`byte_size`], at least [`MIN_MEMORY`].
fn memory_size(s: &str) -> Result<u64, String> {
    let b = byte_size(s)?;
    if b < MIN_MEMORY {
        return Err(format!("{s:?} is below 64M, the least a build runs in (--stage stages a small scene)"));
    }
    Ok(b)
}

/// A size in bytes: a whole number with an optional K, M, G or T suffix (powers of 1024).
fn byte_size(s: &str) -> Result<u64, String> {
    let t = s.trim();
    let (digits, shift) = match t.chars().last().map(|c| c.to_ascii_uppercase()) {
        Some('K') => (&t[..t.len() - 1], 10),
        Some('M') => (&t[..t.len() - 1], 20),
        Some('G') => (&t[..t.len() - 1], 30),
        Some('T') => (&t[..t.len() - 1], 40),
        _ => (t, 0),
    };
    let n: u64 = digits.trim().parse().map_err(|_| format!("{s:?} is not a size such as 4G or 512M"))?;
    n.checked_mul(1 << shift)
        .filter(|&b| b > 0)
        .ok_or_else(|| format!("{s:?} is not a positive size below 2^64 bytes"))
}

/// A `KEY=VALUE` pair, the key not empty.
fn key_value(s: &str) -> Result<(String, String), String> {
    match s.split_once('=') {
        Some((k, v)) if !k.trim().is_empty() => Ok((k.trim().to_string(), v.to_string())),
        _ => Err(format!("{s:?} is not KEY=VALUE")),
    }
}

/// A typed clash test's flags (`mktree clash`).
#[derive(Args, Debug, Default)]
pub struct ClashArgs {
    /// Set A: a selector (all, key:GLOB, name:GLOB, class:GLOB, payload.FIELD:GLOB); repeat for a union.
    #[arg(long = "a")]
    pub a: Vec<String>,
    /// Set B, as --a (default: A against itself).
    #[arg(long = "b")]
    pub b: Vec<String>,
    /// hard, clearance or duplicate.
    #[arg(long = "type")]
    pub kind: Option<String>,
    /// Clearance distance, mm: pairs closer than this.
    #[arg(long)]
    pub distance: Option<f64>,
    /// mm: hard clashes penetrate more than this; duplicates differ by at most this (default 0.01).
    #[arg(long)]
    pub tolerance: Option<f64>,
    /// Report touches (contact without penetration) too.
    #[arg(long)]
    pub touch: bool,
    /// Grouping: none, a, proximity:MM, prefix:N (default none).
    #[arg(long)]
    pub group: Option<String>,
    /// Run (and record, with statuses) the test of this name: the flags given save it under the name.
    #[arg(long)]
    pub test: Option<String>,
    /// With --test: measure every pair, not only those a change touched.
    #[arg(long)]
    pub full: bool,
    /// The status store (default FILE.clash beside the file).
    #[arg(long)]
    pub store: Option<PathBuf>,
    /// Also write the clashes as BCF 3.0 (a topic per group, with a viewpoint and snapshot) to this file.
    #[arg(long)]
    pub bcf: Option<PathBuf>,
}

impl ClashArgs {
    /// Whether any typed flag is given.
    pub fn any(&self) -> bool {
        !self.a.is_empty()
            || !self.b.is_empty()
            || self.kind.is_some()
            || self.distance.is_some()
            || self.tolerance.is_some()
            || self.touch
            || self.group.is_some()
            || self.test.is_some()
            || self.bcf.is_some()
    }
}
