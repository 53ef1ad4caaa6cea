//! A changed leaf rewritten (format-spec/commit.md, "Change commits"): the
//! entries it keeps and those added, quantized in its frame, which grows
//! when an added box leaves it (format-spec/node.md, "Quantized boxes"),
//! with their bounds ("Levels of detail"), and its geometry in a span of
//! blocks of its own. A leaf past its rule or a node block splits
//! (`split.rs`); one a change empties merges with its sibling (`merge.rs`).

use std::collections::BTreeMap;

use rustc_hash::{FxHashMap as HashMap, FxHashSet as HashSet};

use super::merge::Gone;
use super::split::SplitLeaf;
use super::{Deltas, Mod, Step, Structural};
use crate::bulk::{BuildParams, LeafRule};
use crate::db::write::WriteTransaction;
use crate::db::{ReadTransaction, Reads};
use crate::geom::Aabb;
use crate::lod::{self, LodParams, LodPlan, Voxels, bound_grid};
use crate::scene::{Key, Object, ObjectId};
use crate::store::StorageError;
use crate::store::format::frame::{BlockType, FRAME_LEN};
use crate::store::format::geometry::{self, Placement};
use crate::store::format::keys::KeyEntry;
use crate::store::format::node::{self, BoundEntry, LeafView, NodeView, ObjectEntry, RecordDraft};
use crate::store::format::quant::{QuantBox, quantize};
use crate::tree::Owner;
use crate::tree::view;

/// An object added to a leaf: its id, key and the object.
pub(super) struct Added {
    pub(super) id: u32,
    pub(super) object: Object,
}

/// A leaf's changes: the objects it loses and gains.
#[derive(Default)]
pub(super) struct LeafEdit {
    pub(super) remove: HashSet<u32>,
    pub(super) add: Vec<Added>,
}

/// A leaf's entry as the commit rewrites it: its object, its record, its
/// box as stored, and its bounds.
#[derive(Clone)]
pub(super) struct NewEntry {
    pub(super) id: u32,
    pub(super) record: Vec<u8>,
    /// The box of the entry's triangles, from its record.
    pub(super) aabb: Aabb,
    /// The entry's box as the old leaf held it, for a kept entry.
    old_q: Option<[u16; 6]>,
    bounds: Vec<BoundEntry>,
}

