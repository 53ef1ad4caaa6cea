//! Lays a built tree out in blocks (format-spec/node.md, geometry.md):
//! geometry records packed into geometry blocks in leaf order, node records
//! with quantized boxes packed into node blocks as connected pieces, and
//! each child entry's counts of the blocks below it. The packing is chosen
//! among a few piece sizes by the node reads it gives the read model's
//! sample queries ([`QueryMix`]).

use std::borrow::Cow;
use std::collections::HashMap;

use rayon::prelude::*;

use super::source::ObjectSource;

use crate::bulk::{Hierarchy, LoadProgress, Order, QueryMix, Split, Stage, StageMeter};
use crate::geom::Aabb;
use crate::lod::LeafEntry;
use crate::lod::{GroupRule, StoredBounds, Voxels, leaf_group, lift_group};
use crate::scene::{Key, Mesh, ObjectId};
use crate::store::format::frame::{BlockType, FRAME_LEN};
use crate::store::format::geometry::{self, Placement};
use crate::store::format::group::{self, GroupEntry};
use crate::store::format::keys::TreePath;
use crate::store::format::node::{
    self, BoundEntry, ChildEntry, ObjectEntry, RecordDraft, RecordRef, SplitInfo, leaf_len,
};
use crate::store::format::quant::{QuantBox, quantize};
use crate::store::layout::{self, Packing};
use crate::store::{Pager, StorageError};

/// Sample queries per scale of the read model.
pub(crate) const SAMPLES_PER_SCALE: usize = 256;

/// The least average fill of node blocks a packing must reach, when one can.
const MIN_FILL: f64 = 0.8;

/// Decoded bounds the read model keeps per job: the samples of a large
/// tree may leave open more entries than memory should hold at once.
const DECODED_MAX: usize = 4096;

/// Piece sizes tried, as shares of a block (`store/layout.rs`).
const PIECE_SHARES: [f64; 5] = [0.25, 0.35, 0.5, 0.7, 1.0];

/// What the layout wrote, for the meta block.
#[derive(Debug, Clone, Default)]
pub(crate) struct Written {
    pub root: (u32, u32, u32),
    pub node_blocks: u32,
    pub node_bytes: u64,
    pub geometry_blocks: u64,
    pub geometry_bytes: u64,
    /// Vertices as stored (a vertex two parts of an object share counts twice).
    pub vertices: u64,
    /// Per object (by id): the path from the root to its leaf.
    pub paths: Vec<TreePath>,
    /// The objects stored in parts, by id, with the union of their parts'
    /// boxes (any other object's box as the tree holds it is its source's).
    pub split_boxes: Vec<(ObjectId, Aabb)>,
}

impl Written {
    /// Object `id`'s box as the tree holds it.
    pub fn aabb(&self, objects: &dyn ObjectSource, id: ObjectId) -> Aabb {
        match self.split_boxes.binary_search_by_key(&id, |&(o, _)| o) {
            Ok(at) => self.split_boxes[at].1,
            Err(_) => objects.aabb(id),
        }
    }
}

/// Everything about a tree's layout that does not depend on its bounds:
/// each node's box as stored, where each object's record goes, and what a
/// layout without bounds costs the read model's queries (the levels of
/// detail's cost is judged on it).
#[derive(Debug, Clone)]
pub(crate) struct Plan {
    /// Per node: its box as its parent's entry stores it (the root's exact).
    pub frames: Vec<Aabb>,
    child_q: Vec<[u16; 6]>,
    /// Per leaf: its entries, each an object or a part of one.
    entries: Vec<Vec<Entry>>,
    /// Per node: bytes of its leaf record's keys area.
    key_bytes: Vec<usize>,
    payload: u64,
    stream_end: u64,
    samples: Vec<Aabb>,
    /// Per node: the share of the model's queries that read the node block
    /// holding it, when the tree is laid out without bounds.
    pub read_share: Vec<f64>,
}

/// A leaf's entry: an object, or a part of one too large for a geometry
/// block (format-spec/geometry.md, "Parts"), and where its record goes.
/// A whole object's box is its source's: only the quantized box is kept
/// per entry (40 bytes, not 80: the plan lives through every stage).
#[derive(Debug, Clone)]
struct Entry {
    id: ObjectId,
    /// The entry's box quantized in its leaf's frame, as the leaf stores it.
    qbox: [u16; 6],
    /// The part's mesh and box; `None` for a whole object (its source's).
    part: Option<Box<(Mesh, Aabb)>>,
    /// Stream position and record length.
    pos: u64,
    len: u64,
}

impl Entry {
    fn mesh<'a>(&'a self, objects: &'a dyn ObjectSource) -> Result<Cow<'a, Mesh>, StorageError> {
        match &self.part {
            Some(part) => Ok(Cow::Borrowed(&part.0)),
            None => objects.mesh(self.id),
        }
    }
}

