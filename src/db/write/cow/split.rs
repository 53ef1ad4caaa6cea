//! A leaf split in place (format-spec/commit.md, "Splits"): a leaf past
//! its rule or a node block becomes the subtree a bulk load of its objects
//! with the file's parameters builds, whose root takes the leaf's place
//! and id, and whose other records go to new node blocks packed as a bulk
//! load packs them (format-spec/node.md, "Packing").

use std::collections::BTreeSet;
use std::ops::Range;

use rustc_hash::FxHashMap as HashMap;

use super::leaf::{NewEntry, leaf_draft};
use super::{Deltas, Step, Structural};
use crate::bulk::{BuildParams, Hierarchy, LeafRule};
use crate::db::load::split_info;
use crate::db::write::WriteTransaction;
use crate::geom::Aabb;
use crate::scene::Key;
use crate::store::StorageError;
use crate::store::format::frame::BlockType;
use crate::store::format::node::{self, ChildEntry, RecordDraft, RecordRef};
use crate::store::format::quant::{QuantBox, quantize};
use crate::store::layout::{self, Packing};
use crate::tree::Owner;

/// What a leaf split needs besides its entries.
pub(super) struct SplitLeaf<'a> {
    /// The file's build: its method and leaf rule.
    pub(super) params: &'a BuildParams,
    /// The frame the subtree's root quantizes its children's boxes in.
    pub(super) frame: Aabb,
    /// The root's own frame, if it has one.
    pub(super) own_frame: Option<Aabb>,
    /// The leaf's id, which the subtree's root keeps.
    pub(super) node_id: u32,
}

/// A leaf split in place: the subtree's root record, which takes the
/// leaf's place, and what was written below it.
pub(super) struct SubTree {
    pub(super) root: RecordDraft,
    /// Node blocks written below the root's record.
    pub(super) node_blocks: u32,
    /// Geometry blocks of its leaves.
    pub(super) geometry_blocks: u64,
    /// Levels below the root.
    pub(super) levels: u32,
}

/// The subtree a split builds, its nodes in preorder: each node's frame,
/// its box as its parent's entry holds it, and its id.
struct Shape {
    tree: Hierarchy,
    frames: Vec<Aabb>,
    qboxes: Vec<[u16; 6]>,
    ids: Vec<u32>,
}

impl Shape {
    /// The children of node `i`, for an internal node.
    fn kids(&self, i: usize) -> Option<[usize; 2]> {
        self.tree.nodes[i].children().map(|c| c.map(|c| c.index()))
    }
}

/// A split's records made so far, by node: drafts, and the objects and
/// geometry blocks below each.
struct Made {
    drafts: Vec<Option<RecordDraft>>,
    objects: Vec<u32>,
    geometry: Vec<u64>,
}

