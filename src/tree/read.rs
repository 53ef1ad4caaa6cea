//! The read transaction: a consistent snapshot of the committed tree, with
//! verified, counted block reads (format-spec/node.md, geometry.md).
//! `db` opens it and ends it (the reader's seat); the queries read through it.

use rustc_hash::FxHashMap;
use std::collections::VecDeque;
use std::sync::{Arc, Weak};

use super::codes;
use crate::bulk::BuildParams;
use crate::geom::Aabb;
use crate::scene::{Mesh, ObjectId};
use crate::store::format::frame::BlockType;
use crate::store::format::geometry;
use crate::store::format::group;
use crate::store::format::header::Commit;
use crate::store::format::keys;
use crate::store::format::meta::Meta;
use crate::store::format::node::{self, LeafView, Limits, NodeView, RecordRef};
use crate::store::{Block, BlockCache, Pager, ReadStats, StorageError};

/// What a file holds, from its meta block.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct TreeInfo {
    /// The commit the snapshot reads (its transaction id).
    pub txn: u64,
    /// Bytes per block.
    pub block_size: u32,
    /// M, the number of levels of detail; level M is the exact geometry.
    pub lod_levels: u8,
    /// File length in blocks at this commit.
    pub file_blocks: u32,
    /// Blocks of the file on its free list: reused by later writes, and
    /// given back by [`Database::compact`](crate::Database::compact).
    pub free_blocks: u32,
    /// Objects in the tree.
    pub objects: u32,
    /// Nodes, leaves included.
    pub nodes: u32,
    /// Leaves.
    pub leaves: u32,
    /// Deepest level (root 0).
    pub depth: u32,
    /// Node blocks of the tree.
    pub node_blocks: u32,
    /// Geometry blocks of the tree.
    pub geometry_blocks: u64,
    /// Bytes of node records over the node blocks' bytes.
    pub node_fill: f64,
    /// Bytes of geometry records over the geometry blocks' bytes.
    pub geometry_fill: f64,
    /// Triangles over all objects.
    pub triangles: u64,
    /// Vertices over all objects.
    pub vertices: u64,
    /// The scene's box, x0 y0 z0 x1 y1 z1, mm.
    pub scene_box: [f64; 6],
    /// Wall time of the bulk load's tree stage (building the hierarchy), seconds.
    pub build_seconds: f64,
    /// The parameters of the bulk load (the query extent is not stored: `Auto`);
    /// `None` when the stored codes do not decode.
    #[serde(skip)]
    pub params: Option<BuildParams>,
}

/// The committed state a reader sees.
#[derive(Debug)]
pub(crate) struct Snapshot {
    pub txn: u64,
    pub meta: Option<Meta>,
    pub block_count: u32,
    /// Blocks on the free list.
    pub free_blocks: u32,
}

impl Snapshot {
    /// The state commit `c` made, with its meta block.
    pub(crate) fn of(c: &Commit, meta: Option<Meta>) -> Snapshot {
        Snapshot { txn: c.txn, meta, block_count: c.block_count, free_blocks: c.free_blocks }
    }
}

/// What a read transaction reads through, and gives its seat back to: the
/// database that opened it (`db`, which this layer does not name).
pub(crate) trait Owner: Send + Sync {
    /// The file's pager.
    fn pager(&self) -> &Pager;
    /// The database's shared cache of verified blocks.
    fn cache(&self) -> &BlockCache;
    /// A reader of commit `txn` has ended: its blocks may be reused once no
    /// other reader holds them.
    fn release_reader(&self, txn: u64);
}

/// A snapshot of the committed state, unaffected by later commits.
pub struct ReadTransaction {
    owner: Arc<dyn Owner>,
    pub(crate) snapshot: Arc<Snapshot>,
}

impl Drop for ReadTransaction {
    fn drop(&mut self) {
        self.owner.release_reader(self.snapshot.txn);
    }
}

