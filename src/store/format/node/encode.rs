//! Writing node blocks (format-spec/node.md): the records to write
//! (drafts), their encoding, and a block's payload of encoded or copied
//! records, with or without a group block.

use zerocopy::IntoBytes;
use zerocopy::byteorder::little_endian::U16;

use super::{
    BOUND_HEAD_LEN, BlockHead, BoundRaw, ChildRaw, FLAG_FRAME, FLAG_GROUPS, INTERNAL_LEN, InternalRaw, KIND_INTERNAL,
    KIND_LEAF, LeafRaw, MAX_BOUND_BYTES, ObjectRaw, RECORDS_START, RecordRef, frame_len, leaf_len,
};
use crate::geom::{Aabb, Axis};
use crate::scene::Key;
use crate::store::format::frame::FRAME_LEN;

/// A child entry, ready to write.
#[derive(Debug, Clone, PartialEq)]
pub struct ChildEntry {
    /// The child's box in steps of the parent's box.
    pub qbox: [u16; 6],
    /// Where the child's record is.
    pub at: RecordRef,
    /// Node blocks of the child's subtree other than the parent's block.
    pub node_blocks: u32,
    /// Geometry blocks the child's objects occupy.
    pub geometry_blocks: u32,
}

/// An object of a leaf, ready to write.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ObjectEntry {
    /// The object's id, below the meta block's `object_count`.
    pub object_id: u32,
    /// The object's box in steps of the leaf's box.
    pub qbox: [u16; 6],
    /// Byte offset of its geometry record in the leaf's span (a multiple of 4).
    pub position: u64,
}

/// A bound stored in a record: a voxel blob of level `level` for child
/// (internal record) or object (leaf) `target`.
#[derive(Debug, Clone, PartialEq)]
pub struct BoundEntry {
    /// The child (0 or 1) or the object index in the leaf the bound is for.
    pub target: u16,
    /// The level of detail k, 2 ..= M - 1.
    pub level: u8,
    /// The voxel blob (format-spec/lod.md), at most [`MAX_BOUND_BYTES`].
    pub blob: Vec<u8>,
}

/// How an internal node was split.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SplitInfo {
    /// The split axis.
    pub axis: Axis,
    /// 0: objects sorted by min coordinate, 1: by max, 2: by box centre.
    pub order: u8,
    /// wOverlap of the children (the paper's clamped value, >= 0).
    pub overlap: f32,
    /// max(upper of first part) - min(lower of second part), negative for a gap.
    pub gap: f32,
}

/// A record to write.
#[derive(Debug, Clone, PartialEq)]
pub enum RecordDraft {
    /// An internal record (kind 1): two children.
    Internal {
        /// The node's id (its preorder number after a bulk load); root 0.
        node_id: u32,
        /// Objects in the subtree, >= 2.
        object_count: u32,
        /// How the node was split.
        split: SplitInfo,
        /// The first child, then the second.
        children: [ChildEntry; 2],
        /// The record's own frame; `None`: the box its parent's entry decodes to.
        frame: Option<Aabb>,
    },
    /// A leaf record (kind 2): objects over a span of geometry blocks.
    Leaf {
        /// The node's id (its preorder number after a bulk load).
        node_id: u32,
        /// The record's own frame; `None`: the box its parent's entry decodes to.
        frame: Option<Aabb>,
        /// The first geometry block of the leaf's span.
        first_block: u32,
        /// Checksums of the geometry blocks `first_block ..`, one per block of the span.
        checksums: Vec<u32>,
        /// The object entries (parts of a large object are consecutive entries with one id).
        objects: Vec<ObjectEntry>,
        /// Byte offset in the span just past the last object's record.
        end: u64,
        /// Per-object bounds B(o,k) (target = object index).
        bounds: Vec<BoundEntry>,
        /// Each object's key, in entry order (one per object, not per part).
        keys: Vec<Key>,
    },
}