impl Plan {
    /// The plan of `tree` over `objects` in blocks of `block_size` bytes.
    /// Only the meshes of objects too large for one block are read here
    /// (their parts are kept); the others' records are placed by length.
    pub fn new(
        objects: &dyn ObjectSource,
        tree: &Hierarchy,
        block_size: u32,
        mix: &QueryMix,
    ) -> Result<Plan, StorageError> {
        let nodes = &tree.nodes;
        let n = nodes.len();
        let invalid = StorageError::Invalid;
        let mut placement = Placement::new(block_size);
        let payload = geometry::payload(block_size);
        let mut frames = vec![Aabb::EMPTY; n];
        frames[0] = nodes[0].aabb;
        let mut child_q = vec![[0u16; 6]; n];
        for i in 0..n {
            for c in nodes[i].children().into_iter().flatten() {
                let q = quantize(&frames[i], &nodes[c.index()].aabb);
                let qb = QuantBox::decode(&frames[i], q)
                    .ok_or_else(|| invalid("a box quantized backwards".into()))?;
                if !qb.outer.contains(&nodes[c.index()].aabb) {
                    return Err(invalid(format!("node {} does not lie in its parent's box", c.0)));
                }
                child_q[c.index()] = q;
                frames[c.index()] = qb.outer;
            }
        }
        let mut entries: Vec<Vec<Entry>> = vec![Vec::new(); n];
        for (i, node) in nodes.iter().enumerate() {
            let frame = &frames[i];
            if node.objects().is_some() {
                placement.start_block();
            }
            for &id in node.objects().unwrap_or_default() {
                if id.index() >= objects.len() {
                    return Err(invalid(format!("no object {id}")));
                }
                let len = objects.record_len(id);
                if len <= payload {
                    let pos = placement.place(len);
                    let qbox = quantize(frame, &objects.aabb(id));
                    entries[i].push(Entry { id, qbox, part: None, pos, len });
                    continue;
                }
                // A room of less than 1/16 of a block is not worth a part's header.
                let room = placement.room();
                let mesh = objects.mesh(id)?;
                let parts = geometry::parts(&mesh, if room < payload / 16 { payload } else { room }, payload);
                let whole = parts.len() == 1;
                for part in parts {
                    let len = geometry::record_len(&part);
                    let pos = placement.place(len);
                    let aabb = if whole { objects.aabb(id) } else { part.aabb() };
                    let qbox = quantize(frame, &aabb);
                    entries[i].push(Entry {
                        id,
                        qbox,
                        part: (!whole).then(|| Box::new((part, aabb))),
                        pos,
                        len,
                    });
                }
            }
        }
        let key_bytes = entries
            .iter()
            .map(|es| {
                let keys: Vec<Key> = object_ids(es).map(|id| objects.key(id)).collect();
                node::keys_len(&keys)
            })
            .collect();
        let mut plan = Plan {
            frames,
            child_q,
            entries,
            key_bytes,
            payload,
            stream_end: placement.end(),
            samples: mix.sample_centred(&nodes[0].aabb, SAMPLES_PER_SCALE),
            read_share: Vec::new(),
        };
        let sizes = plan.sizes(tree, |_| 0);
        let capacity = node::capacity(block_size);
        if let Some(i) = (0..n).find(|&i| sizes[i] > capacity) {
            return Err(invalid(format!(
                "node {i}'s record takes {} bytes and a node block holds {capacity}: use smaller leaves or larger blocks",
                sizes[i]
            )));
        }
        let (packing, reads) = choose_packing(tree, &sizes, capacity, &plan.samples);
        let reads = reads.unwrap_or_else(|| BlockWalk::new(tree, &packing).reads_per_block(&plan.samples));
        let q = plan.samples.len().max(1) as f64;
        plan.read_share = packing.place.iter().map(|p| f64::from(reads[p.0 as usize]) / q).collect();
        Ok(plan)
    }

    /// The global geometry blocks (from the first of the stream) holding
    /// entry `j` of leaf `leaf`.
    fn entry_blocks(&self, leaf: usize, j: usize) -> std::ops::RangeInclusive<u64> {
        let (pos, len) = self.entries[leaf].get(j).map_or((0, 1), |e| (e.pos, e.len));
        pos / self.payload..=(pos + len.max(1) - 1) / self.payload
    }

    /// Every leaf's entries as the levels of detail judge them: the object
    /// (or part) with its box and its geometry blocks.
    pub fn leaf_entries(&self) -> Vec<Vec<LeafEntry>> {
        self.entries
            .iter()
            .enumerate()
            .map(|(i, es)| {
                es.iter()
                    .enumerate()
                    .map(|(j, e)| LeafEntry {
                        id: e.id,
                        qbox: e.qbox,
                        block: *self.entry_blocks(i, j).start(),
                    })
                    .collect()
            })
            .collect()
    }

