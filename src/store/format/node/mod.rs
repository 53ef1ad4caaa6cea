//! Node blocks (format-spec/node.md): the record layout, and the views a
//! block is read through. A block is validated once, when it is read
//! ([`validate_block`], in `validate.rs`), and then walked through borrowed
//! views ([`NodeView`]) with no decoding or copying. Records to write are
//! encoded by `encode.rs`; a moved tree's references are rewritten by
//! `relocate.rs`.

use zerocopy::byteorder::little_endian::{F32, F64, U16, U32};
use zerocopy::{FromBytes, Immutable, IntoBytes, KnownLayout, Unaligned};

use super::frame::FRAME_LEN;
use super::quant::QuantBox;
use crate::geom::{Aabb, Axis};
use crate::scene::{Key, KeyRef};

mod encode;
mod relocate;
mod validate;

pub use encode::{
    BoundEntry, ChildEntry, GroupRef, ObjectEntry, RecordDraft, RecordPart, SplitInfo, bounds_len, capacity,
    encode_block, encode_block_parts, encode_block_with_groups, keys_len,
};
pub use relocate::relocate_block;
pub use validate::{Limits, validate_block};

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

/// Bytes of a leaf record with `objects` entries over `span` geometry
/// blocks, `bounds` bytes of inline bounds and `keys` bytes of keys, and
/// no frame of its own ([`FRAME_BOX_LEN`] more with one).
pub const fn leaf_len(objects: usize, span: usize, bounds: usize, keys: usize) -> usize {
    LEAF_HEAD_LEN + 4 * span + OBJECT_LEN * objects + 4 + bounds + keys
}

fn frame_len(frame: &Option<Aabb>) -> usize {
    if frame.is_some() { FRAME_BOX_LEN } else { 0 }
}

/// Bytes of the records of a node block [`validate_block`] accepted: its
/// head's `used_bytes` (records fill them exactly).
pub fn used_bytes(block: &[u8]) -> usize {
    block.get(FRAME_LEN..RECORDS_START).and_then(|b| BlockHead::read_from_bytes(b).ok()).map_or(0, |h| h.used_bytes.get() as usize)
}

/// The group block node block `block` (validated) names, with its checksum.
pub fn group_ref(block: &[u8]) -> Option<(u32, u32)> {
    let head = BlockHead::read_from_bytes(block.get(FRAME_LEN..RECORDS_START)?).ok()?;
    (head.group_block.get() != 0).then(|| (head.group_block.get(), head.group_checksum.get()))
}

/// The frame a record carries after its fixed head, if its flags say so.
fn frame_at(flags: u8, rest: &[u8]) -> Option<Aabb> {
    if flags & FLAG_FRAME == 0 {
        return None;
    }
    let (f, _) = <[F64; 6]>::ref_from_prefix(rest).ok()?;
    Some(Aabb::from_array(f.map(|x| x.get())))
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

#[cfg(test)]
mod tests {
    use super::*;

    pub(super) fn limits() -> Limits {
        Limits { block_size: 1024, lod_levels: 4, object_count: 10 }
    }

    pub(super) fn drafts() -> Vec<RecordDraft> {
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

}