/// Bytes of a record's bounds area: the entries, then zero padding to a multiple of 4.
pub fn bounds_len<'a>(bounds: impl IntoIterator<Item = &'a BoundEntry>) -> usize {
    bounds.into_iter().map(|b| BOUND_HEAD_LEN + b.blob.len()).sum::<usize>().next_multiple_of(4)
}

/// Bytes of a leaf's keys area: the keys, then zero padding to a multiple of 4.
pub fn keys_len<'a>(keys: impl IntoIterator<Item = &'a Key>) -> usize {
    keys.into_iter().map(Key::encoded_len).sum::<usize>().next_multiple_of(4)
}

fn encode_frame(frame: &Option<Aabb>, out: &mut Vec<u8>) {
    for x in frame.iter().flat_map(Aabb::to_array) {
        out.extend_from_slice(&x.to_le_bytes());
    }
}

impl RecordDraft {
    /// Encoded bytes (a multiple of 4).
    pub fn encoded_len(&self) -> usize {
        match self {
            RecordDraft::Internal { frame, .. } => INTERNAL_LEN + frame_len(frame),
            RecordDraft::Leaf { frame, checksums, objects, bounds, keys, .. } => {
                leaf_len(objects.len(), checksums.len(), bounds_len(bounds), keys_len(keys)) + frame_len(frame)
            }
        }
    }

    fn encode(&self, out: &mut Vec<u8>) -> Result<(), String> {
        let start = out.len();
        match self {
            RecordDraft::Internal { node_id, object_count, split, children, frame } => {
                let child = |c: &ChildEntry| ChildRaw {
                    qbox: c.qbox.map(U16::new),
                    block: c.at.block.into(),
                    checksum: c.at.checksum.into(),
                    offset: c.at.offset.into(),
                    node_blocks: c.node_blocks.into(),
                    geometry_blocks: c.geometry_blocks.into(),
                };
                let raw = InternalRaw {
                    kind: KIND_INTERNAL,
                    split: split.axis.index() as u8 | (split.order << 2),
                    flags: if frame.is_some() { FLAG_FRAME } else { 0 },
                    reserved: 0,
                    node_id: (*node_id).into(),
                    object_count: (*object_count).into(),
                    split_overlap: split.overlap.into(),
                    split_gap: split.gap.into(),
                    children: [child(&children[0]), child(&children[1])],
                };
                out.extend_from_slice(raw.as_bytes());
                encode_frame(frame, out);
            }
            RecordDraft::Leaf { node_id, frame, first_block, checksums, objects, end, bounds, keys } => {
                let raw = LeafRaw {
                    kind: KIND_LEAF,
                    flags: if frame.is_some() { FLAG_FRAME } else { 0 },
                    object_count: u16::try_from(objects.len())
                        .map_err(|_| format!("a leaf of {} objects (at most 65,535)", objects.len()))?
                        .into(),
                    node_id: (*node_id).into(),
                    first_block: (*first_block).into(),
                    span: u16::try_from(checksums.len())
                        .map_err(|_| {
                            format!("a leaf over {} geometry blocks (at most 65,535)", checksums.len())
                        })?
                        .into(),
                    keys_bytes: u16::try_from(keys_len(keys))
                        .map_err(|_| format!("a leaf of {} bytes of keys (at most 65,535)", keys_len(keys)))?
                        .into(),
                    bounds_bytes: (bounds_len(bounds) as u32).into(),
                };
                out.extend_from_slice(raw.as_bytes());
                encode_frame(frame, out);
                for c in checksums {
                    out.extend_from_slice(&c.to_le_bytes());
                }
                let words = |p: u64| {
                    u32::try_from(p / 4).map_err(|_| format!("a geometry span of {p} bytes (at most 16 GiB)"))
                };
                for o in objects {
                    let raw = ObjectRaw {
                        object_id: o.object_id.into(),
                        qbox: o.qbox.map(U16::new),
                        position: words(o.position)?.into(),
                    };
                    out.extend_from_slice(raw.as_bytes());
                }
                out.extend_from_slice(&words(*end)?.to_le_bytes());
                encode_bounds(bounds, out)?;
                for k in keys {
                    k.encode(out);
                }
                out.resize(out.len().next_multiple_of(4), 0);
            }
        }
        debug_assert_eq!(out.len() - start, self.encoded_len());
        Ok(())
    }
}