    /// The mesh of entry `j` of leaf `leaf`.
    pub fn entry_mesh<'a>(
        &'a self,
        objects: &'a dyn ObjectSource,
        leaf: usize,
        j: usize,
    ) -> Result<Cow<'a, Mesh>, StorageError> {
        let e = self.entries.get(leaf).and_then(|es| es.get(j));
        e.ok_or_else(|| StorageError::Invalid(format!("no entry {j} in leaf {leaf}")))?.mesh(objects)
    }

    /// First and last global geometry block of leaf `i`.
    fn leaf_span(&self, i: usize) -> (u64, u64) {
        let first = self.entries[i].first().map_or(0, |e| e.pos) / self.payload;
        let end = self.entries[i].last().map_or(1, |e| e.pos + e.len.max(1));
        (first, (end - 1) / self.payload)
    }

    /// Record bytes of every node with `bounds`.
    /// Record bytes of every node whose bounds take `bound_bytes(node)`.
    fn sizes(&self, tree: &Hierarchy, bound_bytes: impl Fn(usize) -> usize) -> Vec<usize> {
        (0..tree.nodes.len())
            .map(|i| {
                let extra = bound_bytes(i);
                match tree.nodes[i].objects() {
                    Some(_) => {
                        let (a, b) = self.leaf_span(i);
                        leaf_len(self.entries[i].len(), (b - a + 1) as usize, extra, self.key_bytes[i])
                    }
                    None => node::INTERNAL_LEN + extra,
                }
            })
            .collect()
    }
}

impl Plan {
    /// The model's expected block reads per query for an exact answer, per
    /// scale of the mix, when the tree is laid out with those of `stored`'s
    /// bounds worth at least `min_value` (none at infinity): the node blocks
    /// the chosen packing makes it read, and the geometry blocks of the
    /// objects no box, face or bound decides (as the traversal decides them).
    pub fn expected_reads(
        &self,
        tree: &Hierarchy,
        stored: &StoredBounds,
        min_value: f64,
        block_size: u32,
    ) -> Vec<f64> {
        let sizes = self.sizes(tree, |i| stored.bytes_at(i, min_value));
        let capacity = node::capacity(block_size);
        let scales = self.samples.len().div_ceil(SAMPLES_PER_SCALE);
        if sizes.iter().any(|&s| s > capacity) {
            // Bounds that swell a record past a block cannot be written: never worth keeping.
            return vec![f64::INFINITY; scales];
        }
        let (packing, _) = choose_packing(tree, &sizes, capacity, &self.samples);
        let walk = BlockWalk::new(tree, &packing);
        // Per sample: its node block reads plus its distinct geometry blocks
        // (integer sums, so the same on any number of threads).
        // Each entry's bound is decoded once per job, not once per sample it
        // leaves open (up to DECODED_MAX kept at a time).
        let per_sample: Vec<usize> = self
            .samples
            .par_iter()
            .map_init(Scratch::default, |s: &mut Scratch, q| {
                let Scratch { decoded, blocks, stack, pending, walk_stack, walk_blocks } = s;
                blocks.clear();
                stack.clear();
                if self.frames[0].intersects(q) && !q.contains(&self.frames[0]) {
                    stack.push(0usize);
                }
                while let Some(i) = stack.pop() {
                    for c in tree.nodes[i].children().into_iter().flatten() {
                        let f = &self.frames[c.index()];
                        // A child the query holds is answered without geometry.
                        if f.intersects(q) && !q.contains(f) {
                            stack.push(c.index());
                        }
                    }
                    // An object's entries are consecutive: one confirmed part
                    // answers it, else every part not ruled out is read.
                    let mut j = 0;
                    let es = &self.entries[i];
                    while j < es.len() {
                        let id = es[j].id;
                        let end = j + es[j..].iter().take_while(|e| e.id == id).count();
                        pending.clear();
                        let mut confirmed = false;
                        for (e, entry) in es.iter().enumerate().take(end).skip(j) {
                            let Some(b) = QuantBox::decode(&self.frames[i], entry.qbox) else { continue };
                            if !b.outer.intersects(q) {
                                continue;
                            }
                            if b.face_slabs().iter().any(|f| q.contains(f)) {
                                confirmed = true;
                                break;
                            }
                            // Decoded here, for the few entries a sample leaves open.
                            if decoded.len() >= DECODED_MAX && !decoded.contains_key(&(i, e)) {
                                decoded.clear();
                            }
                            let bound = decoded
                                .entry((i, e))
                                .or_insert_with(|| stored.finest(i, e, min_value, &b.outer));
                            if bound.as_ref().is_some_and(|v| v.holds_a_cell_in(q)) {
                                confirmed = true;
                                break;
                            }
                            if bound.as_ref().is_none_or(|v| v.may_meet(q)) {
                                pending.push(e);
                            }
                        }
                        if !confirmed {
                            for &e in pending.iter() {
                                blocks.extend(self.entry_blocks(i, e));
                            }
                        }
                        j = end;
                    }
                }
                blocks.sort_unstable();
                blocks.dedup();
                walk.blocks_read(q, walk_stack, walk_blocks) + blocks.len()
            })
            .collect();
        let mut reads = vec![0usize; scales];
        for (qi, r) in per_sample.into_iter().enumerate() {
            reads[qi / SAMPLES_PER_SCALE] += r;
        }
        reads.iter().map(|&r| r as f64 / SAMPLES_PER_SCALE as f64).collect()
    }
}

