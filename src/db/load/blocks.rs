//! Writes a planned tree into blocks (format-spec/node.md, geometry.md,
//! group.md): geometry records in leaf order, node records with quantized
//! boxes in the chosen packing, each child entry's counts of the blocks
//! below it, and the group bounds' blocks.

use std::ops::Range;

use rayon::prelude::*;

use super::Sink;
use super::plan::{Plan, object_ids};
use super::read_model::choose_packing;
use crate::bulk::{BuildError, Hierarchy, LoadProgress, NodeId, Order, Split, Stage, StageMeter};
use crate::db::source::ObjectSource;
use crate::geom::Aabb;
use crate::lod::{GroupRule, LeafShells};
use crate::scene::ObjectId;
use crate::store::format::frame::{BlockType, FRAME_LEN};
use crate::store::format::geometry;
use crate::store::format::group::{self, GroupEntry};
use crate::store::format::keys::TreePath;
use crate::store::format::node::{
    self, BoundEntry, ChildEntry, ObjectEntry, RecordDraft, RecordRef, SplitInfo,
};
use crate::store::layout::Packing;
use crate::store::{Pager, StorageError};

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
    pub paths: ObjectPaths,
    /// The objects stored in parts, by id, with the union of their parts'
    /// boxes (any other object's box as the tree holds it is its source's).
    pub split_boxes: Vec<(ObjectId, Aabb)>,
    /// The cells per level-2 grid the group bounds were built under, when
    /// they were (`groups::group_entries` chooses).
    pub group_cuberille_bits: Option<u32>,
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

/// Writes `tree` over `objects` as `plan` lays it out, with the inline
/// `bounds` of each node (internal: its children's group bounds; leaf: its
/// objects'), into `sink`: node blocks placed first (the root's block
/// leads), then geometry blocks and group blocks written, then the node
/// blocks last to first (a record names the checksums of its children's
/// blocks).
pub(crate) fn write(
    sink: Sink,
    objects: &dyn ObjectSource,
    tree: &Hierarchy,
    plan: &Plan,
    bounds: &[Vec<BoundEntry>],
    groups: Option<(&GroupRule, &LeafShells)>,
    progress: &(dyn Fn(LoadProgress) + Sync),
) -> Result<Written, crate::Error> {
    let Sink { pager, txn, allocate } = sink;
    let bs = pager.block_size();
    let n = tree.nodes.len();
    let sizes = plan.sizes(tree, |i| node::bounds_len(&bounds[i]));
    let capacity = node::capacity(bs);
    if let Some(i) = (0..n).find(|&i| sizes[i] > capacity) {
        return Err(BuildError::NodeTooLarge { node: i, len: sizes[i], capacity }.into());
    }
    let (packing, _) = choose_packing(tree, &sizes, capacity, &plan.samples);
    let block_count = u32::try_from(packing.blocks.len()).map_err(|_| StorageError::FileTooLarge)?;
    // Node blocks before the geometry: in an empty file they follow the
    // header and the meta block, the top of the tree first, where a
    // remote open's one range finds them (format-spec/remote.md).
    let first_node = allocate(block_count)?;
    let geometry = write_geometry(Sink { pager, txn, allocate: &mut *allocate }, objects, plan, progress)?;
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
    let (group_entries, group_cuberille_bits) = match groups {
        Some((rule, shells)) => {
            let e = super::groups::group_entries(
                (rule, shells),
                objects,
                tree,
                plan,
                (&packing, &offset),
                bs,
                progress,
            )?;
            (e.per_block, Some(e.cuberille_bits))
        }
        None => {
            // No group levels: the stage reports that it has nothing to do.
            StageMeter::new(progress, Stage::Groups, 0);
            (vec![Vec::new(); packing.blocks.len()], None)
        }
    };
    let group_refs = write_groups(Sink { pager, txn, allocate }, &group_entries, &packing)?;
    let nodes = NodeBlocks {
        tree,
        plan,
        packing: &packing,
        offset: &offset,
        first_node,
        bounds,
        geometry: &geometry,
        groups: &group_entries,
        group_refs: &group_refs,
    };
    let (checksums, node_bytes) = nodes.write(pager, txn, objects, progress)?;
    let (paths, split_boxes) = object_paths(tree, plan, objects.len());
    let (rb, _) = packing.place[0];
    Ok(Written {
        root: (first_node + rb, checksums[rb as usize], offset[0]),
        node_blocks: block_count,
        node_bytes,
        geometry_blocks: geometry.blocks,
        geometry_bytes: geometry.bytes,
        vertices: geometry.vertices,
        paths,
        split_boxes,
        group_cuberille_bits,
    })
}