fn encode_bounds(bounds: &[BoundEntry], out: &mut Vec<u8>) -> Result<(), String> {
    for b in bounds {
        if b.blob.len() > MAX_BOUND_BYTES || b.level > 15 {
            return Err(format!(
                "a bound of {} bytes at level {} (at most {MAX_BOUND_BYTES}, 15)",
                b.blob.len(),
                b.level
            ));
        }
        let raw = BoundRaw {
            target: b.target.into(),
            level_bytes: (u16::from(b.level) | (b.blob.len() as u16) << 4).into(),
        };
        out.extend_from_slice(raw.as_bytes());
        out.extend_from_slice(&b.blob);
    }
    out.resize(out.len().next_multiple_of(4), 0);
    Ok(())
}

/// Record bytes a node block holds.
pub fn capacity(block_size: u32) -> usize {
    block_size as usize - RECORDS_START
}

/// Encodes `records` into a node block's payload, with no group block;
/// returns each record's offset.
pub fn encode_block(records: &[RecordDraft], block: &mut [u8]) -> Result<Vec<u32>, String> {
    encode_block_with_groups(records, None, block)
}

/// A record of a node block being written: a draft to encode, or a stored
/// record's bytes, copied as they are. A change commit rewrites a block
/// whose records are mostly unchanged leaves; copying those costs a copy,
/// where decoding them into drafts costs an allocation per key and bound.
#[derive(Debug, Clone, Copy)]
pub enum RecordPart<'a> {
    /// A record to encode.
    Draft(&'a RecordDraft),
    /// A leaf record as [`NodeView::stored_bytes`](super::NodeView::stored_bytes)
    /// gives it (a leaf names no record by offset, so its bytes hold anywhere).
    StoredLeaf(&'a [u8]),
}

impl RecordPart<'_> {
    /// Encoded bytes.
    pub fn encoded_len(&self) -> usize {
        match self {
            RecordPart::Draft(d) => d.encoded_len(),
            RecordPart::StoredLeaf(b) => b.len(),
        }
    }
}

/// Encodes `records` into a node block's payload, with no group block: the
/// stored ones lose their group marks, which named the old block's group
/// block. Returns each record's offset.
pub fn encode_block_parts(records: &[RecordPart], block: &mut [u8]) -> Result<Vec<u32>, String> {
    let mut bytes = Vec::with_capacity(capacity(block.len() as u32));
    let mut offsets = Vec::with_capacity(records.len());
    for r in records {
        offsets.push((RECORDS_START + bytes.len()) as u32);
        match r {
            RecordPart::Draft(d) => d.encode(&mut bytes)?,
            RecordPart::StoredLeaf(b) => {
                if b.first() != Some(&KIND_LEAF) || b.len() < 2 || b.len() % 4 != 0 {
                    return Err("a stored record that is no leaf record".into());
                }
                let at = bytes.len();
                bytes.extend_from_slice(b);
                bytes[at + 1] &= !FLAG_GROUPS;
            }
        }
    }
    finish_block(bytes, offsets, None, block)
}

/// The group block a node block names, and per record (in order) the mask
/// of levels it holds for it: bit k - 1 for b(S_n,k), k = 2 ..=
/// [`MAX_GROUP_LEVEL`](super::MAX_GROUP_LEVEL).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct GroupRef {
    /// The group block's id (never 0).
    pub block: u32,
    /// The group block's checksum.
    pub checksum: u32,
    /// Per record, the mask of group levels (flag bits 1-7).
    pub levels: Vec<u8>,
}

/// Encodes `records` into a node block's payload, naming `group`'s block
/// and marking each record's group levels; returns each record's offset.
pub fn encode_block_with_groups(
    records: &[RecordDraft],
    group: Option<&GroupRef>,
    block: &mut [u8],
) -> Result<Vec<u32>, String> {
    let mut bytes = Vec::with_capacity(capacity(block.len() as u32));
    let mut offsets = Vec::with_capacity(records.len());
    for r in records {
        offsets.push((RECORDS_START + bytes.len()) as u32);
        r.encode(&mut bytes)?;
    }
    finish_block(bytes, offsets, group, block)
}