/// What one rayon job of [`Plan::expected_reads`] reuses from sample to
/// sample: the bounds it decoded, and buffers (allocations were a tenth
/// of a small tree's commit).
#[derive(Default)]
struct Scratch {
    decoded: HashMap<(usize, usize), Option<Voxels>>,
    blocks: Vec<u64>,
    stack: Vec<usize>,
    pending: Vec<usize>,
    walk_stack: Vec<usize>,
    walk_blocks: Vec<usize>,
}

/// The node blocks of a packing that queries read: a query reads the block
/// of every node whose box it meets (as the traversal does, which tests a
/// child's box before reading its block).
struct BlockWalk<'a> {
    tree: &'a Hierarchy,
    p: &'a Packing,
    /// Per node: true when its whole subtree lies in its block, so a query
    /// that reads the node reads no other block below it.
    closed: Vec<bool>,
}

impl<'a> BlockWalk<'a> {
    fn new(tree: &'a Hierarchy, p: &'a Packing) -> BlockWalk<'a> {
        let mut closed = vec![false; tree.nodes.len()];
        // Preorder: children come after their parent.
        for i in (0..tree.nodes.len()).rev() {
            let b = p.place[i].0;
            closed[i] = tree.nodes[i]
                .children()
                .is_none_or(|cs| cs.iter().all(|c| closed[c.index()] && p.place[c.index()].0 == b));
        }
        BlockWalk { tree, p, closed }
    }

    /// Calls `read` with the block of every node `q` reads, except below a
    /// closed node (its block already named).
    fn walk(&self, q: &Aabb, stack: &mut Vec<usize>, mut read: impl FnMut(usize)) {
        stack.clear();
        if self.tree.nodes.first().is_some_and(|r| r.aabb.intersects(q)) {
            stack.push(0);
        }
        while let Some(i) = stack.pop() {
            read(self.p.place[i].0 as usize);
            if self.closed[i] {
                continue;
            }
            for c in self.tree.nodes[i].children().into_iter().flatten() {
                if self.tree.nodes[c.index()].aabb.intersects(q) {
                    stack.push(c.index());
                }
            }
        }
    }

    /// Per block, how many of `queries` read it.
    fn reads_per_block(&self, queries: &[Aabb]) -> Vec<u32> {
        let mut reads = vec![0u32; self.p.blocks.len()];
        let mut seen = vec![u32::MAX; self.p.blocks.len()];
        let mut stack = Vec::new();
        for (qi, q) in queries.iter().enumerate() {
            self.walk(q, &mut stack, |b| {
                if seen[b] != qi as u32 {
                    seen[b] = qi as u32;
                    reads[b] += 1;
                }
            });
        }
        reads
    }

    /// The distinct blocks one query `q` reads (`stack` and `blocks`: scratch).
    fn blocks_read(&self, q: &Aabb, stack: &mut Vec<usize>, blocks: &mut Vec<usize>) -> usize {
        blocks.clear();
        self.walk(q, stack, |b| blocks.push(b));
        blocks.sort_unstable();
        blocks.dedup();
        blocks.len()
    }
}

/// The packing of `tree`'s records (`sizes` bytes each), among the piece
/// sizes tried, whose blocks the model's `samples` read least (then the fullest); with each block's reads,
/// unless every piece size packs alike (nothing to choose: not measured).
pub(crate) fn choose_packing(
    tree: &Hierarchy,
    sizes: &[usize],
    capacity: usize,
    samples: &[Aabb],
) -> (Packing, Option<Vec<u32>>) {
    let children = |i: usize| tree.nodes[i].children().map(|c| c.map(|x| x.index()));
    let total: usize = sizes.iter().sum();
    let packings: Vec<Packing> = PIECE_SHARES
        .par_iter()
        .map(|share| layout::pack(sizes, children, capacity, (capacity as f64 * share) as usize))
        .collect();
    // Piece sizes often pack a small tree alike: each distinct packing is measured once.
    let mut distinct: Vec<Packing> = Vec::with_capacity(packings.len());
    for p in packings {
        if !distinct.contains(&p) {
            distinct.push(p);
        }
    }
    if distinct.len() == 1 {
        return (distinct.remove(0), None);
    }
    let tried: Vec<(Packing, Vec<u32>)> = distinct
        .into_par_iter()
        .map(|p| {
            let reads = BlockWalk::new(tree, &p).reads_per_block(samples);
            (p, reads)
        })
        .collect();
    // Blocks at least MIN_FILL full on average when some packing makes
    // them so (fewer blocks, a smaller file), then the fewest reads.
    let full = |p: &Packing| total as f64 >= MIN_FILL * (p.blocks.len() * capacity) as f64;
    let any_full = tried.iter().any(|(p, _)| full(p));
    let chosen = tried
        .into_iter()
        .filter(|(p, _)| full(p) || !any_full)
        .min_by_key(|(p, reads)| (reads.iter().map(|&r| u64::from(r)).sum::<u64>(), p.blocks.len()));
    match chosen {
        Some((p, reads)) => (p, Some(reads)),
        None => (layout::pack(sizes, children, capacity, capacity), None),
    }
}

