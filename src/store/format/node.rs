//! Node blocks (format-spec/node.md): variable-size records read in place.
//! A block is validated once, when it is read, and then walked through
//! borrowed views ([`NodeView`]) with no decoding or copying.

use zerocopy::byteorder::little_endian::{F32, F64, U16, U32};
use zerocopy::{FromBytes, Immutable, IntoBytes, KnownLayout, Unaligned};

use super::all_zero;
use super::frame::FRAME_LEN;
use super::quant::QuantBox;
use crate::geom::{Aabb, Axis};
use crate::scene::{Key, KeyRef};
use crate::store::StorageError;

/// Offset of the first record in a node block.
pub const RECORDS_START: usize = FRAME_LEN + 16;
/// Bytes of an internal record.
pub const INTERNAL_LEN: usize = 84;
/// Bytes of a leaf record's fixed head.
pub const LEAF_HEAD_LEN: usize = 20;
/// Bytes of one object entry of a leaf.
pub const OBJECT_LEN: usize = 20;
/// Bytes of a bound entry's head (before its blob).
pub const BOUND_HEAD_LEN: usize = 4;
/// Bytes of a record's own frame, when it carries one (six f64).
pub const FRAME_BOX_LEN: usize = 48;
/// Bit 0 of a record's flags: the record carries its own frame.
const FLAG_FRAME: u8 = 1;
/// Bits 1-7 of a record's flags: bit j set when the block's group block
/// holds b(S_n, j + 1) for the record (format-spec/group.md).
const FLAG_GROUPS: u8 = 0xfe;
/// The finest level a group bound may have (flag bit 7).
pub const MAX_GROUP_LEVEL: u8 = 8;

const KIND_INTERNAL: u8 = 1;
const KIND_LEAF: u8 = 2;

#[derive(Debug, Clone, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
#[repr(C)]
pub(crate) struct BlockHead {
    pub(crate) used_bytes: U32,
    pub(crate) record_count: U16,
    pub(crate) reserved: [u8; 2],
    /// The group block of the block's records' group bounds; 0 for none.
    pub(crate) group_block: U32,
    pub(crate) group_checksum: U32,
}
const _: () = assert!(size_of::<BlockHead>() == RECORDS_START - FRAME_LEN);

/// A child entry of an internal record.
#[derive(Debug, Clone, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
#[repr(C)]
pub(crate) struct ChildRaw {
    pub(crate) qbox: [U16; 6],
    pub(crate) block: U32,
    pub(crate) checksum: U32,
    pub(crate) offset: U32,
    pub(crate) node_blocks: U32,
    pub(crate) geometry_blocks: U32,
}

#[derive(Debug, Clone, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
#[repr(C)]
pub(crate) struct InternalRaw {
    pub(crate) kind: u8,
    pub(crate) split: u8,
    pub(crate) flags: u8,
    pub(crate) reserved: u8,
    pub(crate) node_id: U32,
    pub(crate) object_count: U32,
    pub(crate) split_overlap: F32,
    pub(crate) split_gap: F32,
    pub(crate) children: [ChildRaw; 2],
}
const _: () = assert!(size_of::<InternalRaw>() == INTERNAL_LEN);

#[derive(Debug, Clone, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
#[repr(C)]
pub(crate) struct LeafRaw {
    pub(crate) kind: u8,
    pub(crate) flags: u8,
    pub(crate) object_count: U16,
    pub(crate) node_id: U32,
    pub(crate) first_block: U32,
    pub(crate) span: U16,
    pub(crate) keys_bytes: U16,
    pub(crate) bounds_bytes: U32,
}
const _: () = assert!(size_of::<LeafRaw>() == LEAF_HEAD_LEN);

#[derive(Debug, Clone, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
#[repr(C)]
pub(crate) struct ObjectRaw {
    pub(crate) object_id: U32,
    pub(crate) qbox: [U16; 6],
    pub(crate) position: U32,
}
const _: () = assert!(size_of::<ObjectRaw>() == OBJECT_LEN);

#[derive(Debug, Clone, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
#[repr(C)]
pub(crate) struct BoundRaw {
    pub(crate) target: U16,
    /// Bits 0-3 the level k, bits 4-15 the blob's bytes.
    pub(crate) level_bytes: U16,
}
const _: () = assert!(size_of::<BoundRaw>() == BOUND_HEAD_LEN);

/// The largest inline bound, bytes (12 bits of its head).
pub const MAX_BOUND_BYTES: usize = 4095;

impl BoundRaw {
    fn level(&self) -> u8 {
        (self.level_bytes.get() & 0xf) as u8
    }

    fn blob_bytes(&self) -> usize {
        usize::from(self.level_bytes.get() >> 4)
    }
}

/// Where a child record lives: this block (`block` 0) or another one, whose
/// checksum the parent holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct RecordRef {
    /// 0 for the parent's own block.
    pub block: u32,
    /// The checksum of `block`; 0 for the parent's own block.
    pub checksum: u32,
    /// Byte offset of the record from the block's start.
    pub offset: u32,
}

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

/// Bytes of a leaf record with `objects` entries over `span` geometry
/// blocks, `bounds` bytes of inline bounds and `keys` bytes of keys, and
/// no frame of its own ([`FRAME_BOX_LEN`] more with one).
pub const fn leaf_len(objects: usize, span: usize, bounds: usize, keys: usize) -> usize {
    LEAF_HEAD_LEN + 4 * span + OBJECT_LEN * objects + 4 + bounds + keys
}