/// Where a node record is, with its box (the frame its children's and
/// objects' boxes are quantized in).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NodeRef {
    /// The node block holding the record.
    pub block: u32,
    /// The checksum the parent (or the meta block) holds for `block`.
    pub checksum: u32,
    /// Byte offset of the record in `block`.
    pub offset: u32,
    /// The record's box: the frame its children's and objects' boxes are quantized in.
    pub aabb: Aabb,
}

/// The blocks one operation reads, counted by the pager where they are
/// read. An operation holds the node blocks it reads to its end (a
/// traversal may enter a block again through another of the tree's pieces
/// packed in it; node blocks are a small share of a file). It holds a
/// geometry block while anything refers to it (a caller's `Arc`) and while
/// it is among the last [`Reads::HAND`] blocks the operation used: the
/// blocks neighbouring leaves share are read once, and memory stays
/// bounded whatever the geometry read. A geometry block needed again after
/// that is read and counted again, unless the shared cache serves it
/// (counted as a cache hit). With `keep_all` (a budgeted query, whose
/// costs count what it holds) every block is held to the end, so each is
/// read at most once.
pub struct Reads<'c> {
    /// The blocks read so far, by kind, and the cache hits.
    pub stats: ReadStats,
    // Block ids hash with Fx: SipHash's resistance buys nothing here and costs a warm query.
    /// Blocks read, found while anything still holds them.
    seen: FxHashMap<u32, Weak<Block>>,
    /// `seen`'s size at which its dead entries are dropped.
    prune_at: usize,
    /// The blocks used last, the latest at the back.
    hand: VecDeque<Arc<Block>>,
    /// Blocks held to the end: node blocks, those taken by `hold`, and all with `keep_all`.
    kept: Vec<Arc<Block>>,
    keep_all: bool,
    shared: Option<&'c BlockCache>,
}

impl<'c> Reads<'c> {
    /// Blocks an operation holds beyond those it keeps and those its work
    /// refers to: the geometry blocks neighbouring leaves share stay in hand.
    pub const HAND: usize = 16;

    /// Reads through `shared` (a pool kept across operations) when given.
    pub fn new(shared: Option<&'c BlockCache>) -> Reads<'c> {
        Reads {
            stats: ReadStats::default(),
            seen: FxHashMap::default(),
            prune_at: 64,
            hand: VecDeque::new(),
            kept: Vec::new(),
            keep_all: false,
            shared,
        }
    }

    /// True when block `id` is in hand (reading it costs nothing).
    pub fn holds(&self, id: u32) -> bool {
        self.seen.get(&id).is_some_and(|w| w.strong_count() > 0)
    }

    /// Blocks in hand.
    pub fn held(&self) -> usize {
        self.seen.values().filter(|w| w.strong_count() > 0).count()
    }

    /// Takes `block` in hand for the rest of the operation without reading it
    /// (a record already held).
    pub(crate) fn hold(&mut self, block: Arc<Block>) {
        self.seen.insert(block.id, Arc::downgrade(&block));
        self.kept.push(block);
    }

    /// With `all`, keeps every block read until the operation ends.
    pub(crate) fn keep_all(&mut self, all: bool) {
        self.keep_all = all;
    }

    /// Lends what this holds, with its counts and cache, to another
    /// operation ([`take_back`](Self::take_back) returns it).
    pub(crate) fn lend(&mut self) -> Reads<'c> {
        std::mem::replace(self, Reads::new(self.shared))
    }

    /// Takes back what `lent` read and holds.
    pub(crate) fn take_back(&mut self, lent: Reads<'_>) {
        let Reads { stats, seen, prune_at, hand, kept, keep_all, shared: _ } = lent;
        *self = Reads { stats, seen, prune_at, hand, kept, keep_all, shared: self.shared };
    }

    /// Block `id` if in hand, as the latest used.
    fn get(&mut self, id: u32) -> Option<Arc<Block>> {
        let b = self.seen.get(&id)?.upgrade()?;
        self.touch(&b);
        Some(b)
    }