/// The geometry blocks as written.
struct GeometryWritten {
    /// The first block; the others follow it.
    first: u32,
    /// Each block's checksum.
    sums: Vec<u32>,
    blocks: u64,
    bytes: u64,
    vertices: u64,
}

/// Blocks a worker encodes, seals and writes as one run, in one write: a
/// run's records are many, and each worker holds one run's buffer (1 MiB
/// of 16 KiB blocks) at a time.
const RUN_BLOCKS: u64 = 64;

/// Writes every leaf entry's geometry record where `plan` placed it, in
/// consecutive blocks. Each leaf's records start a block of their own
/// (format-spec/geometry.md), so runs of whole leaves share no block: the
/// runs are encoded, sealed and written in parallel, each block as the
/// stream places it.
fn write_geometry(
    Sink { pager, txn, allocate }: Sink,
    objects: &dyn ObjectSource,
    plan: &Plan,
    progress: &(dyn Fn(LoadProgress) + Sync),
) -> Result<GeometryWritten, StorageError> {
    let p = plan.payload;
    let blocks = plan.stream_end.div_ceil(p);
    let count = u32::try_from(blocks).map_err(|_| StorageError::FileTooLarge)?;
    let first = allocate(count)?;
    let meter = StageMeter::new(progress, Stage::Geometry, blocks);
    // Each run starts at a leaf's first block (the first at block 0) and
    // ends where the next starts (the last at the stream's end).
    let mut starts: Vec<(u64, usize)> = Vec::new();
    for (leaf, entries) in plan.entries.iter().enumerate() {
        let Some(e) = entries.first() else { continue };
        let block = e.pos / p;
        if starts.last().is_none_or(|&(run, _)| block >= run + RUN_BLOCKS) {
            starts.push((if starts.is_empty() { 0 } else { block }, leaf));
        }
    }
    let ends = starts.iter().skip(1).copied().chain([(blocks, plan.entries.len())]);
    let runs: Vec<(Range<u64>, Range<usize>)> =
        starts.iter().zip(ends).map(|(&(b0, l0), (b1, l1))| (b0..b1, l0..l1)).collect();
    let bs = pager.block_size() as usize;
    let written = runs
        .into_par_iter()
        .map(|(run, leaves)| {
            let mut buf = vec![0u8; (run.end - run.start) as usize * bs];
            let mut record = Vec::new();
            let (mut bytes, mut vertices) = (0u64, 0u64);
            for e in plan.entries[leaves].iter().flatten() {
                record.clear();
                vertices += match &e.part {
                    Some(part) => {
                        geometry::encode_object(e.id, &part.0, &mut record);
                        part.0.vertex_count() as u64
                    }
                    None => objects.encode_record(e.id, &mut record)?,
                };
                bytes += record.len() as u64;
                let mut at = e.pos - run.start * p;
                let mut rest = &record[..];
                while !rest.is_empty() {
                    let (block, off) = ((at / p) as usize, (at % p) as usize);
                    let take = rest.len().min(p as usize - off);
                    let to = block * bs + FRAME_LEN + off;
                    buf[to..to + take].copy_from_slice(&rest[..take]);
                    rest = &rest[take..];
                    at += take as u64;
                }
            }
            // `run.start` < `blocks`, which fits a u32 (`count`).
            let sums = pager.write_run(first + run.start as u32, &mut buf, BlockType::Geometry, txn)?;
            meter.add(run.end - run.start);
            Ok((sums, bytes, vertices))
        })
        .collect::<Result<Vec<_>, StorageError>>()?;
    let mut out =
        GeometryWritten { first, sums: Vec::with_capacity(count as usize), blocks, bytes: 0, vertices: 0 };
    for (sums, bytes, vertices) in written {
        out.sums.extend(sums);
        out.bytes += bytes;
        out.vertices += vertices;
    }
    Ok(out)
}

