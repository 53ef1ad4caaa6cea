//! Clash detection: every pair of scene objects that touch (share a point:
//! a face, edge or vertex in common counts) or come within a clearance d.
//! The tree is walked once to list the objects with their boxes; then each
//! object, as the probe, is run through the one traversal against the
//! objects of higher id: its box grown by d at level 1, its voxel-level
//! bound tests at 1 < k < M, its exact surface with clearance d at M. A pair
//! is tested once, lower id as the probe: the contact rule is symmetric
//! (`geom::contact`), so at M the pairs are exactly those that `collide` of
//! either object reports. Every block goes through one pool for the whole
//! run (the caller's cache, or one of `DEFAULT_CACHE_BLOCKS` blocks): while
//! the blocks the run touches fit it, the reads are at most the file's
//! blocks (reported beside them); past that, memory stays at the pool's
//! size and a block read again is counted again. A file with no tree (new,
//! or emptied by removals) has no pairs, as a region query over it has no
//! objects.

use std::sync::Arc;
use std::time::Instant;

use serde::Serialize;

use super::QueryError;
use super::select::{Everything, Region, Triangles, reach};
use super::{QueryOptions, Seen, TraverseStats, Visitor, levels, walk};
use crate::geom::{Aabb, Pose};
use crate::scene::ObjectId;
use crate::store::format::geometry;
use crate::store::format::node::NodeView;
use crate::store::format::quant::QuantBox;
use crate::store::{Block, BlockCache, StorageError};
use crate::tree::{ReadTransaction, Reads, view};

/// A clash run's settings.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ClashOptions {
    /// The level k (1 ..= M); `None` is M, the exact pairs.
    pub lod: Option<u8>,
    /// d, mm: objects within d clash (0: touching or intersecting).
    pub clearance: f64,
}

/// Every clashing pair, with the run's reads.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ClashAnswer {
    /// Sorted pairs (a, b), a < b: exact at M (the unordered pairs of
    /// `collide` over every object), a superset below.
    pub pairs: Vec<(ObjectId, ObjectId)>,
    /// The level k the run answered at.
    pub level: u8,
    /// Blocks in the file, to set the reads against.
    pub file_blocks: u32,
    /// What the traversal did.
    pub stats: TraverseStats,
}

/// An object as listed: its id, box, and where its record is.
struct Listed {
    id: ObjectId,
    aabb: Aabb,
    leaf: (Arc<Block>, u32, usize),
}

/// Lists every object with its leaf.
#[derive(Default)]
struct List {
    objects: Vec<Listed>,
}

impl Visitor for List {
    fn node(&mut self, block: &Arc<Block>, offset: u32, frame: &Aabb) -> Result<(), StorageError> {
        let NodeView::Leaf(leaf) = view(block, offset)? else { return Ok(()) };
        let held = block.clone();
        for i in 0..leaf.len() {
            let Some(o) = leaf.object(i) else { continue };
            let aabb = QuantBox::decode(frame, o.qbox).map_or(*frame, |q| q.outer);
            self.objects.push(Listed { id: ObjectId(o.object_id), aabb, leaf: (held.clone(), offset, i) });
        }
        Ok(())
    }

    fn object(&mut self, _: &Seen) -> Result<(), StorageError> {
        Ok(())
    }
}

fn add(total: &mut TraverseStats, s: &TraverseStats) {
    total.reads += s.reads;
    total.nodes_visited += s.nodes_visited;
    total.leaves_visited += s.leaves_visited;
    total.pruned += s.pruned;
    for (t, x) in [(&mut total.confirmed, &s.confirmed), (&mut total.rejected, &s.rejected)] {
        t.resize(t.len().max(x.len()), 0);
        for (a, b) in t.iter_mut().zip(x) {
            *a += b;
        }
    }
    total.geometry_tests += s.geometry_tests;
    total.triangles_tested += s.triangles_tested;
}

/// Every pair of objects of `txn`'s tree within `opts.clearance` (touching
/// at 0), at level k. Reads go through `cache`, or a pool of the run's own
/// of `DEFAULT_CACHE_BLOCKS` blocks when `None`.
pub fn clash(
    txn: &ReadTransaction,
    opts: &ClashOptions,
    cache: Option<&BlockCache>,
) -> Result<ClashAnswer, QueryError> {
    let started = Instant::now();
    let d = opts.clearance;
    if !(d.is_finite() && d >= 0.0) {
        return Err(QueryError::Clearance(d));
    }
    let (k, m) = levels(txn, opts.lod)?;
    let (Some(info), Some(root)) = (txn.info(), txn.root()) else {
        let file_blocks = u32::try_from(txn.pager().block_count()?).unwrap_or(u32::MAX);
        return Ok(ClashAnswer { pairs: Vec::new(), level: k, file_blocks, stats: TraverseStats::default() });
    };
    let own = BlockCache::new(crate::store::cache::DEFAULT_CACHE_BLOCKS);
    let pool = cache.unwrap_or(&own);
    let mut total = TraverseStats::default();
    let mut list = List::default();
    let boxes = QueryOptions { lod: Some(1), budget: None, ..Default::default() };
    // One hand for the run: the node blocks are read once, whatever the pool drops.
    let mut reads = Reads::new(Some(pool));
    let listing = walk(txn, root, &Everything, &boxes, &mut reads, &mut list)?;
    add(&mut total, &listing.stats);
    list.objects.sort_by_key(|o| o.id);
    let mut pairs = Vec::new();
    // An object larger than a block is listed once per part: one probe each.
    for group in list.objects.chunk_by(|x, y| x.id == y.id) {
        let id = group[0].id;
        let aabb = group.iter().fold(Aabb::EMPTY, |b, p| b.union(&p.aabb));
        let near = Region::Box(reach(&aabb, d));
        let at = QueryOptions { lod: Some(if k == m { 1 } else { k }), ..Default::default() };
        let found = walk(txn, root, &near, &at, &mut reads, &mut ())?;
        add(&mut total, &found.stats);
        let mut hits: Vec<ObjectId> = found.objects.into_iter().filter(|&b| b > id).collect();
        if k == m && !hits.is_empty() {
            let before = reads.stats;
            let mut parts = Vec::with_capacity(group.len());
            for p in group {
                let (block, offset, index) = &p.leaf;
                let NodeView::Leaf(leaf) = view(block, *offset)? else { continue };
                parts.push(txn.read_object(block.id, &leaf, *index, &mut reads)?.1);
            }
            total.reads += reads.stats - before;
            let Some(mesh) = geometry::join(&parts) else { continue };
            let probe = Triangles::posed(&mesh, &Pose::default(), d)?;
            let exact = walk(txn, root, &probe, &QueryOptions::default(), &mut reads, &mut ())?;
            add(&mut total, &exact.stats);
            hits = exact.objects.into_iter().filter(|&b| b > id).collect();
        }
        pairs.extend(hits.into_iter().map(|b| (id, b)));
    }
    pairs.sort_unstable();
    total.seconds = started.elapsed().as_secs_f64();
    Ok(ClashAnswer { pairs, level: k, file_blocks: info.file_blocks, stats: total })
}