    /// Takes a block just read (or found in the shared cache) in hand.
    fn put(&mut self, b: &Arc<Block>) {
        if self.seen.len() >= self.prune_at {
            self.seen.retain(|_, w| w.strong_count() > 0);
            self.prune_at = 2 * self.seen.len() + 64;
        }
        self.seen.insert(b.id, Arc::downgrade(b));
        if self.keep_all || b.bytes.get(4) == Some(&(BlockType::Node as u8)) {
            self.kept.push(b.clone());
        }
        self.touch(b);
    }

    /// Makes `b` the latest block used, dropping the oldest past `HAND`.
    fn touch(&mut self, b: &Arc<Block>) {
        if let Some(i) = self.hand.iter().position(|h| Arc::ptr_eq(h, b)) {
            self.hand.remove(i);
        } else if self.hand.len() == Self::HAND {
            self.hand.pop_front();
        }
        self.hand.push_back(b.clone());
    }
}

impl ReadTransaction {
    /// A reader of `snapshot`, which `owner` has seated.
    pub(crate) fn new(owner: Arc<dyn Owner>, snapshot: Arc<Snapshot>) -> ReadTransaction {
        ReadTransaction { owner, snapshot }
    }

    pub(crate) fn pager(&self) -> &Pager {
        self.owner.pager()
    }

    /// The database's shared cache of verified blocks.
    pub fn cache(&self) -> &BlockCache {
        self.owner.cache()
    }

    /// The snapshot's tree, or `None` for a database with no tree yet.
    pub fn info(&self) -> Option<TreeInfo> {
        let m = self.snapshot.meta.as_ref()?;
        let bs = f64::from(self.pager().block_size());
        let fill =
            |bytes: u64, blocks: u64| if blocks == 0 { 0.0 } else { bytes as f64 / (blocks as f64 * bs) };
        Some(TreeInfo {
            txn: self.snapshot.txn,
            block_size: self.pager().block_size(),
            lod_levels: self.pager().lod_levels(),
            file_blocks: self.snapshot.block_count,
            free_blocks: self.snapshot.free_blocks,
            objects: m.object_count,
            nodes: m.node_count,
            leaves: m.leaf_count,
            depth: m.depth,
            node_blocks: m.node_blocks,
            geometry_blocks: m.geometry_blocks,
            node_fill: fill(m.node_bytes, m.node_blocks.into()),
            geometry_fill: fill(m.geometry_bytes, m.geometry_blocks),
            triangles: m.triangle_count,
            vertices: m.vertex_count,
            scene_box: m.scene_box,
            build_seconds: m.build.build_seconds,
            params: codes::decode(&m.build),
        })
    }

    /// The commit this snapshot reads: the transaction id of the last
    /// commit before it began (0 for a file never committed to).
    pub fn txn(&self) -> u64 {
        self.snapshot.txn
    }

    /// The meta block's `object_ids`: every id below it used at most once
    /// (0 without a tree). A change commit only grows it; a bulk load
    /// numbers its objects from 0 again (format-spec/meta.md).
    pub(crate) fn object_ids(&self) -> u32 {
        self.snapshot.meta.as_ref().map_or(0, |m| m.object_ids)
    }

    /// The root record, or `None` for an empty database.
    pub fn root(&self) -> Option<NodeRef> {
        let m = self.snapshot.meta.as_ref()?;
        Some(NodeRef {
            block: m.root_block,
            checksum: m.root_checksum,
            offset: m.root_offset,
            aabb: Aabb::from_array(m.scene_box),
        })
    }

    /// Whether node ids are preorder numbers (format-spec/meta.md,
    /// `node_ids`): true after a bulk load, false once a change commit
    /// split or merged a leaf, until `compact` lays the tree out anew.
    pub(crate) fn ids_in_preorder(&self) -> bool {
        self.snapshot.meta.as_ref().is_none_or(|m| m.node_ids == 0)
    }