fn frame_len(frame: &Option<Aabb>) -> usize {
    if frame.is_some() { FRAME_BOX_LEN } else { 0 }
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
    /// A leaf record as [`NodeView::stored_bytes`] gives it (a leaf names
    /// no record by offset, so its bytes hold anywhere).
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
/// of levels it holds for it: bit k - 1 for b(S_n,k), k = 2 ..= [`MAX_GROUP_LEVEL`].
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

/// What validation needs to know of the file.
#[derive(Debug, Clone, Copy)]
pub struct Limits {
    /// Bytes per block.
    pub block_size: u32,
    /// M: bound levels lie in 2 ..= M - 1.
    pub lod_levels: u8,
    /// Object ids lie below this.
    pub object_count: u32,
}

/// Bytes of the records of a node block [`validate_block`] accepted: its
/// head's `used_bytes` (records fill them exactly).
pub fn used_bytes(block: &[u8]) -> usize {
    block.get(FRAME_LEN..RECORDS_START).and_then(|b| BlockHead::read_from_bytes(b).ok()).map_or(0, |h| h.used_bytes.get() as usize)
}

/// Checks every rule of format-spec/node.md on node block `id` (its checksum
/// already verified), so that [`NodeView`]s of it never fail on structure.
/// Returns the record offsets.
pub fn validate_block(id: u32, block: &[u8], limits: &Limits) -> Result<Vec<u32>, StorageError> {
    let bad = |field: &'static str, detail: String| StorageError::corrupt(id, field, detail);
    let head = block
        .get(FRAME_LEN..RECORDS_START)
        .and_then(|b| BlockHead::read_from_bytes(b).ok())
        .ok_or_else(|| bad("node block", "too small".into()))?;
    let used = head.used_bytes.get() as usize;
    let end = RECORDS_START.checked_add(used).filter(|&e| e <= block.len() && used.is_multiple_of(4));
    let Some(end) = end else { return Err(bad("used_bytes", format!("{used} bytes do not fit the block"))) };
    if head.reserved != [0; 2] || !all_zero(&block[end..]) {
        return Err(bad("reserved", "reserved bytes are not zero".into()));
    }
    let count = usize::from(head.record_count.get());
    // Each record is at least a leaf head, so the count is bounded by the bytes.
    if count == 0 || count > used / LEAF_HEAD_LEN {
        return Err(bad("record_count", format!("{count} records in {used} bytes")));
    }
    let mut offsets = Vec::with_capacity(count);
    let mut at = RECORDS_START;
    let mut groups = 0u8;
    for i in 0..count {
        if at >= end {
            return Err(bad("record_count", format!("record {i} starts past the used bytes")));
        }
        offsets.push(at as u32);
        groups |= record_flags(&block[at..end]) & FLAG_GROUPS;
        at += validate_record(id, i as u32, &block[at..end], limits)?;
    }
    // A group block is named when, and only when, some record has a group bound there.
    let (gb, gs) = (head.group_block.get(), head.group_checksum.get());
    if (gb == 0) != (groups == 0) || (gb == 0 && gs != 0) || gb == id {
        return Err(bad(
            "group_block",
            format!("group block {gb} (checksum {gs:#x}) for records with group levels {groups:#x}"),
        ));
    }
    if at != end {
        return Err(bad("used_bytes", format!("{} bytes after the last record", end - at)));
    }
    // In-block children name a record of this block.
    for (i, &o) in offsets.iter().enumerate() {
        if let Ok(NodeView::Internal(n)) = NodeView::at(block, o) {
            for c in 0..2 {
                let r = n.child_ref(c);
                if r.block == 0 && offsets.binary_search(&r.offset).is_err() {
                    return Err(StorageError::corrupt_record(
                        id,
                        i as u32,
                        "child_offset",
                        format!("{} is not a record of this block", r.offset),
                    ));
                }
            }
        }
    }
    Ok(offsets)
}

/// A record's flags byte (0 for a record too short to have one).
fn record_flags(bytes: &[u8]) -> u8 {
    match bytes.first() {
        Some(&KIND_INTERNAL) => bytes.get(2).copied().unwrap_or(0),
        Some(&KIND_LEAF) => bytes.get(1).copied().unwrap_or(0),
        _ => 0,
    }
}

/// The group block node block `block` (validated) names, with its checksum.
pub fn group_ref(block: &[u8]) -> Option<(u32, u32)> {
    let head = BlockHead::read_from_bytes(block.get(FRAME_LEN..RECORDS_START)?).ok()?;
    (head.group_block.get() != 0).then(|| (head.group_block.get(), head.group_checksum.get()))
}

/// Validates one record at the start of `bytes`; returns its length.
fn validate_record(id: u32, index: u32, bytes: &[u8], limits: &Limits) -> Result<usize, StorageError> {
    let bad = |field: &'static str, detail: String| StorageError::corrupt_record(id, index, field, detail);
    let qbox_ok = |q: &[U16; 6]| (0..3).all(|a| q[a].get() <= q[a + 3].get());
    match bytes.first() {
        Some(&KIND_INTERNAL) => {
            let (raw, rest) = InternalRaw::ref_from_prefix(bytes).map_err(|_| bad("record", "short".into()))?;
            validate_groups(raw.flags, limits).map_err(|d| bad("flags", d))?;
            let frame = validate_frame(raw.flags, rest).map_err(|d| bad("frame", d))?;
            if raw.split & 0b11 > 2 || raw.split >> 2 > 2 {
                return Err(bad("split", format!("{:#x} is not an axis and order", raw.split)));
            }
            let (overlap, gap) = (raw.split_overlap.get(), raw.split_gap.get());
            if !overlap.is_finite() || overlap < 0.0 || !gap.is_finite() {
                return Err(bad("split_overlap", format!("overlap {overlap}, gap {gap}")));
            }
            if raw.object_count.get() < 2 {
                return Err(bad("object_count", "an internal node holds fewer than two objects".into()));
            }
            for c in &raw.children {
                if !qbox_ok(&c.qbox) {
                    return Err(bad("child_box", "a lower step exceeds the upper one".into()));
                }
                let (b, s) = (c.block.get(), c.checksum.get());
                if b == id || (b == 0 && s != 0) {
                    return Err(bad("child_block", format!("block {b} with checksum {s}")));
                }
                if c.offset.get() % 4 != 0 || (c.offset.get() as usize) < RECORDS_START {
                    return Err(bad("child_offset", format!("{} is not a record offset", c.offset.get())));
                }
            }
            if raw.reserved != 0 {
                return Err(bad("reserved", "reserved bytes are not zero".into()));
            }
            Ok(INTERNAL_LEN + frame)
        }
        Some(&KIND_LEAF) => {
            let (raw, rest) = LeafRaw::ref_from_prefix(bytes).map_err(|_| bad("record", "short".into()))?;
            validate_groups(raw.flags, limits).map_err(|d| bad("flags", d))?;
            let frame = validate_frame(raw.flags, rest).map_err(|d| bad("frame", d))?;
            // The rest of the record is read as if the frame were not there.
            let bytes = &bytes[frame..];
            let (n, span) = (usize::from(raw.object_count.get()), usize::from(raw.span.get()));
            if n == 0 || span == 0 || raw.first_block.get() == 0 {
                return Err(bad(
                    "object_count",
                    format!("{n} objects over {span} blocks from {}", raw.first_block),
                ));
            }
            let bounds = raw.bounds_bytes.get() as usize;
            let keys = usize::from(raw.keys_bytes.get());
            let len = bounds.checked_add(leaf_len(n, span, 0, keys)).filter(|&l| l <= bytes.len());
            let Some(len) = len else {
                return Err(bad("bounds_bytes", "the record overruns the block".into()));
            };
            let payload = limits.block_size as u64 - FRAME_LEN as u64;
            let objects_at = LEAF_HEAD_LEN + 4 * span;
            let mut prev: Option<u64> = None;
            // The first entry of each object: its parts follow it, so no id starts twice.
            let mut starts: Vec<u32> = Vec::new();
            for i in 0..n {
                let at = objects_at + i * OBJECT_LEN;
                let (o, _) =
                    ObjectRaw::ref_from_prefix(&bytes[at..]).map_err(|_| bad("objects", "short".into()))?;
                if o.object_id.get() >= limits.object_count {
                    return Err(bad(
                        "object_id",
                        format!("{} >= {} objects", o.object_id, limits.object_count),
                    ));
                }
                if !qbox_ok(&o.qbox) {
                    return Err(bad("object_box", "a lower step exceeds the upper one".into()));
                }
                if starts.last() != Some(&o.object_id.get()) {
                    starts.push(o.object_id.get());
                }
                let p = u64::from(o.position.get()) * 4;
                if i == 0 && p >= payload {
                    return Err(bad(
                        "position",
                        "the first object does not start in the span's first block".into(),
                    ));
                }
                if prev.is_some_and(|q| p < q + super::geometry::HEADER_LEN as u64) {
                    return Err(bad("position", format!("object {i} starts inside the one before")));
                }
                prev = Some(p);
            }
            let starts_in_order = starts.len();
            starts.sort_unstable();
            if let Some(w) = starts.windows(2).find(|w| w[0] == w[1]) {
                return Err(bad("object_id", format!("object {}'s entries are not consecutive", w[0])));
            }
            let end_at = objects_at + n * OBJECT_LEN;
            let end = u64::from(u32::from_le_bytes(
                bytes[end_at..end_at + 4].try_into().map_err(|_| bad("end", "short".into()))?,
            )) * 4;
            if prev.is_some_and(|q| end < q + super::geometry::HEADER_LEN as u64)
                || end > payload * span as u64
            {
                return Err(bad(
                    "end",
                    format!("the span's records end at {end} bytes, past its {span} blocks"),
                ));
            }
            if (end - 1) / payload + 1 != span as u64 {
                return Err(bad("span", format!("{span} blocks for records ending at byte {end}")));
            }
            let bounds_end = end_at + 4 + bounds;
            validate_bounds(&bytes[end_at + 4..bounds_end], n, limits).map_err(|d| bad("bounds", d))?;
            validate_keys(&bytes[bounds_end..len], starts_in_order).map_err(|d| bad("keys", d))?;
            Ok(len + frame)
        }
        Some(k) => Err(bad("kind", format!("{k} is neither internal (1) nor leaf (2)"))),
        None => Err(bad("record", "empty".into())),
    }
}

/// A record's own frame, when its flags say it has one: six finite f64,
/// lower corner below the upper, within the coordinate range. Returns its
/// bytes (0 without one).
fn validate_frame(flags: u8, rest: &[u8]) -> Result<usize, String> {
    // Every bit is named: bit 0 the frame, bits 1-7 group levels (validate_groups).
    if flags & FLAG_FRAME == 0 {
        return Ok(0);
    }
    let (f, _) = <[F64; 6]>::ref_from_prefix(rest).map_err(|_| "the frame is cut".to_string())?;
    let f = f.map(|x| x.get());
    let range = super::geometry::MAX_COORDINATE;
    if !f.iter().all(|x| x.is_finite() && x.abs() <= range) || (0..3).any(|a| f[a] > f[a + 3]) {
        return Err(format!("{f:?} is not a box in the coordinate range"));
    }
    Ok(FRAME_BOX_LEN)
}

/// A record's group levels lie in 2 ..= M - 1.
fn validate_groups(flags: u8, limits: &Limits) -> Result<(), String> {
    let levels = flags & FLAG_GROUPS;
    // Bit j is level j + 1: any bit at or above M - 1 names a level >= M.
    let allowed = if limits.lod_levels >= 3 { FLAG_GROUPS & ((1u16 << (limits.lod_levels - 1)) - 1) as u8 } else { 0 };
    if levels & !allowed != 0 {
        return Err(format!("group levels {levels:#x} with M = {}", limits.lod_levels));
    }
    Ok(())
}

/// The frame a record carries after its fixed head, if its flags say so.
fn frame_at(flags: u8, rest: &[u8]) -> Option<Aabb> {
    if flags & FLAG_FRAME == 0 {
        return None;
    }
    let (f, _) = <[F64; 6]>::ref_from_prefix(rest).ok()?;
    Some(Aabb::from_array(f.map(|x| x.get())))
}

/// A leaf's keys area holds one key per object, then fewer than 4 zero bytes.
fn validate_keys(mut area: &[u8], objects: usize) -> Result<(), String> {
    for i in 0..objects {
        let (_, n) = KeyRef::decode(area).ok_or_else(|| format!("object {i}'s key is cut or unknown"))?;
        area = &area[n..];
    }
    if area.len() >= 4 || !all_zero(area) {
        return Err("bytes after the keys are not padding".into());
    }
    Ok(())
}

fn validate_bounds(mut area: &[u8], targets: usize, limits: &Limits) -> Result<(), String> {
    let mut last: Option<(u16, u8)> = None;
    // Entries while a head fits; fewer than 4 bytes left are the zero padding.
    while area.len() >= BOUND_HEAD_LEN {
        let (raw, rest) = BoundRaw::ref_from_prefix(area).map_err(|_| "a bound's head is cut".to_string())?;
        let (t, k) = (raw.target.get(), raw.level());
        if usize::from(t) >= targets || k < 2 || k >= limits.lod_levels {
            return Err(format!("a bound of target {t} at level {k}"));
        }
        // One bound per target and level, in order: a reader finds them by scanning once.
        if last.is_some_and(|l| l >= (t, k)) {
            return Err("bounds are not in (target, level) order".into());
        }
        last = Some((t, k));
        let n = raw.blob_bytes();
        if n > rest.len() {
            return Err(format!("a bound of {n} bytes overruns its record"));
        }
        // A bound is of a surface, which touches some cell: one of no cell
        // would rule its object out of every query.
        if super::blob::sets_no_cell(&rest[..n]) {
            return Err(format!("the bound of target {t} at level {k} sets no cell"));
        }
        area = &rest[n..];
    }
    if !all_zero(area) {
        return Err("the bounds' padding is not zero".into());
    }
    Ok(())
}

/// A record of a validated block, borrowed in place.
#[derive(Debug, Clone, Copy)]
pub enum NodeView<'a> {
    /// An internal record.
    Internal(InternalView<'a>),
    /// A leaf record.
    Leaf(LeafView<'a>),
}

/// An internal record in place.
#[derive(Debug, Clone, Copy)]
pub struct InternalView<'a> {
    raw: &'a InternalRaw,
    frame: Option<Aabb>,
}

/// A leaf record in place.
#[derive(Debug, Clone, Copy)]
pub struct LeafView<'a> {
    raw: &'a LeafRaw,
    frame: Option<Aabb>,
    checksums: &'a [U32],
    objects: &'a [ObjectRaw],
    end: u64,
    bounds: &'a [u8],
    keys: &'a [u8],
}