/// The node blocks the read model's `samples` read per query on `packing`
/// of `tree`, averaged per scale of the mix (samples in scale order,
/// [`SAMPLES_PER_SCALE`] each).
pub(crate) fn node_reads_per_scale(tree: &Hierarchy, packing: &Packing, samples: &[Aabb]) -> Vec<f64> {
    let walk = BlockWalk::new(tree, packing);
    let (mut stack, mut blocks) = (Vec::new(), Vec::new());
    samples
        .chunks(SAMPLES_PER_SCALE)
        .map(|scale| {
            let reads: usize = scale.iter().map(|q| walk.blocks_read(q, &mut stack, &mut blocks)).sum();
            reads as f64 / scale.len() as f64
        })
        .collect()
}

/// Where a write transaction's new blocks go: its pager and id, and its
/// allocator (count -> first block).
pub(crate) struct Sink<'a> {
    pub pager: &'a Pager,
    pub txn: u64,
    pub allocate: &'a mut dyn FnMut(u32) -> Result<u32, StorageError>,
}

/// Writes `tree` over `objects` as `plan` lays it out, with the inline
/// `bounds` of each node (internal: its children's group bounds; leaf: its
/// objects'), into `sink`.
pub(crate) fn write(
    Sink { pager, txn, allocate }: Sink,
    objects: &dyn ObjectSource,
    tree: &Hierarchy,
    plan: &Plan,
    bounds: &[Vec<BoundEntry>],
    groups: Option<&GroupRule>,
    progress: &(dyn Fn(LoadProgress) + Sync),
) -> Result<Written, StorageError> {
    let bs = pager.block_size();
    let nodes = &tree.nodes;
    let n = nodes.len();
    let invalid = StorageError::Invalid;
    let p = plan.payload;
    let geometry_blocks = plan.stream_end.div_ceil(p);
    let count = u32::try_from(geometry_blocks).map_err(|_| StorageError::FileTooLarge)?;
    let first_geometry = allocate(count)?;
    let mut sums = Vec::with_capacity(count as usize);
    let mut block = vec![0u8; bs as usize];
    let mut filled = 0u64; // stream bytes of blocks already written
    let mut record = Vec::new();
    let mut geometry_bytes = 0u64;
    let mut vertices = 0u64;
    let meter = StageMeter::new(progress, Stage::Geometry, geometry_blocks);
    let flush = |block: &mut Vec<u8>, index: u64, sums: &mut Vec<u32>| -> Result<(), StorageError> {
        let id = first_geometry + index as u32;
        sums.push(pager.write(id, block, BlockType::Geometry, txn)?);
        block.fill(0);
        meter.add(1);
        Ok(())
    };
    for entries in &plan.entries {
        for e in entries {
            record.clear();
            vertices += match &e.part {
                Some(part) => {
                    geometry::encode_object(e.id, &part.0, &mut record);
                    part.0.vertex_count() as u64
                }
                None => objects.encode_record(e.id, &mut record)?,
            };
            geometry_bytes += record.len() as u64;
            let pos = e.pos;
            let mut at = pos;
            let mut rest = &record[..];
            while !rest.is_empty() {
                while at >= filled + p {
                    flush(&mut block, filled / p, &mut sums)?;
                    filled += p;
                }
                let off = (at - filled) as usize;
                let take = rest.len().min(p as usize - off);
                block[FRAME_LEN + off..FRAME_LEN + off + take].copy_from_slice(&rest[..take]);
                rest = &rest[take..];
                at += take as u64;
            }
        }
    }
    while filled < plan.stream_end {
        flush(&mut block, filled / p, &mut sums)?;
        filled += p;
    }
    drop(meter);
    let child_q = &plan.child_q;
    let leaf_span = |i: usize| plan.leaf_span(i);
    let sizes = plan.sizes(tree, |i| node::bounds_len(&bounds[i]));
    let capacity = node::capacity(bs);
    if let Some(i) = (0..n).find(|&i| sizes[i] > capacity) {
        return Err(invalid(format!(
            "node {i}'s record with its bounds takes {} bytes and a node block holds {capacity}",
            sizes[i]
        )));
    }
    let (packing, _) = choose_packing(tree, &sizes, capacity, &plan.samples);
    let block_count = u32::try_from(packing.blocks.len()).map_err(|_| StorageError::FileTooLarge)?;
    let first_node = allocate(block_count)?;
    // Offsets of every record in its block.
    let mut offset = vec![0u32; n];
    for members in &packing.blocks {
        let mut at = node::RECORDS_START as u32;
        for &m in members {
            offset[m as usize] = at;
            at += sizes[m as usize] as u32;
        }
    }
    // The group bounds, each node block's in a group block of its own.
    let group_entries = match groups {
        Some(rule) => group_entries(rule, objects, tree, plan, &packing, &offset, bs)?,
        None => vec![Vec::new(); packing.blocks.len()],
    };
    let group_count = group_entries.iter().filter(|e| !e.is_empty()).count();
    let first_group = if group_count > 0 { allocate(group_count as u32)? } else { 0 };
    let mut group_refs: Vec<Option<(u32, u32)>> = vec![None; packing.blocks.len()];
    for (b, id) in
        group_entries.iter().enumerate().filter(|(_, e)| !e.is_empty()).map(|(b, _)| b).zip(first_group..)
    {
        let mut bytes = vec![0u8; bs as usize];
        group::encode(&group_entries[b], &mut bytes).map_err(invalid)?;
        group_refs[b] = Some((id, pager.write(id, &mut bytes, BlockType::Group, txn)?));
    }
    let below = node_blocks_below(n, &packing.place, |i| nodes[i].children().map(|c| c.map(|x| x.index())));
    let subtree_leaves = |i: usize| -> (usize, usize) {
        // First and last leaf of a subtree in preorder.
        let (mut a, mut b) = (i, i);
        while let Some(c) = nodes[a].children() {
            a = c[0].index();
        }
        while let Some(c) = nodes[b].children() {
            b = c[1].index();
        }
        (a, b)
    };
    // Blocks last to first: a child's block never precedes its parent's.
    let mut checksums = vec![0u32; packing.blocks.len()];
    let mut node_bytes = 0u64;
    let meter = StageMeter::new(progress, Stage::Nodes, packing.blocks.len() as u64);
    for b in (0..packing.blocks.len()).rev() {
        meter.add(1);
        let records: Vec<RecordDraft> = packing.blocks[b]
            .iter()
            .map(|&m| {
                let i = m as usize;
                let node = &nodes[i];
                match (node.children(), node.split()) {
                    (Some(kids), Some(s)) => {
                        let child = |c: usize| {
                            let (cb, _) = packing.place[c];
                            let at = if cb as usize == b {
                                RecordRef { block: 0, checksum: 0, offset: offset[c] }
                            } else {
                                RecordRef {
                                    block: first_node + cb,
                                    checksum: checksums[cb as usize],
                                    offset: offset[c],
                                }
                            };
                            let (fl, ll) = subtree_leaves(c);
                            let geometry_blocks = (leaf_span(ll).1 - leaf_span(fl).0 + 1) as u32;
                            ChildEntry {
                                qbox: child_q[c],
                                at,
                                node_blocks: below[c]
                                    - u32::from(block_in_subtree(
                                        &packing.place,
                                        b as u32,
                                        c,
                                        subtree_end(c, &subtree_leaves),
                                    )),
                                geometry_blocks,
                            }
                        };
                        RecordDraft::Internal {
                            node_id: i as u32,
                            object_count: object_count(tree, i),
                            split: split_info(s),
                            children: [child(kids[0].index()), child(kids[1].index())],
                            frame: None,
                        }
                    }
                    _ => {
                        let (a, last) = leaf_span(i);
                        let base = a * p;
                        let entries = plan.entries[i]
                            .iter()
                            .map(|e| ObjectEntry { object_id: e.id.0, qbox: e.qbox, position: e.pos - base })
                            .collect();
                        let end = plan.entries[i].last().map_or(0, |e| e.pos + e.len);
                        let keys = object_ids(&plan.entries[i]).map(|id| objects.key(id)).collect();
                        RecordDraft::Leaf {
                            node_id: i as u32,
                            frame: None,
                            first_block: first_geometry + a as u32,
                            checksums: sums[a as usize..=last as usize].to_vec(),
                            objects: entries,
                            end: end - base,
                            bounds: bounds[i].clone(),
                            keys,
                        }
                    }
                }
            })
            .collect();
        let mut bytes = vec![0u8; bs as usize];
        let group = group_refs[b].map(|(block, checksum)| {
            let levels = packing.blocks[b]
                .iter()
                .map(|&m| {
                    group_entries[b]
                        .iter()
                        .filter(|e| e.record == offset[m as usize])
                        .fold(0u8, |mask, e| mask | 1 << (e.level - 1))
                })
                .collect();
            node::GroupRef { block, checksum, levels }
        });
        node::encode_block_with_groups(&records, group.as_ref(), &mut bytes).map_err(invalid)?;
        node_bytes += records.iter().map(|r| r.encoded_len() as u64).sum::<u64>();
        checksums[b] = pager.write(first_node + b as u32, &mut bytes, BlockType::Node, txn)?;
    }
    // Nodes are in preorder: a parent's path is known before its children's.
    let mut node_paths = vec![TreePath::default(); n];
    for i in 0..n {
        for (c, kid) in nodes[i].children().into_iter().flatten().enumerate() {
            node_paths[kid.index()] = node_paths[i].child(c);
        }
    }
    let mut paths = vec![TreePath::default(); objects.len()];
    let mut split_boxes: Vec<(ObjectId, Aabb)> = Vec::new();
    for (i, es) in plan.entries.iter().enumerate() {
        for (j, e) in es.iter().enumerate() {
            let first = j == 0 || es[j - 1].id != e.id;
            if first {
                paths[e.id.index()] = node_paths[i];
            }
            if let Some((_, part_box)) = e.part.as_deref() {
                match split_boxes.last_mut() {
                    Some((id, aabb)) if !first && *id == e.id => *aabb = aabb.union(part_box),
                    _ => split_boxes.push((e.id, *part_box)),
                }
            }
        }
    }
    split_boxes.sort_unstable_by_key(|&(id, _)| id);
    let (rb, _) = packing.place[0];
    Ok(Written {
        root: (first_node + rb, checksums[rb as usize], offset[0]),
        node_blocks: block_count,
        node_bytes,
        geometry_blocks,
        geometry_bytes,
        vertices,
        paths,
        split_boxes,
    })
}