    fn check_in_snapshot(&self, block: u32) -> Result<(), StorageError> {
        if block == 0 || block >= self.snapshot.block_count {
            return Err(StorageError::corrupt(
                block,
                "reference",
                format!("not a block of the committed state ({} blocks)", self.snapshot.block_count),
            ));
        }
        Ok(())
    }

    /// Block `id` of type `t` carrying `checksum`: from `reads`' hand, the
    /// shared cache, or the device (verified, validated, counted).
    pub(crate) fn block(
        &self,
        id: u32,
        t: BlockType,
        checksum: u32,
        reads: &mut Reads,
    ) -> Result<Arc<Block>, StorageError> {
        if let Some(b) = reads.get(id) {
            if b.checksum != checksum || b.bytes.get(4) != Some(&(t as u8)) {
                return Err(StorageError::corrupt(id, "checksum", "two references disagree on this block"));
            }
            return Ok(b);
        }
        let hit =
            reads.shared.and_then(|c| c.get(id, checksum)).filter(|b| b.bytes.get(4) == Some(&(t as u8)));
        let b = match hit {
            Some(b) => {
                reads.stats.cache_hits += 1;
                b
            }
            None => {
                let b = self.load(id, t, checksum, &mut reads.stats)?;
                if let Some(c) = reads.shared {
                    c.put(b.clone());
                }
                b
            }
        };
        reads.put(&b);
        Ok(b)
    }

    /// Block `id` from the device, verified and validated, its read counted
    /// in `stats`.
    fn load(
        &self,
        id: u32,
        t: BlockType,
        checksum: u32,
        stats: &mut ReadStats,
    ) -> Result<Arc<Block>, StorageError> {
        self.check_in_snapshot(id)?;
        let (bytes, sum) = self.pager().read(id, t, Some(checksum), stats)?;
        let records = match t {
            BlockType::Node => node::validate_block(id, &bytes, &self.limits())?,
            BlockType::KeyLeaf => keys::validate(id, &bytes, true)?,
            BlockType::KeyBranch => keys::validate(id, &bytes, false)?,
            _ => Vec::new(),
        };
        let groups = match t {
            BlockType::Group => group::validate(id, &bytes, self.pager().lod_levels())?,
            _ => Vec::new(),
        };
        Ok(Arc::new(Block { id, checksum: sum, bytes, records, groups }))
    }

    /// Node block `id`, fetched ahead, looked into to find what to fetch
    /// next: not counted as a read (the traversal's read of it is) and not
    /// kept. `None` when it fails to verify; the read reports why.
    pub(crate) fn peek_node(&self, id: u32, checksum: u32) -> Option<Arc<Block>> {
        self.load(id, BlockType::Node, checksum, &mut ReadStats::default()).ok()
    }

    fn limits(&self) -> Limits {
        Limits {
            block_size: self.pager().block_size(),
            lod_levels: self.pager().lod_levels(),
            object_count: self.snapshot.meta.as_ref().map_or(0, |m| m.object_ids),
        }
    }

    /// The node block a child reference names (`from`: the block holding
    /// the reference, for a reference within it).
    pub(crate) fn node_block(
        &self,
        from: &Arc<Block>,
        at: RecordRef,
        reads: &mut Reads,
    ) -> Result<Arc<Block>, StorageError> {
        if at.block == 0 {
            Ok(from.clone())
        } else {
            self.block(at.block, BlockType::Node, at.checksum, reads)
        }
    }