/// Writes the head and the encoded `bytes` of records at `offsets` into
/// `block`, marking each record's group levels.
fn finish_block(
    mut bytes: Vec<u8>,
    offsets: Vec<u32>,
    group: Option<&GroupRef>,
    block: &mut [u8],
) -> Result<Vec<u32>, String> {
    if RECORDS_START + bytes.len() > block.len() {
        return Err(format!("{} bytes of records exceed the block", bytes.len()));
    }
    if let Some(g) = group {
        if g.block == 0 || g.levels.len() != offsets.len() || g.levels.iter().any(|l| l & !FLAG_GROUPS != 0) {
            return Err("a group block of 0, or a level mask per record that is not one".into());
        }
        for (&o, &l) in offsets.iter().zip(&g.levels) {
            let at = o as usize - RECORDS_START;
            let flags = if bytes[at] == KIND_INTERNAL { at + 2 } else { at + 1 };
            bytes[flags] |= l;
        }
    }
    let (group_block, group_checksum) = group.map_or((0, 0), |g| (g.block, g.checksum));
    let head = BlockHead {
        used_bytes: (bytes.len() as u32).into(),
        record_count: u16::try_from(offsets.len()).map_err(|_| "too many records".to_string())?.into(),
        reserved: [0; 2],
        group_block: group_block.into(),
        group_checksum: group_checksum.into(),
    };
    block[FRAME_LEN..RECORDS_START].copy_from_slice(head.as_bytes());
    block[RECORDS_START..RECORDS_START + bytes.len()].copy_from_slice(&bytes);
    Ok(offsets)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::store::format::node::tests::{drafts, limits};
    use crate::store::format::node::{NodeView, group_ref, relocate_block, validate_block};

    #[test]
    fn parts_give_the_offsets_validation_finds() {
        // A writer caches the blocks it wrote with these offsets as verified.
        let drafts = drafts();
        let parts: Vec<RecordPart> = drafts.iter().map(RecordPart::Draft).collect();
        let mut block = vec![0u8; 1024];
        let offsets = encode_block_parts(&parts, &mut block).unwrap();
        assert_eq!(validate_block(3, &block, &limits()).unwrap(), offsets);
        assert_eq!(offsets.len(), drafts.len());
    }

    #[test]
    fn group_levels_and_the_group_block_round_trip_and_move() {
        let mut block = vec![0u8; 1024];
        let group = GroupRef { block: 9, checksum: 77, levels: vec![0b110, 0b010] };
        let offsets = encode_block_with_groups(&drafts(), Some(&group), &mut block).unwrap();
        assert_eq!(validate_block(3, &block, &limits()).unwrap(), offsets);
        assert_eq!(group_ref(&block), Some((9, 77)));
        let levels = |o: u32| NodeView::at(&block, o).unwrap().group_levels().collect::<Vec<u8>>();
        assert_eq!((levels(offsets[0]), levels(offsets[1])), (vec![2, 3], vec![2]));
        // The frame flag is kept apart from the group levels.
        assert!(NodeView::at(&block, offsets[1]).unwrap().own_frame().is_none());
        let child = &mut |b: u32, sum: u32| Ok((b + 100, sum + 1));
        let span = &mut |first: u32, sums: &[u32]| Ok((first, sums.to_vec()));
        relocate_block(3, &mut block, &offsets, child, span).unwrap();
        assert_eq!(group_ref(&block), Some((109, 78)), "the group block moves as a child block");
        assert!(encode_block_with_groups(&drafts(), Some(&GroupRef { levels: vec![1], ..group }), &mut block).is_err());
        let mut none = vec![0u8; 1024];
        encode_block(&drafts(), &mut none).unwrap();
        assert_eq!(group_ref(&none), None);
    }
}