impl WriteTransaction<'_> {
    /// The new record and geometry of leaf `at` with `edit` applied.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn rewrite_leaf(
        &mut self,
        r: &ReadTransaction,
        mods: &mut HashMap<(u32, u32), Mod>,
        at: (u32, u32),
        edit: &LeafEdit,
        key_changes: &mut BTreeMap<Key, Option<KeyEntry>>,
        reads: &mut Reads,
        deltas: &mut Deltas,
        freed: &mut Vec<u32>,
    ) -> Step<()> {
        let bs = self.inner.pager().block_size();
        let md = &mods[&at];
        let (block, offset, frame) = (md.block.clone(), md.offset, md.frame);
        let NodeView::Leaf(leaf) = view(&block, offset)? else {
            return Err(StorageError::corrupt(block.id(), "path", "a path ends at no leaf").into());
        };
        let (first_block, sums) = leaf.geometry();
        let old_span = sums.len();
        let old_frame = view(&block, offset)?.own_frame();
        let (mut entries, mut keys, removed) =
            kept_entries(r, block.id(), &leaf, &edit.remove, reads, deltas)?;
        add_entries(&edit.add, geometry::payload(bs), deltas, &mut entries, &mut keys)?;
        // The old span goes whatever the leaf becomes: what it keeps is written anew.
        freed.extend((0..old_span as u32).map(|j| first_block + j));
        deltas.geometry_blocks -= old_span as i64;
        if entries.is_empty() {
            deltas.objects -= removed;
            let gone = Gone { objects: removed, geometry_blocks: old_span as i64 };
            return self.merge_with_sibling(r, mods, at, gone, key_changes, reads, deltas);
        }
        // The frame stays when what is added lies in it; else it grows, and
        // every entry is quantized anew in the leaf's own frame (their
        // bounds, drawn on the grid around the old boxes, go).
        let added = entries.iter().filter(|e| e.old_q.is_none()).fold(Aabb::EMPTY, |b, e| b.union(&e.aabb));
        let (new_frame, requantize) = if added.is_empty() || frame.contains(&added) {
            (old_frame, false)
        } else {
            (Some(frame.union(&added)), true)
        };
        let quant_frame = new_frame.unwrap_or(frame);
        let node_id = view(&block, offset)?.node_id();
        let objects_held = keys.len() as u64;
        let (mut draft, dropped, drawn) = leaf_draft(
            &entries,
            keys.clone(),
            node_id,
            new_frame,
            &quant_frame,
            requantize,
            deltas.rules.as_ref(),
            bs,
        )?;
        let params = r.info().and_then(|i| i.params);
        let (span, node_blocks) = if must_split(params.as_ref(), &draft, objects_held, bs)? {
            let Some(params) = params else { return Ok(Err(Structural)) };
            let split = SplitLeaf { params: &params, frame: quant_frame, own_frame: new_frame, node_id };
            let Ok(sub) = self.split_leaf(split, entries, keys, deltas)? else { return Ok(Err(Structural)) };
            let depth = mods[&at].depth as u32 + sub.levels;
            deltas.depth = deltas.depth.max(depth);
            draft = sub.root;
            (sub.geometry_blocks, sub.node_blocks)
        } else {
            if draft.encoded_len() > node::capacity(bs) {
                return Ok(Err(Structural));
            }
            deltas.count_bounds(dropped, drawn);
            (self.write_span(&entries, &mut draft)?, 0)
        };
        deltas.geometry_blocks += span as i64;
        let md =
            mods.get_mut(&at).ok_or_else(|| StorageError::Invalid("a changed leaf is not noted".into()))?;
        md.required = if requantize { new_frame } else { None };
        md.objects = edit.add.len() as i64 - removed;
        md.geometry_blocks = span as i64 - old_span as i64;
        md.node_blocks = i64::from(node_blocks);
        md.draft = Some(draft);
        deltas.objects += md.objects;
        Ok(Ok(()))
    }

    /// Writes the geometry records of `entries` at the positions `draft`
    /// (a leaf) gives them, in a span of blocks of their own, and sets the
    /// draft's span; returns its blocks.
    pub(super) fn write_span(
        &mut self,
        entries: &[NewEntry],
        draft: &mut RecordDraft,
    ) -> Result<u64, StorageError> {
        let RecordDraft::Leaf { first_block, checksums, objects, end, .. } = draft else {
            return Err(StorageError::Invalid("a span for an internal record".into()));
        };
        let pager = self.inner.pager().clone();
        let bs = pager.block_size();
        let p = geometry::payload(bs);
        let span = end.div_ceil(p);
        let first = self.allocate(u32::try_from(span).map_err(|_| StorageError::FileTooLarge)?)?;
        checksums.clear();
        let mut blockbuf = vec![0u8; bs as usize];
        for (e, o) in entries.iter().zip(objects.iter()) {
            // Records were placed on this stream; lay each one's bytes.
            let mut at = o.position;
            let mut rest = &e.record[..];
            while !rest.is_empty() {
                let b = at / p;
                while checksums.len() as u64 != b {
                    let id = first + checksums.len() as u32;
                    checksums.push(self.put(id, &mut blockbuf, BlockType::Geometry)?);
                    blockbuf.fill(0);
                }
                let off = (at % p) as usize;
                let take = rest.len().min(p as usize - off);
                blockbuf[FRAME_LEN + off..FRAME_LEN + off + take].copy_from_slice(&rest[..take]);
                rest = &rest[take..];
                at += take as u64;
            }
        }
        while (checksums.len() as u64) < span {
            let id = first + checksums.len() as u32;
            checksums.push(self.put(id, &mut blockbuf, BlockType::Geometry)?);
            blockbuf.fill(0);
        }
        *first_block = first;
        Ok(span)
    }
}