    /// Object `i` of `leaf` (in block `block`): its id, and the geometry
    /// blocks (id, checksum) its record lies in, in order, with the payload
    /// bytes it takes in each.
    fn object_span(&self, block: u32, leaf: &LeafView, i: usize) -> Result<(u32, ObjectSpan), StorageError> {
        let bs = self.pager().block_size();
        let o = leaf.object(i).ok_or_else(|| StorageError::corrupt(block, "objects", "no such object"))?;
        let (first, sums) = leaf.geometry();
        let sums: Vec<u32> = sums.collect();
        let p = geometry::payload(bs);
        let (start, end) = o.span;
        let mut out = Vec::new();
        for b in geometry::blocks_of(start, end, bs) {
            let sum = *sums.get(b as usize).ok_or_else(|| {
                StorageError::corrupt(block, "position", "an object's record lies past its leaf's span")
            })?;
            let id = u32::try_from(u64::from(first) + b)
                .map_err(|_| StorageError::corrupt(block, "first_block", "overflows"))?;
            let from = if b == start / p { start % p } else { 0 };
            let to = if b == (end - 1) / p { (end - 1) % p + 1 } else { p };
            out.push((id, sum, from as usize..to as usize));
        }
        Ok((o.object_id, out))
    }

    /// The geometry blocks (id, checksum) that object `i` of `leaf` (in
    /// block `block`) lies in.
    pub(crate) fn object_blocks(
        &self,
        block: u32,
        leaf: &LeafView,
        i: usize,
    ) -> Result<Vec<(u32, u32)>, StorageError> {
        Ok(self.object_span(block, leaf, i)?.1.into_iter().map(|(id, sum, _)| (id, sum)).collect())
    }

    /// The exact object `i` of `leaf` (in block `block`): its geometry
    /// blocks are read through `reads`.
    pub(crate) fn read_object(
        &self,
        block: u32,
        leaf: &LeafView,
        i: usize,
        reads: &mut Reads,
    ) -> Result<(ObjectId, Mesh), StorageError> {
        let (object_id, span) = self.object_span(block, leaf, i)?;
        let first = leaf.geometry().0;
        let mut bytes = Vec::new();
        for (id, sum, within) in span {
            let g = self.block(id, BlockType::Geometry, sum, reads)?;
            let at = crate::store::format::frame::FRAME_LEN;
            bytes.extend_from_slice(&g.bytes[at + within.start..at + within.end]);
        }
        let (id, mesh) = geometry::decode_object(first, &bytes)?;
        if id.0 != object_id {
            return Err(StorageError::corrupt(
                first,
                "object_id",
                format!("the leaf says {object_id}, the record {id}"),
            ));
        }
        Ok((id, mesh))
    }

    /// True when the device fetches over a network, where reading the blocks
    /// a query will need together saves round trips.
    pub(crate) fn fetches_ahead(&self) -> bool {
        self.pager().device().transfer_counts().is_some()
    }

    /// Of `wanted` (id, checksum), in their order, each once: the blocks
    /// neither in `reads`' hand nor in the shared cache (whose order of
    /// eviction this leaves as it was), nor outside the snapshot.
    pub(crate) fn unread(&self, wanted: &[(u32, u32)], reads: &Reads) -> Vec<u32> {
        let mut seen = rustc_hash::FxHashSet::default();
        wanted
            .iter()
            .filter(|&&(id, sum)| {
                self.check_in_snapshot(id).is_ok()
                    && !reads.holds(id)
                    && reads.shared.is_none_or(|c| !c.holds(id, sum))
                    && seen.insert(id)
            })
            .map(|&(id, _)| id)
            .collect()
    }

    /// Has the device fetch blocks `ids` together, to be read next; true
    /// when it holds them all now (looking into them costs no request).
    pub(crate) fn fetch_ahead(&self, ids: &[u32]) -> bool {
        self.pager().fetch_ahead(ids)
    }
}

/// The geometry blocks an object's record lies in: (id, checksum, the
/// payload bytes it takes there).
type ObjectSpan = Vec<(u32, u32, std::ops::Range<usize>)>;

/// The record at `offset` of a validated node block.
pub(crate) fn view(block: &Block, offset: u32) -> Result<NodeView<'_>, StorageError> {
    if block.records.binary_search(&offset).is_err() {
        return Err(StorageError::corrupt(
            block.id,
            "child_offset",
            format!("{offset} is not a record of the block"),
        ));
    }
    NodeView::at(&block.bytes, offset).map_err(|d| StorageError::corrupt(block.id, "record", d))
}