impl<'a> NodeView<'a> {
    /// The record at `offset` of a block that [`validate_block`] accepted.
    pub fn at(block: &'a [u8], offset: u32) -> Result<NodeView<'a>, String> {
        let bytes = block.get(offset as usize..).ok_or("offset past the block")?;
        match bytes.first() {
            Some(&KIND_INTERNAL) => {
                let (raw, rest) = InternalRaw::ref_from_prefix(bytes).map_err(|_| "short record")?;
                Ok(NodeView::Internal(InternalView { raw, frame: frame_at(raw.flags, rest) }))
            }
            Some(&KIND_LEAF) => {
                let (raw, rest) = LeafRaw::ref_from_prefix(bytes).map_err(|_| "short record")?;
                let frame = frame_at(raw.flags, rest);
                let rest = rest.get(frame_len(&frame)..).ok_or("short record")?;
                let (checksums, rest) =
                    <[U32]>::ref_from_prefix_with_elems(rest, usize::from(raw.span.get()))
                        .map_err(|_| "short")?;
                let (objects, rest) =
                    <[ObjectRaw]>::ref_from_prefix_with_elems(rest, usize::from(raw.object_count.get()))
                        .map_err(|_| "short")?;
                let (end, rest) = U32::ref_from_prefix(rest).map_err(|_| "short")?;
                let (bounds, rest) =
                    rest.split_at_checked(raw.bounds_bytes.get() as usize).ok_or("bounds overrun")?;
                let keys = rest.get(..usize::from(raw.keys_bytes.get())).ok_or("keys overrun")?;
                Ok(NodeView::Leaf(LeafView {
                    raw,
                    frame,
                    checksums,
                    objects,
                    end: u64::from(end.get()) * 4,
                    bounds,
                    keys,
                }))
            }
            _ => Err("not a record".into()),
        }
    }

    /// The preorder id.
    pub fn node_id(&self) -> u32 {
        match self {
            NodeView::Internal(n) => n.raw.node_id.get(),
            NodeView::Leaf(l) => l.raw.node_id.get(),
        }
    }

    /// The frame the record's entries are quantized in: its own, or
    /// `decoded`, the box its parent's entry decodes to (the root's: the
    /// meta block's scene box).
    pub fn frame(&self, decoded: Aabb) -> Aabb {
        let own = match self {
            NodeView::Internal(n) => n.frame,
            NodeView::Leaf(l) => l.frame,
        };
        own.unwrap_or(decoded)
    }

    /// The levels k whose group bound b(S_n,k) the block's group block
    /// holds for this record (the paper's `bFits[k]`), coarse to fine.
    pub fn group_levels(&self) -> impl Iterator<Item = u8> + use<> {
        let flags = match self {
            NodeView::Internal(n) => n.raw.flags,
            NodeView::Leaf(l) => l.raw.flags,
        } & FLAG_GROUPS;
        (2..=MAX_GROUP_LEVEL).filter(move |k| flags >> (k - 1) & 1 == 1)
    }

    /// The record's own frame, if it carries one.
    pub fn own_frame(&self) -> Option<Aabb> {
        match self {
            NodeView::Internal(n) => n.frame,
            NodeView::Leaf(l) => l.frame,
        }
    }

    /// Objects in the subtree.
    pub fn object_count(&self) -> u32 {
        match self {
            NodeView::Internal(n) => n.raw.object_count.get(),
            NodeView::Leaf(l) => l.object_count(),
        }
    }
}

impl<'a> NodeView<'a> {
    /// The record's bytes as stored in `block` at `offset` (where
    /// [`at`](Self::at) found it).
    pub fn stored_bytes(&self, block: &'a [u8], offset: u32) -> Result<&'a [u8], String> {
        let len = match self {
            NodeView::Internal(n) => self.len_without_frame() + frame_len(&n.frame),
            NodeView::Leaf(l) => self.len_without_frame() + frame_len(&l.frame),
        };
        let start = offset as usize;
        block.get(start..start + len).ok_or_else(|| "record past the block".to_string())
    }
}

impl NodeView<'_> {
    /// The record's bytes without a frame of its own: what a bulk load
    /// would write for it.
    pub fn len_without_frame(&self) -> usize {
        match self {
            NodeView::Internal(_) => INTERNAL_LEN,
            NodeView::Leaf(l) => leaf_len(l.objects.len(), l.checksums.len(), l.bounds.len(), l.keys.len()),
        }
    }