/// Writes the non-empty group blocks of `entries` (per node block); returns
/// per node block its group block and checksum.
fn write_groups(
    Sink { pager, txn, allocate }: Sink,
    entries: &[Vec<GroupEntry>],
    packing: &Packing,
) -> Result<Vec<Option<(u32, u32)>>, StorageError> {
    let bs = pager.block_size();
    let count = entries.iter().filter(|e| !e.is_empty()).count();
    let first = if count > 0 { allocate(count as u32)? } else { 0 };
    let mut refs: Vec<Option<(u32, u32)>> = vec![None; packing.blocks.len()];
    for (b, id) in entries.iter().enumerate().filter(|(_, e)| !e.is_empty()).map(|(b, _)| b).zip(first..) {
        let mut bytes = vec![0u8; bs as usize];
        group::encode(&entries[b], &mut bytes).map_err(StorageError::Invalid)?;
        refs[b] = Some((id, pager.write(id, &mut bytes, BlockType::Group, txn)?));
    }
    Ok(refs)
}

/// The node blocks of a packed tree, and what their records name.
struct NodeBlocks<'a> {
    tree: &'a Hierarchy,
    plan: &'a Plan,
    packing: &'a Packing,
    /// Per node: its record's offset in its block.
    offset: &'a [u32],
    /// The first node block; block b of the packing is `first_node + b`.
    first_node: u32,
    bounds: &'a [Vec<BoundEntry>],
    geometry: &'a GeometryWritten,
    /// Per node block: its group block's entries, and where that block is.
    groups: &'a [Vec<GroupEntry>],
    group_refs: &'a [Option<(u32, u32)>],
}

impl NodeBlocks<'_> {
    /// Writes the blocks last to first (a child's block never precedes its
    /// parent's, whose record holds its checksum); returns each block's
    /// checksum and the records' bytes.
    fn write(
        &self,
        pager: &Pager,
        txn: u64,
        objects: &dyn ObjectSource,
        progress: &(dyn Fn(LoadProgress) + Sync),
    ) -> Result<(Vec<u32>, u64), StorageError> {
        let (nodes, packing, offset) = (&self.tree.nodes, self.packing, self.offset);
        let below = node_blocks_below(nodes.len(), &packing.place, |i| {
            nodes[i].children().map(|c| c.map(|x| x.index()))
        });
        let mut checksums = vec![0u32; packing.blocks.len()];
        let mut node_bytes = 0u64;
        let meter = StageMeter::new(progress, Stage::Nodes, packing.blocks.len() as u64);
        for b in (0..packing.blocks.len()).rev() {
            meter.add(1);
            let records: Vec<RecordDraft> = packing.blocks[b]
                .iter()
                .map(|&m| self.record(m as usize, b, &checksums, &below, objects))
                .collect();
            let mut bytes = vec![0u8; pager.block_size() as usize];
            let group = self.group_refs[b].map(|(block, checksum)| {
                let levels = packing.blocks[b]
                    .iter()
                    .map(|&m| {
                        self.groups[b]
                            .iter()
                            .filter(|e| e.record == offset[m as usize])
                            .fold(0u8, |mask, e| mask | 1 << (e.level - 1))
                    })
                    .collect();
                node::GroupRef { block, checksum, levels }
            });
            node::encode_block_with_groups(&records, group.as_ref(), &mut bytes)
                .map_err(StorageError::Invalid)?;
            node_bytes += records.iter().map(|r| r.encoded_len() as u64).sum::<u64>();
            checksums[b] = pager.write(self.first_node + b as u32, &mut bytes, BlockType::Node, txn)?;
        }
        Ok((checksums, node_bytes))
    }

    /// Node `i`'s record in block `b`, the blocks after it written
    /// (`checksums`); `below`: per node, the distinct node blocks of its subtree.
    fn record(
        &self,
        i: usize,
        b: usize,
        checksums: &[u32],
        below: &[u32],
        objects: &dyn ObjectSource,
    ) -> RecordDraft {
        let (nodes, plan, packing, offset) = (&self.tree.nodes, self.plan, self.packing, self.offset);
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
        let node = &nodes[i];
        match (node.children(), node.split()) {
            (Some(kids), Some(s)) => {
                let child = |c: usize| {
                    let (cb, _) = packing.place[c];
                    let at = if cb as usize == b {
                        RecordRef { block: 0, checksum: 0, offset: offset[c] }
                    } else {
                        RecordRef {
                            block: self.first_node + cb,
                            checksum: checksums[cb as usize],
                            offset: offset[c],
                        }
                    };
                    let (fl, ll) = subtree_leaves(c);
                    let geometry_blocks = (plan.leaf_span(ll).1 - plan.leaf_span(fl).0 + 1) as u32;
                    let end = subtree_end(c, &subtree_leaves);
                    ChildEntry {
                        qbox: plan.child_q[c],
                        at,
                        node_blocks: below[c] - u32::from(block_in_subtree(&packing.place, b as u32, c, end)),
                        geometry_blocks,
                    }
                };
                RecordDraft::Internal {
                    node_id: i as u32,
                    object_count: object_count(self.tree, i),
                    split: split_info(s),
                    children: [child(kids[0].index()), child(kids[1].index())],
                    frame: None,
                }
            }
            _ => {
                let (a, last) = plan.leaf_span(i);
                let base = a * plan.payload;
                let entries = plan.entries[i]
                    .iter()
                    .map(|e| ObjectEntry { object_id: e.id.0, qbox: e.qbox, position: e.pos - base })
                    .collect();
                let end = plan.entries[i].last().map_or(0, |e| e.pos + e.len);
                RecordDraft::Leaf {
                    node_id: i as u32,
                    frame: None,
                    first_block: self.geometry.first + a as u32,
                    checksums: self.geometry.sums[a as usize..=last as usize].to_vec(),
                    objects: entries,
                    end: end - base,
                    bounds: self.bounds[i].clone(),
                    keys: object_ids(&plan.entries[i]).map(|id| objects.key(id)).collect(),
                }
            }
        }
    }
}