/// Every node's group bounds b(S_n,k) (`lod/group.rs`), built bottom up
/// over the boxes the records hold, and per node block the entries its
/// group block holds: level by level, coarse first, and within a level in
/// the block's record order (a piece's root first), each that still fits.
fn group_entries(
    rule: &GroupRule,
    objects: &dyn ObjectSource,
    tree: &Hierarchy,
    plan: &Plan,
    packing: &Packing,
    offset: &[u32],
    block_size: u32,
) -> Result<Vec<Vec<GroupEntry>>, StorageError> {
    let nodes = &tree.nodes;
    let levels: Vec<u8> = rule.group_levels().collect();
    let lod = |e: crate::lod::LodError| StorageError::Invalid(format!("a group bound: {e}"));
    // Per node, per level: the encoded bound (None: not stored, the level
    // answers as the coarser one, or the bound is empty).
    let mut blobs: Vec<Vec<Option<Vec<u8>>>> = vec![Vec::new(); nodes.len()];
    // The bounds of nodes whose parent is not built yet (preorder: children
    // come after their parent, so walking ids down builds children first).
    let mut held: HashMap<usize, Vec<Voxels>> = HashMap::new();
    for i in (0..nodes.len()).rev() {
        let mut mine: Vec<Voxels> = Vec::with_capacity(levels.len());
        let kids: Option<Vec<Vec<Voxels>>> = nodes[i]
            .children()
            .map(|c| c.iter().map(|c| held.remove(&c.index()).unwrap_or_default()).collect());
        let meshes: Vec<Cow<Mesh>> = match &kids {
            Some(_) => Vec::new(),
            None => (0..plan.entries[i].len())
                .map(|j| plan.entry_mesh(objects, i, j))
                .collect::<Result<_, _>>()?,
        };
        let mut out = Vec::with_capacity(levels.len());
        let mut last_level = None;
        for (li, &k) in levels.iter().enumerate() {
            let grid = rule.grid(k, &plan.frames[i]).map_err(lod)?;
            let lattice_level = grid.level();
            let v = match &kids {
                Some(kids) => lift_group(grid, kids.iter().filter_map(|k| k.get(li))).map_err(lod)?,
                None => leaf_group(grid, meshes.iter().map(|m| m.as_ref())),
            };
            // A level on the same grid as the coarser one holds the same bound.
            let same = last_level == Some(lattice_level);
            last_level = Some(lattice_level);
            out.push((!same && !v.is_empty()).then(|| crate::lod::encode(&v)));
            mine.push(v);
        }
        blobs[i] = out;
        if i > 0 {
            held.insert(i, mine);
        }
    }
    let capacity = group::capacity(block_size);
    let mut per_block = Vec::with_capacity(packing.blocks.len());
    for members in &packing.blocks {
        let mut chosen: Vec<GroupEntry> = Vec::new();
        let mut used = group::entries_len(&[]);
        for (li, &k) in levels.iter().enumerate() {
            for &m in members {
                let Some(Some(blob)) = blobs[m as usize].get_mut(li) else { continue };
                if used + group::ENTRY_LEN + blob.len() <= capacity {
                    used += group::ENTRY_LEN + blob.len();
                    chosen.push(GroupEntry {
                        record: offset[m as usize],
                        level: k,
                        blob: std::mem::take(blob),
                    });
                }
            }
        }
        chosen.sort_by_key(|e| (e.record, e.level));
        per_block.push(chosen);
    }
    Ok(per_block)
}