    /// The record as a draft to write again: every field as stored.
    pub fn to_draft(&self) -> RecordDraft {
        match self {
            NodeView::Internal(n) => {
                let child = |i: usize| {
                    let c = &n.raw.children[i];
                    ChildEntry {
                        qbox: c.qbox.map(|x| x.get()),
                        at: n.child_ref(i),
                        node_blocks: c.node_blocks.get(),
                        geometry_blocks: c.geometry_blocks.get(),
                    }
                };
                RecordDraft::Internal {
                    node_id: n.raw.node_id.get(),
                    object_count: n.raw.object_count.get(),
                    split: n.split(),
                    children: [child(0), child(1)],
                    frame: n.frame,
                }
            }
            NodeView::Leaf(l) => {
                let objects = (0..l.len())
                    .filter_map(|i| l.object(i))
                    .map(|o| ObjectEntry { object_id: o.object_id, qbox: o.qbox, position: o.span.0 })
                    .collect();
                RecordDraft::Leaf {
                    node_id: l.raw.node_id.get(),
                    frame: l.frame,
                    first_block: l.raw.first_block.get(),
                    checksums: l.checksums.iter().map(|c| c.get()).collect(),
                    objects,
                    end: l.end,
                    bounds: l
                        .bounds()
                        .map(|b| BoundEntry { target: b.target, level: b.level, blob: b.blob.to_vec() })
                        .collect(),
                    keys: l.keys().map(|(_, k)| k.to_key()).collect(),
                }
            }
        }
    }
}

/// A bound borrowed from a record: the blob of level `level` for `target`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoundView<'a> {
    /// The child (0 or 1) or the object index in the leaf the bound is for.
    pub target: u16,
    /// The level of detail k.
    pub level: u8,
    /// The voxel blob (format-spec/lod.md).
    pub blob: &'a [u8],
}

