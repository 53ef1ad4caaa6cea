//! The mktree side of the peer benchmark: the scene built into a file as
//! `mktree build` builds it by default, and the queries the other peers
//! answer, cold or through a cache that holds the whole file.
//!
//! Every call into the engine's build and query API is in this file, behind
//! a few small functions: that API is being rewritten, and this is the one
//! place the bench adapts to it.

use std::path::{Path, PathBuf};
use std::time::Instant;

use mktree::bulk::BuildParams;
use mktree::db::{CreateOptions, Database, ReadTransaction, read_hierarchy_blocks};
use mktree::geom::Aabb;
use mktree::lod::LodParams;
use mktree::query::{QueryAnswer, QueryOptions, Region, query_region};
use mktree::scene::Scene;
use mktree::store::BlockCache;

use crate::error::{BenchError, io};

/// A built mktree file, open for reading.
pub struct MktreePeer {
    path: PathBuf,
    block_size: u32,
    build_seconds: f64,
    txn: ReadTransaction,
    paths: AnswerPaths,
    // Held for its file lock while the snapshot is read.
    _db: Database,
}

/// Where the stored tree's records lie, to count the node blocks on the
/// paths from the root to the leaves holding given objects: the node
/// blocks every traversal reads to report them (a subtree inside the query
/// still has its leaves read, for the keys), and the root's block for any
/// query meeting the root's box, even one with no answer.
struct AnswerPaths {
    /// The root's box.
    root: Aabb,
    /// Per node: its parent (`u32::MAX` at the root).
    parent: Vec<u32>,
    /// Per node: the node block holding its record.
    block: Vec<u32>,
    /// Per object id: the leaf holding it (`u32::MAX` for none).
    leaf_of: Vec<u32>,
}

impl AnswerPaths {
    fn of(txn: &ReadTransaction) -> Result<AnswerPaths, BenchError> {
        let (tree, block) = read_hierarchy_blocks(txn)?;
        let mut parent = vec![u32::MAX; tree.nodes.len()];
        let mut leaf_of = Vec::new();
        for (i, node) in tree.nodes.iter().enumerate() {
            for c in node.children().into_iter().flatten() {
                if let Some(p) = parent.get_mut(c.index()) {
                    *p = i as u32;
                }
            }
            for o in node.objects().unwrap_or_default() {
                let o = o.index();
                if o >= leaf_of.len() {
                    leaf_of.resize(o + 1, u32::MAX);
                }
                leaf_of[o] = i as u32;
            }
        }
        let root = tree.nodes.first().map_or(Aabb::EMPTY, |n| n.aabb);
        Ok(AnswerPaths { root, parent, block, leaf_of })
    }

    /// The distinct node blocks on the paths from the root to the leaves
    /// holding `objects` (ids), the answer to `query`.
    fn node_blocks(&self, query: &Aabb, objects: &[u32]) -> u64 {
        let mut walked = std::collections::HashSet::new();
        let mut blocks = std::collections::HashSet::new();
        if self.root.intersects(query) {
            blocks.extend(self.block.first());
        }
        for &o in objects {
            let mut n = self.leaf_of.get(o as usize).copied().unwrap_or(u32::MAX);
            while n != u32::MAX && walked.insert(n) {
                blocks.insert(self.block[n as usize]);
                n = self.parent[n as usize];
            }
        }
        blocks.len() as u64
    }
}

/// Block reads of one query, by kind.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Reads {
    /// Node blocks.
    pub node: u64,
    /// Geometry blocks (exact object records).
    pub geometry: u64,
    /// Every block read.
    pub total: u64,
}

/// One query's answer and the blocks it read.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Counted {
    /// Sorted object ids.
    pub objects: Vec<u32>,
    /// Blocks read, the file's opening left out.
    pub reads: Reads,
}

/// A block cache that holds every block once warm.
pub struct WarmCache(BlockCache);

/// Builds `scene` into a new file at `path` with `mktree build`'s defaults
/// (cli/src/args.rs): method refine (R 0.2, query extent auto), leaves
/// whose geometry fits one block, M = `lod_levels` levels of detail.
pub fn build_file(
    scene: &Scene,
    path: &Path,
    block_size: u32,
    lod_levels: u8,
) -> Result<MktreePeer, BenchError> {
    let started = Instant::now();
    let db = Database::create(path, CreateOptions { block_size, lod_levels })?;
    let params = BuildParams::for_blocks(block_size);
    let mut w = db.begin_write()?;
    w.set_lod_params(LodParams::default());
    w.bulk_load(scene, &params, &|_| {})?;
    w.commit()?;
    let build_seconds = started.elapsed().as_secs_f64();
    let txn = db.begin_read()?;
    let paths = AnswerPaths::of(&txn)?;
    Ok(MktreePeer { path: path.to_path_buf(), block_size, build_seconds, txn, paths, _db: db })
}

impl MktreePeer {
    /// Seconds from creating the file to its build's commit (the bench's
    /// own reading of the tree's paths left out).
    pub fn build_seconds(&self) -> f64 {
        self.build_seconds
    }

    /// Bytes per block.
    pub fn block_size(&self) -> u32 {
        self.block_size
    }

    /// The file's size in bytes.
    pub fn file_bytes(&self) -> Result<u64, BenchError> {
        Ok(std::fs::metadata(&self.path).map_err(io(format!("reading {}", self.path.display())))?.len())
    }