/// A node's split as its record stores it.
pub(crate) fn split_info(s: &Split) -> SplitInfo {
    let order = match s.order {
        Order::Min => 0,
        Order::Max => 1,
        Order::Center => 2,
    };
    SplitInfo { axis: s.axis, order, overlap: s.overlap as f32, gap: s.gap as f32 }
}

/// The distinct objects of a leaf's entries, in entry order (an object's parts are consecutive).
fn object_ids(entries: &[Entry]) -> impl Iterator<Item = ObjectId> + '_ {
    entries.iter().enumerate().filter(|(j, e)| *j == 0 || entries[j - 1].id != e.id).map(|(_, e)| e.id)
}

fn object_count(tree: &Hierarchy, i: usize) -> u32 {
    let mut stack = vec![i];
    let mut n = 0u32;
    while let Some(j) = stack.pop() {
        match (tree.nodes[j].children(), tree.nodes[j].objects()) {
            (Some(c), _) => stack.extend(c.map(|c| c.index())),
            (None, Some(o)) => n += o.len() as u32,
            _ => {}
        }
    }
    n
}

/// One past the last preorder id of node `i`'s subtree.
fn subtree_end(i: usize, leaves: &dyn Fn(usize) -> (usize, usize)) -> usize {
    leaves(i).1 + 1
}