impl WriteTransaction<'_> {
    /// Splits a leaf of `entries` as a bulk load of its objects with the
    /// file's parameters would (format-spec/commit.md, "Splits"): writes
    /// the new leaves' spans and every record below the subtree's root in
    /// new node blocks, each named from one parent block; the root, which
    /// takes the leaf's place and id, is returned. The entries' bounds go
    /// (they are drawn around boxes quantized in the old leaf's frame).
    pub(super) fn split_leaf(
        &mut self,
        split: SplitLeaf,
        entries: Vec<NewEntry>,
        keys: Vec<Key>,
        deltas: &mut Deltas,
    ) -> Step<SubTree> {
        let bs = self.inner.pager().block_size();
        let runs = object_runs(&entries);
        if runs.len() != keys.len() {
            return Err(StorageError::Invalid("a leaf's keys do not match its objects".into()).into());
        }
        if runs.len() < 2 {
            return Ok(Err(Structural));
        }
        let shape = shape(&split, &entries, &runs, deltas)?;
        let Ok(leaves) = self.write_split_leaves(&shape, &runs, &entries, &keys, deltas, bs)? else {
            return Ok(Err(Structural));
        };
        let (mut drafts, geometry_blocks) = internal_drafts(&shape, split.own_frame, leaves)?;
        let node_blocks = self.write_split_blocks(&shape, &mut drafts, bs, deltas)?;
        let tree = &shape.tree;
        deltas.nodes += tree.nodes.len() as i64 - 1;
        deltas.leaves += tree.leaves().count() as i64 - 1;
        deltas.node_blocks += i64::from(node_blocks);
        Ok(Ok(SubTree {
            root: drafts.swap_remove(0),
            node_blocks,
            geometry_blocks,
            levels: tree.depth().saturating_sub(1),
        }))
    }

    /// The leaves of the split's subtree: their records, each leaf's
    /// entries quantized in its frame with its bounds drawn anew, and their
    /// spans written. `Err(Structural)`: a leaf's record overruns a node block.
    fn write_split_leaves(
        &mut self,
        shape: &Shape,
        runs: &[Range<usize>],
        entries: &[NewEntry],
        keys: &[Key],
        deltas: &mut Deltas,
        bs: u32,
    ) -> Step<Made> {
        let n = shape.tree.nodes.len();
        let mut made = Made { drafts: vec![None; n], objects: vec![0; n], geometry: vec![0; n] };
        for (i, node) in shape.tree.nodes.iter().enumerate() {
            let Some(objects) = node.objects() else { continue };
            let mut sub = Vec::new();
            let mut sub_keys = Vec::with_capacity(objects.len());
            for o in objects {
                let run = runs
                    .get(o.index())
                    .ok_or_else(|| StorageError::Invalid("a split lost an object".into()))?;
                sub.extend(entries[run.clone()].iter().cloned());
                sub_keys.push(keys[o.index()].clone());
            }
            let frame = &shape.frames[i];
            let (mut d, dropped, drawn) =
                leaf_draft(&sub, sub_keys, shape.ids[i], None, frame, true, deltas.rules.as_ref(), bs)?;
            deltas.count_bounds(dropped, drawn);
            if d.encoded_len() > node::capacity(bs) {
                return Ok(Err(Structural));
            }
            made.geometry[i] = self.write_span(&sub, &mut d)?;
            made.objects[i] = objects.len() as u32;
            made.drafts[i] = Some(d);
        }
        Ok(Ok(made))
    }

    /// Writes the split's records but its root's in new node blocks, packed
    /// as a bulk load packs them (store/layout.rs), children's blocks before
    /// their parent's; sets each entry's child reference and node blocks.
    /// Returns the blocks written.
    fn write_split_blocks(
        &mut self,
        shape: &Shape,
        drafts: &mut [RecordDraft],
        bs: u32,
        deltas: &mut Deltas,
    ) -> Result<u32, crate::Error> {
        let capacity = node::capacity(bs);
        // The root stays in the leaf's block, alone in its piece.
        let mut sizes: Vec<usize> = drafts.iter().map(RecordDraft::encoded_len).collect();
        sizes[0] = capacity;
        let packing = layout::pack(&sizes, |i| shape.kids(i), capacity, capacity);
        let root_block = packing.place[0].0 as usize;
        if packing.blocks[root_block].len() != 1 {
            return Err(StorageError::Invalid("a split's root shares its piece".into()).into());
        }
        let below = blocks_below(shape, &packing);
        // Blocks whose records lie deeper first: a block's children blocks before it.
        let mut order: Vec<usize> = (0..packing.blocks.len()).filter(|&b| b != root_block).collect();
        let min_level =
            |b: usize| packing.blocks[b].iter().map(|&i| shape.tree.nodes[i as usize].level).min();
        order.sort_by_key(|&b| std::cmp::Reverse(min_level(b)));
        let mut refs: Vec<Option<RecordRef>> = vec![None; drafts.len()];
        for b in order.iter().copied().chain([root_block]) {
            let nodes: Vec<usize> = packing.blocks[b].iter().map(|&i| i as usize).collect();
            let mut offset = HashMap::default();
            let mut at = node::RECORDS_START as u32;
            for &i in &nodes {
                offset.insert(i, at);
                at += drafts[i].encoded_len() as u32;
            }
            for &i in &nodes {
                let Some(cs) = shape.kids(i) else { continue };
                let RecordDraft::Internal { children, .. } = &mut drafts[i] else { continue };
                for (entry, c) in children.iter_mut().zip(cs) {
                    let (cb, _) = packing.place[c];
                    entry.at = if cb as usize == b {
                        RecordRef { block: 0, checksum: 0, offset: offset[&c] }
                    } else {
                        refs[c].ok_or_else(|| StorageError::Invalid("a child block is not written".into()))?
                    };
                    entry.node_blocks = below[c].iter().filter(|&&x| x as usize != b).count() as u32;
                }
            }
            if b == root_block {
                break;
            }
            let records: Vec<RecordDraft> = nodes.iter().map(|&i| drafts[i].clone()).collect();
            let id = self.allocate(1)?;
            let mut bytes = vec![0u8; bs as usize];
            node::encode_block(&records, &mut bytes).map_err(StorageError::Invalid)?;
            let checksum = self.put(id, &mut bytes, BlockType::Node)?;
            for &i in &nodes {
                refs[i] = Some(RecordRef { block: id, checksum, offset: offset[&i] });
            }
            deltas.node_bytes += records.iter().map(RecordDraft::encoded_len).sum::<usize>() as i64;
        }
        Ok(order.len() as u32)
    }
}