fn bounds_iter(mut area: &[u8]) -> impl Iterator<Item = BoundView<'_>> {
    std::iter::from_fn(move || {
        let (raw, rest) = BoundRaw::ref_from_prefix(area).ok()?;
        let n = raw.blob_bytes();
        let blob = rest.get(..n)?;
        area = &rest[n..];
        Some(BoundView { target: raw.target.get(), level: raw.level(), blob })
    })
}

impl<'a> InternalView<'a> {
    /// Child `i`'s (0 or 1) box, decoded in `frame` (this node's box).
    pub fn child_box(&self, i: usize, frame: &Aabb) -> Option<QuantBox> {
        QuantBox::decode(frame, self.raw.children[i].qbox.map(|x| x.get()))
    }

    /// Where child `i`'s record is.
    pub fn child_ref(&self, i: usize) -> RecordRef {
        let c = &self.raw.children[i];
        RecordRef { block: c.block.get(), checksum: c.checksum.get(), offset: c.offset.get() }
    }

    /// Child `i`'s node blocks other than this record's, and its geometry blocks.
    pub fn child_blocks(&self, i: usize) -> (u32, u32) {
        let c = &self.raw.children[i];
        (c.node_blocks.get(), c.geometry_blocks.get())
    }

    /// The split.
    pub fn split(&self) -> SplitInfo {
        let s = self.raw.split;
        SplitInfo {
            axis: Axis::from_index(usize::from(s & 0b11)).unwrap_or(Axis::X),
            order: s >> 2,
            overlap: self.raw.split_overlap.get(),
            gap: self.raw.split_gap.get(),
        }
    }
}

