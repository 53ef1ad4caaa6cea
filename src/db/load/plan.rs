//! The layout plan of a bulk load (format-spec/node.md, geometry.md): each
//! node's box as its parent's entry stores it, where each object's
//! geometry record goes (leaf order, parts for objects larger than a
//! block), and the bytes of every node record; the packing of records into
//! node blocks is chosen by the read model (`read_model.rs`).

use std::borrow::Cow;

use super::read_model::{BlockWalk, SAMPLES_PER_SCALE, choose_packing};
use crate::bulk::{Hierarchy, QueryMix};
use crate::db::source::ObjectSource;
use crate::geom::Aabb;
use crate::lod::{LeafEntries, LeafEntry};
use crate::scene::{Key, Mesh, ObjectId};
use crate::store::StorageError;
use crate::store::format::geometry::{self, Placement};
use crate::store::format::node::{self, leaf_len};
use crate::store::format::quant::{QuantBox, quantize};

/// Everything about a tree's layout that does not depend on its bounds:
/// each node's box as stored, where each object's record goes, and what a
/// layout without bounds costs the read model's queries (the levels of
/// detail's cost is judged on it).
#[derive(Debug, Clone)]
pub(crate) struct Plan {
    /// Per node: its box as its parent's entry stores it (the root's exact).
    pub frames: Vec<Aabb>,
    pub(super) child_q: Vec<[u16; 6]>,
    /// Per leaf: its entries, each an object or a part of one.
    pub(super) entries: Vec<Vec<Entry>>,
    /// Per node: bytes of its leaf record's keys area.
    pub(super) key_bytes: Vec<usize>,
    pub(super) payload: u64,
    pub(super) stream_end: u64,
    pub(super) samples: Vec<Aabb>,
    /// Per node: the share of the model's queries that read the node block
    /// holding it, when the tree is laid out without bounds.
    pub read_share: Vec<f64>,
}

/// A leaf's entry: an object, or a part of one too large for a geometry
/// block (format-spec/geometry.md, "Parts"), and where its record goes.
/// A whole object's box is its source's: only the quantized box is kept
/// per entry (40 bytes, not 80: the plan lives through every stage).
#[derive(Debug, Clone)]
pub(super) struct Entry {
    pub(super) id: ObjectId,
    /// The entry's box quantized in its leaf's frame, as the leaf stores it.
    pub(super) qbox: [u16; 6],
    /// The part's mesh and box; `None` for a whole object (its source's).
    pub(super) part: Option<Box<(Mesh, Aabb)>>,
    /// Stream position and record length.
    pub(super) pos: u64,
    pub(super) len: u64,
}

impl Entry {
    pub(super) fn mesh<'a>(&'a self, objects: &'a dyn ObjectSource) -> Result<Cow<'a, Mesh>, StorageError> {
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
            if let Some(ids) = node.objects() {
                placement.start_block();
                // Exact room for an entry per object (more only for parts):
                // grown by doubling, the lists held a third more at 10^7.
                entries[i].reserve_exact(ids.len());
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
    pub(super) fn entry_blocks(&self, leaf: usize, j: usize) -> std::ops::RangeInclusive<u64> {
        let (pos, len) = self.entries[leaf].get(j).map_or((0, 1), |e| (e.pos, e.len));
        pos / self.payload..=(pos + len.max(1) - 1) / self.payload
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
    pub(super) fn leaf_span(&self, i: usize) -> (u64, u64) {
        let first = self.entries[i].first().map_or(0, |e| e.pos) / self.payload;
        let end = self.entries[i].last().map_or(1, |e| e.pos + e.len.max(1));
        (first, (end - 1) / self.payload)
    }

    /// Record bytes of every node with `bounds`.
    /// Record bytes of every node whose bounds take `bound_bytes(node)`.
    pub(super) fn sizes(&self, tree: &Hierarchy, bound_bytes: impl Fn(usize) -> usize) -> Vec<usize> {
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

/// The distinct objects of a leaf's entries, in entry order (an object's parts are consecutive).
pub(super) fn object_ids(entries: &[Entry]) -> impl Iterator<Item = ObjectId> + '_ {
    entries.iter().enumerate().filter(|(j, e)| *j == 0 || entries[j - 1].id != e.id).map(|(_, e)| e.id)
}

/// Every leaf's entries as the levels of detail judge them: the object (or
/// part) with its box and the geometry block its record starts in, read
/// from the plan's own entries.
impl LeafEntries for Plan {
    fn nodes(&self) -> usize {
        self.entries.len()
    }

    fn count(&self, node: usize) -> usize {
        self.entries.get(node).map_or(0, Vec::len)
    }

    fn entry(&self, node: usize, j: usize) -> Option<LeafEntry> {
        let e = self.entries.get(node)?.get(j)?;
        Some(LeafEntry { qbox: e.qbox, block: *self.entry_blocks(node, j).start() })
    }
}