/// The entries of `leaf` (of node block `block`) whose objects `remove`
/// does not name, each record encoded anew with its bounds, and the keys
/// of their objects; the removed entries' geometry and bounds are counted
/// out of `deltas`. Also returns how many objects were removed.
fn kept_entries(
    r: &ReadTransaction,
    block: u32,
    leaf: &LeafView,
    remove: &HashSet<u32>,
    reads: &mut Reads,
    deltas: &mut Deltas,
) -> Result<(Vec<NewEntry>, Vec<Key>, i64), StorageError> {
    let mut keys = leaf.keys().map(|(_, k)| k.to_key());
    let mut entries: Vec<NewEntry> = Vec::new();
    let mut kept_keys: Vec<Key> = Vec::new();
    let mut removed_objects = 0i64;
    let mut last_id = None;
    for i in 0..leaf.len() {
        let o =
            leaf.object(i).ok_or_else(|| StorageError::corrupt(block, "objects", "an entry is missing"))?;
        // An object's parts are adjacent entries, and it has one key.
        let first_of_object = last_id != Some(o.object_id);
        last_id = Some(o.object_id);
        let key = if first_of_object { keys.next() } else { None };
        let (_, mesh) = r.read_object(block, leaf, i, reads)?;
        let bounds = leaf.bounds().filter(|b| usize::from(b.target) == i);
        if remove.contains(&o.object_id) {
            deltas.geometry_bytes -= geometry::record_len(&mesh) as i64;
            deltas.triangles -= mesh.triangle_count() as i64;
            deltas.vertices -= mesh.vertex_count() as i64;
            if first_of_object {
                removed_objects += 1;
            }
            for b in bounds {
                deltas.drop_bound(b.level, b.blob.len());
            }
            continue;
        }
        if let Some(k) = key {
            kept_keys.push(k);
        }
        let mut record = Vec::new();
        geometry::encode_object(ObjectId(o.object_id), &mesh, &mut record);
        let bounds =
            bounds.map(|b| BoundEntry { target: 0, level: b.level, blob: b.blob.to_vec() }).collect();
        entries.push(NewEntry { id: o.object_id, record, aabb: mesh.aabb(), old_q: Some(o.qbox), bounds });
    }
    Ok((entries, kept_keys, removed_objects))
}

/// Appends the entries of the objects `add` brings to `entries`, each
/// object in parts a geometry block's payload `p` holds, and their keys to
/// `keys`; their geometry is counted into `deltas`.
fn add_entries(
    add: &[Added],
    p: u64,
    deltas: &mut Deltas,
    entries: &mut Vec<NewEntry>,
    keys: &mut Vec<Key>,
) -> Result<(), StorageError> {
    for a in add {
        let pieces = if geometry::record_len(&a.object.mesh) <= p {
            vec![a.object.mesh.clone()]
        } else {
            geometry::parts(&a.object.mesh, p, p)
        };
        for mesh in pieces {
            let mut record = Vec::new();
            geometry::encode_object(ObjectId(a.id), &mesh, &mut record);
            let stored = geometry::decode_object(0, &record)?.1;
            deltas.geometry_bytes += record.len() as i64;
            deltas.triangles += stored.triangle_count() as i64;
            deltas.vertices += stored.vertex_count() as i64;
            entries.push(NewEntry { id: a.id, record, aabb: stored.aabb(), old_q: None, bounds: Vec::new() });
        }
        keys.push(
            a.object.key.clone().ok_or_else(|| StorageError::Invalid("an object without a key".into()))?,
        );
    }
    Ok(())
}

/// Whether a leaf of `objects` objects, drafted as `draft`, splits: a leaf
/// grows to twice its bulk load's capacity at most (its reads with it),
/// and its record must fit a node block; past either, it splits as its
/// file's method splits (format-spec/commit.md, "Splits"). A leaf of one
/// object cannot.
fn must_split(
    params: Option<&BuildParams>,
    draft: &RecordDraft,
    objects: u64,
    bs: u32,
) -> Result<bool, StorageError> {
    let RecordDraft::Leaf { end, .. } = draft else {
        return Err(StorageError::Invalid("a leaf drafted as an internal record".into()));
    };
    let p = geometry::payload(bs);
    let over = match params.map(|p| p.leaf) {
        Some(LeafRule::Objects(n)) => objects > 2 * u64::from(n),
        Some(LeafRule::Bytes { capacity }) => *end > 2 * capacity.max(p),
        None => end.div_ceil(p) > 4,
    };
    Ok((over || draft.encoded_len() > node::capacity(bs)) && objects > 1)
}