    /// The objects whose triangles meet `query` (level M), from a cold cache.
    pub fn exact(&self, query: &Aabb) -> Result<Counted, BenchError> {
        exact_answer(&self.txn, query)
    }

    /// The least node blocks a traversal reads to report `objects` (ids)
    /// as the answer to `query`: those on the paths from the root to their
    /// leaves, and the root's when the query meets its box.
    pub fn answer_node_blocks(&self, query: &Aabb, objects: &[u32]) -> u64 {
        self.paths.node_blocks(query, objects)
    }

    /// The objects whose boxes meet `query` (level 1), from a cold cache.
    pub fn filter(&self, query: &Aabb) -> Result<Counted, BenchError> {
        Ok(counted(self.region(query, Some(1), None)?))
    }

    /// An empty cache with room for every block of the file.
    pub fn warm_cache(&self) -> WarmCache {
        WarmCache(BlockCache::new(usize::MAX))
    }

    /// The exact answer to `query` through `cache`, and the blocks it read
    /// from the file (none once warm).
    pub fn warm_exact(&self, cache: &WarmCache, query: &Aabb) -> Result<Counted, BenchError> {
        Ok(counted(self.region(query, None, Some(&cache.0))?))
    }

    fn region(
        &self,
        query: &Aabb,
        lod: Option<u8>,
        cache: Option<&BlockCache>,
    ) -> Result<QueryAnswer, BenchError> {
        // Without a cache of the caller's, the query reads through a pool of
        // its own: each block at most once, every read counted.
        Ok(query_region(&self.txn, &Region::Box(*query), &QueryOptions { lod, ..Default::default() }, cache)?)
    }
}

/// The objects of `txn`'s snapshot whose triangles meet `query` (level M),
/// read through a pool of the query's own, every block read counted: the
/// exact answer of any reader, of a local file or of a URL.
pub fn exact_answer(txn: &ReadTransaction, query: &Aabb) -> Result<Counted, BenchError> {
    Ok(counted(query_region(txn, &Region::Box(*query), &QueryOptions::default(), None)?))
}

fn counted(answer: QueryAnswer) -> Counted {
    let r = answer.stats.reads;
    Counted {
        objects: answer.objects.iter().map(|o| o.0).collect(),
        reads: Reads { node: r.node, geometry: r.geometry, total: r.total() },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mktree::db::DEFAULT_LOD_LEVELS;
    use mktree::scene::generate::{GenOptions, Preset, generate_scene};

    #[test]
    fn answers_are_exact_at_level_m_and_by_box_at_level_1() {
        let scene = generate_scene(&GenOptions { preset: Preset::Tanker1, objects: None, seed: 0 }).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let peer = build_file(&scene, &dir.path().join("t1.mkt"), 4096, DEFAULT_LOD_LEVELS).unwrap();
        assert!(peer.file_bytes().unwrap() > 0 && peer.file_bytes().unwrap().is_multiple_of(4096));
        let cache = peer.warm_cache();
        let boxes = scene.object_boxes();
        for q in crate::random_boxes(&scene.aabb(), 10, 0.2, 1) {
            let region = mktree::query::Region::Box(q);
            let exact: Vec<u32> =
                mktree::query::brute_force_region(&scene, &region).iter().map(|o| o.0).collect();
            let (e, f) = (peer.exact(&q).unwrap(), peer.filter(&q).unwrap());
            assert_eq!(e.objects, exact);
            assert!(f.objects.iter().all(|&o| boxes[o as usize].grown(1.0).intersects(&q)));
            assert!(exact.iter().all(|o| f.objects.contains(o)));
            assert_eq!(e.reads.total, e.reads.node + e.reads.geometry);
            assert!(e.reads.total >= f.reads.total && f.reads.node > 0);
            peer.warm_exact(&cache, &q).unwrap();
            let warm = peer.warm_exact(&cache, &q).unwrap();
            assert_eq!((warm.objects, warm.reads.total), (exact, 0));
        }
    }

    #[test]
    fn the_lower_bound_is_never_above_the_reads_and_counts_each_block_once() {
        let scene = generate_scene(&GenOptions { preset: Preset::Tanker1, objects: None, seed: 0 }).unwrap();
        let dir = tempfile::tempdir().unwrap();
        // Small blocks: a tree several node blocks deep.
        let peer = build_file(&scene, &dir.path().join("t1.mkt"), 2048, DEFAULT_LOD_LEVELS).unwrap();
        let mut below = 0;
        for share in [0.01, 0.05, 0.2, 1.0] {
            for q in crate::random_boxes(&scene.aabb(), 20, share, 2) {
                let (e, f) = (peer.exact(&q).unwrap(), peer.filter(&q).unwrap());
                let exact = peer.answer_node_blocks(&q, &e.objects) + e.reads.geometry;
                let filter = peer.answer_node_blocks(&q, &f.objects);
                assert!(exact <= e.reads.total && filter <= f.reads.total, "{q:?}");
                assert!(filter >= 1, "a query inside the scene reads the root's block at least");
                below += usize::from(filter < f.reads.node);
            }
        }
        assert!(below > 0, "some queries read node blocks that lead to no answer");
        // The whole scene's answer: every node block, once.
        let all: Vec<u32> = (0..scene.len() as u32).collect();
        let whole = peer.filter(&scene.aabb()).unwrap();
        assert_eq!(peer.answer_node_blocks(&scene.aabb(), &all), whole.reads.node);
    }
}