/// An object of a leaf in place.
#[derive(Debug, Clone, Copy)]
pub struct ObjectView {
    /// The object's id.
    pub object_id: u32,
    /// The box of the object's (or part's) triangles, in steps of the leaf's box.
    pub qbox: [u16; 6],
    /// Byte range of its geometry record (and any padding after it) in the leaf's span.
    pub span: (u64, u64),
}

impl<'a> LeafView<'a> {
    /// Entries: objects, and the parts of objects larger than a geometry
    /// block (consecutive entries of one id).
    pub fn len(&self) -> usize {
        self.objects.len()
    }

    /// Distinct objects.
    pub fn object_count(&self) -> u32 {
        let ids = self.objects.iter().map(|o| o.object_id.get());
        ids.clone().zip(ids.skip(1)).filter(|(a, b)| a != b).count() as u32
            + u32::from(!self.objects.is_empty())
    }

    /// Never true for a valid record.
    #[cfg(feature = "internals")]
    pub fn is_empty(&self) -> bool {
        self.objects.is_empty()
    }

    /// Object `i`.
    pub fn object(&self, i: usize) -> Option<ObjectView> {
        let o = self.objects.get(i)?;
        let next = self.objects.get(i + 1).map_or(self.end, |n| u64::from(n.position.get()) * 4);
        Some(ObjectView {
            object_id: o.object_id.get(),
            qbox: o.qbox.map(|x| x.get()),
            span: (u64::from(o.position.get()) * 4, next),
        })
    }

    /// The first geometry block of the span and the checksums of its blocks.
    pub fn geometry(&self) -> (u32, impl ExactSizeIterator<Item = u32> + 'a) {
        (self.raw.first_block.get(), self.checksums.iter().map(|c| c.get()))
    }

    /// The inline per-object bounds B(o,k), by (object index, level).
    pub fn bounds(&self) -> impl Iterator<Item = BoundView<'a>> + 'a {
        bounds_iter(self.bounds)
    }