/// A drafted leaf record, the bounds it drops as (level, bytes) and those
/// it draws as (level, bytes, cell diagonal).
type LeafDraft = (RecordDraft, Vec<(u8, usize)>, Vec<(u8, usize, f64)>);

/// A leaf record of `entries` (each object's parts adjacent; `keys` one per
/// object), quantized in `frame`, its span not yet written; the bounds it
/// drops as (level, bytes); and those it draws as (level, bytes, cell
/// diagonal). A kept entry keeps its bounds unless `requantize`; then
/// they are drawn anew at the same levels on the grid around the entry's
/// new box (a bound is drawn on the grid around its entry's box as the
/// record holds it). A new entry gets a bound at each level most of the
/// leaf's kept entries have one: where the read model found bounds paid
/// for these objects' neighbours (format-spec/commit.md, "Levels of detail").
#[allow(clippy::too_many_arguments)]
pub(super) fn leaf_draft(
    entries: &[NewEntry],
    keys: Vec<Key>,
    node_id: u32,
    own_frame: Option<Aabb>,
    frame: &Aabb,
    requantize: bool,
    rules: Option<&(LodPlan, LodParams)>,
    bs: u32,
) -> Result<LeafDraft, crate::Error> {
    let mut placement = Placement::new(bs);
    let mut objects = Vec::with_capacity(entries.len());
    let mut bounds = Vec::new();
    let mut dropped = Vec::new();
    let mut drawn = Vec::new();
    let usual = usual_levels(entries);
    for (j, e) in entries.iter().enumerate() {
        let position = placement.place(e.record.len() as u64);
        let qbox = match (requantize, e.old_q) {
            (false, Some(q)) => q,
            _ => quantize(frame, &e.aabb),
        };
        objects.push(ObjectEntry { object_id: e.id, qbox, position });
        let target =
            u16::try_from(j).map_err(|_| StorageError::Invalid("a leaf of too many entries".into()))?;
        if !requantize && e.old_q.is_some() {
            bounds.extend(e.bounds.iter().map(|b| BoundEntry {
                target,
                level: b.level,
                blob: b.blob.clone(),
            }));
            continue;
        }
        dropped.extend(e.bounds.iter().map(|b| (b.level, b.blob.len())));
        let levels: Vec<u8> =
            if e.old_q.is_some() { e.bounds.iter().map(|b| b.level).collect() } else { usual.clone() };
        let Some((plan, params)) = rules.filter(|_| !levels.is_empty()) else { continue };
        let Some(outer) = QuantBox::decode(frame, qbox).map(|q| q.outer) else { continue };
        let mesh = geometry::decode_object(0, &e.record)?.1;
        for level in levels {
            let grid = bound_grid(plan, params, level, &outer)?.filter(|g| g.cells() <= u64::from(u16::MAX));
            let Some(grid) = grid else { continue };
            let voxels = Voxels::of_surfaces(grid, [&mesh]);
            let blob = lod::encode(&voxels);
            if blob.len() <= node::MAX_BOUND_BYTES {
                drawn.push((level, blob.len(), voxels.grid().max_cell_diagonal()));
                bounds.push(BoundEntry { target, level, blob });
            }
        }
    }
    let end = placement.end();
    let span =
        usize::try_from(end.div_ceil(geometry::payload(bs))).map_err(|_| StorageError::FileTooLarge)?;
    let draft = RecordDraft::Leaf {
        node_id,
        frame: own_frame,
        first_block: 0,
        checksums: vec![0; span],
        objects,
        end,
        bounds,
        keys,
    };
    Ok((draft, dropped, drawn))
}

/// The levels most of the kept entries among `entries` have a bound at:
/// those a new entry gets one at.
fn usual_levels(entries: &[NewEntry]) -> Vec<u8> {
    let kept = entries.iter().filter(|e| e.old_q.is_some()).count();
    let mut held = [0usize; 16];
    for b in entries.iter().filter(|e| e.old_q.is_some()).flat_map(|e| &e.bounds) {
        if let Some(n) = held.get_mut(usize::from(b.level)) {
            *n += 1;
        }
    }
    (0..held.len() as u8).filter(|&k| 2 * held[usize::from(k)] > kept).collect()
}