/// True when a node of the subtree `[c, end)` (preorder ids) lies in block `b`.
fn block_in_subtree(place: &[(u32, u32)], b: u32, c: usize, end: usize) -> bool {
    place[c..end].iter().any(|p| p.0 == b)
}

/// For each node, the distinct node blocks of its subtree (nodes in
/// preorder: a subtree is a range of ids), by the offline distinct-count of
/// ranges with a Fenwick tree.
fn node_blocks_below(
    n: usize,
    place: &[(u32, u32)],
    children: impl Fn(usize) -> Option<[usize; 2]>,
) -> Vec<u32> {
    // Subtree ranges [i, end_i).
    let mut end = vec![0usize; n];
    for i in (0..n).rev() {
        end[i] = match children(i) {
            Some(c) => end[c[1]],
            None => i + 1,
        };
    }
    let mut by_end: Vec<usize> = (0..n).collect();
    by_end.sort_by_key(|&i| end[i]);
    let mut fenwick = vec![0i64; n + 1];
    let add = |f: &mut Vec<i64>, mut i: usize, v: i64| {
        i += 1;
        while i < f.len() {
            f[i] += v;
            i += i & i.wrapping_neg();
        }
    };
    let sum = |f: &Vec<i64>, mut i: usize| -> i64 {
        let mut s = 0;
        while i > 0 {
            s += f[i];
            i -= i & i.wrapping_neg();
        }
        s
    };
    let mut last_seen: std::collections::HashMap<u32, usize> = std::collections::HashMap::new();
    let mut out = vec![0u32; n];
    let mut pos = 0usize;
    for &i in &by_end {
        while pos < end[i] {
            let b = place[pos].0;
            if let Some(&prev) = last_seen.get(&b) {
                add(&mut fenwick, prev, -1);
            }
            add(&mut fenwick, pos, 1);
            last_seen.insert(b, pos);
            pos += 1;
        }
        out[i] = (sum(&fenwick, end[i]) - sum(&fenwick, i)) as u32;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bulk::{BuildParams, LeafRule, Method, build};
    use proptest::prelude::*;

    /// Per block, the queries that read it, walking every node a query meets.
    fn every_node_walk(tree: &Hierarchy, p: &Packing, queries: &[Aabb]) -> Vec<u32> {
        (0..p.blocks.len())
            .map(|b| {
                let met = |q: &Aabb| {
                    let mut stack = vec![0usize];
                    let mut hit = false;
                    while let Some(i) = stack.pop() {
                        if !tree.nodes[i].aabb.intersects(q) {
                            continue;
                        }
                        hit |= p.place[i].0 as usize == b;
                        stack.extend(tree.nodes[i].children().into_iter().flatten().map(|c| c.index()));
                    }
                    hit
                };
                queries.iter().filter(|q| met(q)).count() as u32
            })
            .collect()
    }

    fn arb_box(span: f64) -> impl Strategy<Value = Aabb> {
        (prop::array::uniform3(0.0..span), prop::array::uniform3(0.0..span / 4.0)).prop_map(|(lo, d)| {
            Aabb::new([lo[0], lo[1], lo[2]].into(), [lo[0] + d[0], lo[1] + d[1], lo[2] + d[2]].into())
        })
    }

    proptest! {
        /// A closed subtree (all in its node's block) is not walked below,
        /// and every packing's reads equal those of walking every node met.
        #[test]
        fn block_reads_skip_closed_subtrees_and_count_the_same(
            boxes in prop::collection::vec(arb_box(100.0), 1..120),
            queries in prop::collection::vec(arb_box(140.0), 1..40),
            sizes in prop::collection::vec(40usize..400, 240),
            piece in 100usize..1000,
        ) {
            let params = BuildParams { method: Method::Moa, leaf: LeafRule::Objects(3), ..BuildParams::paper() };
            let tree = build(&boxes, None, &params, &|_| {}).unwrap();
            let sizes = &sizes[..tree.nodes.len()];
            let children = |i: usize| tree.nodes[i].children().map(|c| c.map(|x| x.index()));
            let p = layout::pack(sizes, children, 1000, piece);
            let walk = BlockWalk::new(&tree, &p);
            let reads = walk.reads_per_block(&queries);
            prop_assert_eq!(&reads, &every_node_walk(&tree, &p, &queries));
            // The scratch buffers carry over from query to query, as in the read model.
            let (mut stack, mut blocks) = (Vec::new(), Vec::new());
            for q in &queries {
                let one = every_node_walk(&tree, &p, std::slice::from_ref(q));
                prop_assert_eq!(walk.blocks_read(q, &mut stack, &mut blocks), one.iter().filter(|&&r| r > 0).count());
            }
        }
    }

    #[test]
    fn distinct_blocks_of_subtrees() {
        // 0 -> (1, 4); 1 -> (2, 3); preorder ids.
        let kids = |i: usize| match i {
            0 => Some([1, 4]),
            1 => Some([2, 3]),
            _ => None,
        };
        let place = [(0, 0), (0, 1), (1, 0), (2, 0), (1, 1)];
        assert_eq!(node_blocks_below(5, &place, kids), vec![3, 3, 1, 1, 1]);
    }
}