/// The entries of each object of `entries`, whose parts are adjacent.
fn object_runs(entries: &[NewEntry]) -> Vec<Range<usize>> {
    let mut runs: Vec<Range<usize>> = Vec::new();
    for (j, e) in entries.iter().enumerate() {
        match runs.last_mut() {
            Some(r) if entries[r.start].id == e.id => r.end = j + 1,
            _ => runs.push(j..j + 1),
        }
    }
    runs
}

/// The subtree a bulk load of the objects `runs` of `entries` builds with
/// the file's parameters, its frames and its ids: the root keeps the
/// leaf's, the others take new ones.
fn shape(
    split: &SplitLeaf,
    entries: &[NewEntry],
    runs: &[Range<usize>],
    deltas: &mut Deltas,
) -> Result<Shape, crate::Error> {
    let boxes: Vec<Aabb> =
        runs.iter().map(|r| entries[r.clone()].iter().fold(Aabb::EMPTY, |b, e| b.union(&e.aabb))).collect();
    let sizes: Vec<u64> =
        runs.iter().map(|r| entries[r.clone()].iter().map(|e| e.record.len() as u64).sum()).collect();
    let by_bytes = matches!(split.params.leaf, LeafRule::Bytes { .. });
    let mut tree = crate::bulk::build(&boxes, by_bytes.then_some(&sizes[..]), split.params, &|_| {})?;
    if tree.nodes.len() == 1 {
        // Within the file's rule, but not within a node block: halves.
        let half = u32::try_from(runs.len().div_ceil(2)).map_err(|_| StorageError::FileTooLarge)?;
        let params = BuildParams { leaf: LeafRule::Objects(half), ..split.params.clone() };
        tree = crate::bulk::build(&boxes, None, &params, &|_| {})?;
    }
    let n = tree.nodes.len();
    let mut shape = Shape { tree, frames: vec![split.frame; n], qboxes: vec![[0u16; 6]; n], ids: vec![] };
    // Frames, parents before children (preorder): each child's box
    // quantized in its parent's frame, as a reader decodes it.
    for i in 0..n {
        for c in shape.kids(i).into_iter().flatten() {
            let q = quantize(&shape.frames[i], &shape.tree.nodes[c].aabb);
            shape.frames[c] = QuantBox::decode(&shape.frames[i], q)
                .ok_or_else(|| StorageError::Invalid("a child box is backwards".into()))?
                .outer;
            shape.qboxes[c] = q;
        }
    }
    shape.ids = vec![split.node_id; n];
    for id in shape.ids.iter_mut().skip(1) {
        *id = deltas.next_node_id()?;
    }
    Ok(shape)
}

/// The split's internal records, children first, over the leaves `made`
/// holds, the root with frame `own_frame` as its own; returns every
/// record and the geometry blocks below the root.
fn internal_drafts(
    shape: &Shape,
    own_frame: Option<Aabb>,
    mut made: Made,
) -> Result<(Vec<RecordDraft>, u64), StorageError> {
    for i in (0..shape.tree.nodes.len()).rev() {
        let Some([a, b]) = shape.kids(i) else { continue };
        made.objects[i] = made.objects[a] + made.objects[b];
        made.geometry[i] = made.geometry[a] + made.geometry[b];
        let s = shape.tree.nodes[i]
            .split()
            .ok_or_else(|| StorageError::Invalid("a node with no split".into()))?;
        let child = |c: usize| -> Result<ChildEntry, StorageError> {
            Ok(ChildEntry {
                qbox: shape.qboxes[c],
                at: RecordRef { block: 0, checksum: 0, offset: 0 },
                node_blocks: 0,
                geometry_blocks: u32::try_from(made.geometry[c]).map_err(|_| StorageError::FileTooLarge)?,
            })
        };
        made.drafts[i] = Some(RecordDraft::Internal {
            node_id: shape.ids[i],
            object_count: made.objects[i],
            split: split_info(s),
            children: [child(a)?, child(b)?],
            frame: if i == 0 { own_frame } else { None },
        });
    }
    let drafts: Vec<RecordDraft> = made
        .drafts
        .into_iter()
        .collect::<Option<_>>()
        .ok_or_else(|| StorageError::Invalid("a split node with no record".into()))?;
    Ok((drafts, made.geometry[0]))
}

/// Per node of the split, the blocks `packing` puts its subtree in, for
/// its parent's entry.
fn blocks_below(shape: &Shape, packing: &Packing) -> Vec<BTreeSet<u32>> {
    let n = packing.place.len();
    let mut below: Vec<BTreeSet<u32>> = vec![BTreeSet::new(); n];
    for i in (0..n).rev() {
        let mut set = BTreeSet::from([packing.place[i].0]);
        for c in shape.kids(i).into_iter().flatten() {
            set.extend(below[c].iter().copied());
        }
        below[i] = set;
    }
    below
}