/// Every object's path from the root to its leaf, kept as each node's path
/// and each object's leaf: 4 bytes an object, not a 16-byte path (160 MB
/// at 10^7 objects, held while the key index is written).
#[derive(Debug, Clone, Default)]
pub(crate) struct ObjectPaths {
    /// Per node (preorder): its path.
    node: Vec<TreePath>,
    /// Per object (by id): its leaf.
    leaf: Vec<u32>,
}

impl ObjectPaths {
    /// The path of object `id`'s leaf (the root's, for an id not placed).
    pub fn of(&self, id: ObjectId) -> TreePath {
        let leaf = self.leaf.get(id.index()).map_or(0, |&l| l as usize);
        self.node.get(leaf).copied().unwrap_or_default()
    }
}

/// Per object (by id) the path from the root to its leaf, and the objects
/// stored in parts with the union of their parts' boxes.
fn object_paths(tree: &Hierarchy, plan: &Plan, objects: usize) -> (ObjectPaths, Vec<(ObjectId, Aabb)>) {
    let nodes = &tree.nodes;
    // Nodes are in preorder: a parent's path is known before its children's.
    let mut node = vec![TreePath::default(); nodes.len()];
    for i in 0..nodes.len() {
        for (c, kid) in nodes[i].children().into_iter().flatten().enumerate() {
            node[kid.index()] = node[i].child(c);
        }
    }
    let mut leaf = vec![0u32; objects];
    let mut split_boxes: Vec<(ObjectId, Aabb)> = Vec::new();
    for (i, es) in plan.entries.iter().enumerate() {
        for (j, e) in es.iter().enumerate() {
            let first = j == 0 || es[j - 1].id != e.id;
            if first {
                // Node ids are u32 (`NodeId`).
                leaf[e.id.index()] = i as u32;
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
    (ObjectPaths { node, leaf }, split_boxes)
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

/// Objects below node `i`.
fn object_count(tree: &Hierarchy, i: usize) -> u32 {
    tree.subtree(NodeId(i as u32)).filter_map(|(_, _, n)| n.objects()).map(|o| o.len() as u32).sum()
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