    /// Each object's key, with the index of its first entry, in entry order.
    pub(crate) fn keys(&self) -> impl Iterator<Item = (usize, KeyRef<'a>)> + 'a {
        let objects = self.objects;
        let starts = (0..objects.len())
            .filter(move |&i| i == 0 || objects[i - 1].object_id.get() != objects[i].object_id.get());
        let mut area = self.keys;
        starts.map_while(move |i| {
            let (k, n) = KeyRef::decode(area)?;
            area = &area[n..];
            Some((i, k))
        })
    }

    /// The key of entry `i`'s object.
    pub fn key(&self, i: usize) -> Option<Key> {
        let id = self.objects.get(i)?.object_id.get();
        let first = (0..=i).rev().take_while(|&j| self.objects[j].object_id.get() == id).last()?;
        self.keys().find(|&(j, _)| j == first).map(|(_, k)| k.to_key())
    }
}

/// Where a child's block went: (block, checksum) -> the new ones.
pub type MoveChild<'a> = dyn FnMut(u32, u32) -> Result<(u32, u32), StorageError> + 'a;

/// Where a leaf's span went: (first block, its blocks' checksums) -> the new ones.
pub type MoveSpan<'a> = dyn FnMut(u32, &[u32]) -> Result<(u32, Vec<u32>), StorageError> + 'a;

/// Points the references of node block `id`, which [`validate_block`]
/// accepted with record offsets `records`, at blocks moved elsewhere:
/// each child in another block through `child` (its block and checksum ->
/// the new ones), and each leaf's span through `span` (its first geometry
/// block and its blocks' checksums -> the new first block and checksums).
/// Everything else stays byte for byte (a compaction moves a tree as it is).
pub fn relocate_block(
    id: u32,
    block: &mut [u8],
    records: &[u32],
    child: &mut MoveChild<'_>,
    span: &mut MoveSpan<'_>,
) -> Result<(), StorageError> {
    let short = |r: u32| StorageError::corrupt_record(id, r, "record", "short record");
    // The group block moves as a child block does.
    if let Some(head) = block.get_mut(FRAME_LEN..RECORDS_START).and_then(|b| BlockHead::mut_from_bytes(b).ok())
        && head.group_block.get() != 0
    {
        let (b, sum) = child(head.group_block.get(), head.group_checksum.get())?;
        (head.group_block, head.group_checksum) = (b.into(), sum.into());
    }
    for &r in records {
        let bytes = block.get_mut(r as usize..).ok_or_else(|| short(r))?;
        match bytes.first() {
            Some(&KIND_INTERNAL) => {
                let (raw, _) = InternalRaw::mut_from_prefix(bytes).map_err(|_| short(r))?;
                for c in raw.children.iter_mut().filter(|c| c.block.get() != 0) {
                    let (b, sum) = child(c.block.get(), c.checksum.get())?;
                    (c.block, c.checksum) = (b.into(), sum.into());
                }
            }
            Some(&KIND_LEAF) => {
                let (raw, rest) = LeafRaw::mut_from_prefix(bytes).map_err(|_| short(r))?;
                let skip = if raw.flags & FLAG_FRAME != 0 { FRAME_BOX_LEN } else { 0 };
                let rest = rest.get_mut(skip..).ok_or_else(|| short(r))?;
                let (sums, _) = <[U32]>::mut_from_prefix_with_elems(rest, usize::from(raw.span.get()))
                    .map_err(|_| short(r))?;
                let old: Vec<u32> = sums.iter().map(|c| c.get()).collect();
                let (first, new) = span(raw.first_block.get(), &old)?;
                raw.first_block = first.into();
                for (c, n) in sums.iter_mut().zip(new) {
                    *c = n.into();
                }
            }
            _ => return Err(StorageError::corrupt_record(id, r, "kind", "not a record")),
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn limits() -> Limits {
        Limits { block_size: 1024, lod_levels: 4, object_count: 10 }
    }

    fn drafts() -> Vec<RecordDraft> {
        let leaf = RecordDraft::Leaf {
            node_id: 1,
            frame: None,
            first_block: 9,
            checksums: vec![77],
            objects: vec![
                ObjectEntry { object_id: 3, qbox: [0, 0, 0, 10, 10, 10], position: 0 },
                ObjectEntry { object_id: 4, qbox: [1, 2, 3, 4, 5, 6], position: 100 },
                ObjectEntry { object_id: 4, qbox: [1, 2, 3, 4, 5, 6], position: 200 },
            ],
            end: 300,
            bounds: vec![BoundEntry { target: 1, level: 2, blob: vec![1, 1, 4] }],
            keys: vec![Key::Int(3), Key::bytes("four").unwrap()],
        };
        let inner = RecordDraft::Internal {
            node_id: 0,
            object_count: 3,
            split: SplitInfo { axis: Axis::Y, order: 1, overlap: 0.5, gap: -1.0 },
            children: [
                ChildEntry {
                    qbox: [0, 0, 0, 9, 9, 9],
                    at: RecordRef { block: 0, checksum: 0, offset: RECORDS_START as u32 + 84 },
                    node_blocks: 0,
                    geometry_blocks: 1,
                },
                ChildEntry {
                    qbox: [9, 9, 9, 99, 99, 99],
                    at: RecordRef { block: 5, checksum: 1234, offset: RECORDS_START as u32 },
                    node_blocks: 1,
                    geometry_blocks: 1,
                },
            ],
            frame: None,
        };
        vec![inner, leaf]
    }

    #[test]
    fn records_round_trip_in_place() {
        let mut block = vec![0u8; 1024];
        let offsets = encode_block(&drafts(), &mut block).unwrap();
        assert_eq!(validate_block(3, &block, &limits()).unwrap(), offsets);
        let NodeView::Internal(n) = NodeView::at(&block, offsets[0]).unwrap() else { panic!() };
        assert_eq!(n.child_ref(1), RecordRef { block: 5, checksum: 1234, offset: RECORDS_START as u32 });
        assert_eq!(n.split().axis, Axis::Y);
        let NodeView::Leaf(l) = NodeView::at(&block, offsets[1]).unwrap() else { panic!() };
        assert_eq!(l.len(), 3);
        assert_eq!(l.object_count(), 2, "the parts of object 4 are one object");
        assert_eq!(l.object(1).unwrap().span, (100, 200));
        assert_eq!(l.key(0), Some(Key::Int(3)));
        assert_eq!(l.key(2), Some(Key::bytes("four").unwrap()), "a part has its object's key");
        assert_eq!(l.key(3), None);
        let blob = [1, 1, 4];
        assert_eq!(l.bounds().collect::<Vec<_>>(), vec![BoundView { target: 1, level: 2, blob: &blob }]);
        assert_eq!(l.geometry().1.collect::<Vec<_>>(), vec![77]);
    }

    #[test]
    fn a_record_read_back_is_the_draft_it_was_written_from() {
        let mut block = vec![0u8; 1024];
        let drafts = drafts();
        let offsets = encode_block(&drafts, &mut block).unwrap();
        for (d, &o) in drafts.iter().zip(&offsets) {
            assert_eq!(&NodeView::at(&block, o).unwrap().to_draft(), d);
        }
    }

    #[test]
    fn records_with_their_own_frames_round_trip() {
        let frame = Aabb::from_array([-1.5, 0.0, 2.0, 10.0, 20.25, 30.0]);
        let mut drafts = drafts();
        for d in &mut drafts {
            match d {
                RecordDraft::Internal { frame: f, .. } | RecordDraft::Leaf { frame: f, .. } => *f = Some(frame),
            }
        }
        // The in-block child follows an internal record that is a frame longer.
        if let RecordDraft::Internal { children, .. } = &mut drafts[0] {
            children[0].at.offset += FRAME_BOX_LEN as u32;
        }
        let mut block = vec![0u8; 1024];
        let offsets = encode_block(&drafts, &mut block).unwrap();
        assert_eq!(offsets[1] as usize, RECORDS_START + INTERNAL_LEN + FRAME_BOX_LEN);
        assert_eq!(validate_block(3, &block, &limits()).unwrap(), offsets);
        let decoded = Aabb::from_array([0.0; 6]);
        for &o in &offsets {
            let v = NodeView::at(&block, o).unwrap();
            assert_eq!(v.own_frame(), Some(frame));
            assert_eq!(v.frame(decoded), frame);
        }
        let NodeView::Leaf(l) = NodeView::at(&block, offsets[1]).unwrap() else { panic!() };
        assert_eq!(l.object(1).unwrap().span, (100, 200));
        assert_eq!(l.key(2), Some(Key::bytes("four").unwrap()));
        assert_eq!(l.geometry().1.collect::<Vec<_>>(), vec![77]);
        // A frame turned inside out, a NaN, an unknown flag: corruption.
        let leaf_frame = offsets[1] as usize + LEAF_HEAD_LEN;
        for (at, bytes) in [
            (leaf_frame, 100.0f64.to_le_bytes()),
            (leaf_frame + 8, f64::NAN.to_le_bytes()),
            (offsets[0] as usize + 2, [3, 0, 0, 0, 0, 0, 0, 0]),
        ] {
            let mut b = block.clone();
            let n = if at == offsets[0] as usize + 2 { 1 } else { 8 };
            b[at..at + n].copy_from_slice(&bytes[..n]);
            assert!(validate_block(3, &b, &limits()).is_err(), "byte {at}");
        }
    }

    #[test]
    fn a_relocated_block_changes_only_its_references() {
        let mut block = vec![0u8; 1024];
        let offsets = encode_block(&drafts(), &mut block).unwrap();
        let before = block.clone();
        let mut children = Vec::new();
        let child = &mut |b: u32, sum: u32| {
            children.push((b, sum));
            Ok((b + 100, sum ^ 0xffff))
        };
        let span = &mut |first: u32, sums: &[u32]| Ok((first + 1000, sums.iter().map(|s| s + 1).collect()));
        relocate_block(3, &mut block, &offsets, child, span).unwrap();
        assert_eq!(children, [(5, 1234)], "the child in this block is not a reference");
        assert_eq!(validate_block(3, &block, &limits()).unwrap(), offsets);
        let NodeView::Internal(n) = NodeView::at(&block, offsets[0]).unwrap() else { panic!() };
        assert_eq!(n.child_ref(0), RecordRef { block: 0, checksum: 0, offset: RECORDS_START as u32 + 84 });
        assert_eq!(n.child_ref(1), RecordRef { block: 105, checksum: 1234 ^ 0xffff, offset: RECORDS_START as u32 });
        let NodeView::Leaf(l) = NodeView::at(&block, offsets[1]).unwrap() else { panic!() };
        let (first, sums) = l.geometry();
        assert_eq!((first, sums.collect::<Vec<_>>()), (1009, vec![78]));
        // Every other byte as it was: the child's block and checksum (20 +
        // 32 + 12 .. + 20 of the internal record) and the leaf's first block
        // and checksum (8 .. 12 and 20 .. 24 of its record).
        let internal = offsets[0] as usize + 20 + 32 + 12;
        let leaf = offsets[1] as usize;
        let moved: Vec<usize> = (internal..internal + 8).chain(leaf + 8..leaf + 12).chain(leaf + 20..leaf + 24).collect();
        for (i, (a, b)) in before.iter().zip(&block).enumerate() {
            assert!(a == b || moved.contains(&i), "byte {i} changed");
        }
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

    #[test]
    fn broken_rules_are_corruption() {
        let mut block = vec![0u8; 1024];
        let offsets = encode_block(&drafts(), &mut block).unwrap();
        // (byte, value): the kind, the used bytes, an in-block child offset,
        // the reserved tail, an object id out of range, the third entry's id
        // made 3 (object 3 again, after 4), the bound's bitmap (its blob:
        // level 1, form 1, one byte) cleared; a key's unknown tag, a key's
        // length past the keys, padding that is not zero.
        let third = offsets[1] as usize + 20 + 4 + 2 * 20;
        let bitmap = offsets[1] as usize + 20 + 4 + 3 * 20 + 4 + 4 + 2;
        // The keys after the bound's 8 bytes: 9 of an integer, 6 of "four", 1 of padding.
        let keys = offsets[1] as usize + 20 + 4 + 3 * 20 + 4 + 8;
        let cases = [
            (keys, 5),
            (keys + 10, 9),
            (keys + 15, 1),
            (RECORDS_START, 7),
            (16, 1),
            (RECORDS_START + 20 + 16, 1),
            // A group level with no group block, a group block no record names.
            (RECORDS_START + 2, 1 << 1),
            (FRAME_LEN + 8, 9),
            // A group level at M (level 4 of a file of M = 4).
            (RECORDS_START + 2, 1 << 3),
            (1000, 1),
            (offsets[1] as usize + 20 + 4, 99),
            (third, 3),
            (bitmap, 0),
        ];
        for (i, (at, value)) in cases.into_iter().enumerate() {
            let mut b = block.clone();
            b[at] = value;
            assert!(validate_block(3, &b, &limits()).is_err(), "case {i}");
        }
    }
}
