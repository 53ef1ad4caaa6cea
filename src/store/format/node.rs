//! Node blocks, node records and LOD entries (format-spec/node.md).

use zerocopy::byteorder::little_endian::{F32, U16, U32};
use zerocopy::{FromBytes, Immutable, IntoBytes, KnownLayout, Unaligned};

use super::all_zero;
use super::frame::FRAME_LEN;
use crate::geom::{Aabb, Axis};
use crate::store::StorageError;

/// Offset of the first record in a node block.
pub const RECORDS_START: usize = FRAME_LEN + 8;
/// Bytes of a record before its LOD entries.
pub const FIXED_LEN: usize = 120;
/// Bytes of one level's pair of LOD entries.
pub const LOD_PAIR_LEN: usize = 32;

/// Record size for `lod_levels` levels.
pub const fn record_size(lod_levels: u8) -> usize {
    FIXED_LEN + LOD_PAIR_LEN * lod_levels as usize
}

/// Records a node block holds.
pub fn records_per_block(block_size: u32, lod_levels: u8) -> usize {
    ((block_size as usize - RECORDS_START) / record_size(lod_levels)).min(u16::MAX as usize)
}

#[derive(Debug, Clone, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
#[repr(C)]
pub(crate) struct NodeBlockHeader {
    pub(crate) record_count: U16,
    pub(crate) record_size: U16,
    pub(crate) reserved: [u8; 4],
}

/// The fixed part of a node record.
#[derive(Debug, Clone, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
#[repr(C)]
pub struct NodeFixed {
    pub node_id: U32,
    pub kind: u8,
    pub split_axis: u8,
    pub split_order: u8,
    pub reserved0: u8,
    pub aabb: [F32; 6],
    pub split_overlap: F32,
    pub split_gap: F32,
    pub level: U16,
    pub reserved1: [u8; 2],
    pub object_count: U32,
    pub child0_block: U32,
    pub child0_checksum: U32,
    pub child1_block: U32,
    pub child1_checksum: U32,
    pub child0_slot: U16,
    pub child1_slot: U16,
    pub reserved2: [u8; 4],
    pub child0_box: [F32; 6],
    pub child1_box: [F32; 6],
}
const _: () = assert!(size_of::<NodeFixed>() == FIXED_LEN);

/// A LOD entry as stored.
#[derive(Debug, Clone, Copy, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
#[repr(C)]
pub struct LodEntryRaw {
    pub tag: u8,
    pub reserved: [u8; 3],
    pub value: U32,
    pub aux: U32,
    pub checksum: U32,
}
const _: () = assert!(size_of::<LodEntryRaw>() * 2 == LOD_PAIR_LEN);

/// Where a level of detail is stored: the paper's Fits / Page pair.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum LodRef {
    /// Not stored for this node.
    #[default]
    Absent,
    /// Fits one block (Fits = true): one read.
    InBlock { block: u32, offset: u32, checksum: u32 },
    /// Larger than a block, in consecutive blocks: `blocks` reads.
    Run { first: u32, blocks: u32, checksum: u32 },
    /// The union of the children's (Fits = false): `reads` reads through the subtree.
    Spread { reads: u32 },
    /// The same bound as entry (`level`, `objects`) of this record: a level
    /// that buys no accuracy is not stored twice. Never names another `Same`.
    Same { level: u8, objects: bool },
    /// b(S_n,1): the record's own box, no read.
    InRecord,
}

impl LodRef {
    /// The paper's Fits[k].
    pub fn fits(&self) -> bool {
        matches!(self, LodRef::InBlock { .. })
    }

    /// Block reads to fetch it from a cold cache, with the node record in
    /// hand; a `Same` entry costs what it names (`NodeRecord::entry`).
    pub fn reads(&self) -> u64 {
        match *self {
            LodRef::Absent | LodRef::InRecord | LodRef::Same { .. } => 0,
            LodRef::InBlock { .. } => 1,
            LodRef::Run { blocks, .. } => blocks.into(),
            LodRef::Spread { reads } => reads.into(),
        }
    }

    /// The stored block this entry starts at, for `InBlock` and `Run`.
    pub fn block(&self) -> Option<(u32, u32)> {
        match *self {
            LodRef::InBlock { block, checksum, .. } => Some((block, checksum)),
            LodRef::Run { first, checksum, .. } => Some((first, checksum)),
            _ => None,
        }
    }

    fn encode(&self) -> LodEntryRaw {
        let (tag, value, aux, checksum) = match *self {
            LodRef::Absent => (0, 0, 0, 0),
            LodRef::InBlock { block, offset, checksum } => (1, block, offset, checksum),
            LodRef::Run { first, blocks, checksum } => (2, first, blocks, checksum),
            LodRef::Spread { reads } => (3, reads, 0, 0),
            LodRef::Same { level, objects } => (4, level.into(), objects.into(), 0),
            LodRef::InRecord => (5, 0, 0, 0),
        };
        LodEntryRaw { tag, reserved: [0; 3], value: value.into(), aux: aux.into(), checksum: checksum.into() }
    }

    fn decode(raw: &LodEntryRaw) -> Option<LodRef> {
        let (v, a, c) = (raw.value.get(), raw.aux.get(), raw.checksum.get());
        if raw.reserved != [0; 3] {
            return None;
        }
        match raw.tag {
            0 if v == 0 && a == 0 && c == 0 => Some(LodRef::Absent),
            1 if v != 0 => Some(LodRef::InBlock { block: v, offset: a, checksum: c }),
            2 if v != 0 && a >= 2 => Some(LodRef::Run { first: v, blocks: a, checksum: c }),
            3 if a == 0 && c == 0 => Some(LodRef::Spread { reads: v }),
            4 if (1..=255).contains(&v) && a <= 1 && c == 0 => {
                Some(LodRef::Same { level: v as u8, objects: a == 1 })
            }
            5 if v == 0 && a == 0 && c == 0 => Some(LodRef::InRecord),
            _ => None,
        }
    }
}

/// A reference from a record to a child record.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChildRef {
    pub block: u32,
    pub slot: u16,
    /// The child block's checksum when it is another block; 0 when it is the same block.
    pub checksum: u32,
    /// The child's box, as the child's record stores it.
    pub aabb: [f32; 6],
}

impl ChildRef {
    /// The child's box.
    pub fn aabb(&self) -> Aabb {
        let a = self.aabb;
        Aabb::from_f32([a[0], a[1], a[2]], [a[3], a[4], a[5]])
    }
}

/// The split of an internal node.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SplitInfo {
    pub axis: Axis,
    /// 0: objects sorted by min coordinate, 1: by max, 2: by box centre.
    pub order: u8,
    pub overlap: f32,
    pub gap: f32,
}

/// A node record, decoded.
#[derive(Debug, Clone, PartialEq)]
pub struct NodeRecord {
    pub node_id: u32,
    pub aabb: [f32; 6],
    pub level: u16,
    pub object_count: u32,
    /// `Some` for internal nodes.
    pub children: Option<([ChildRef; 2], SplitInfo)>,
    /// For k = 1 .. M: [group_bound b(S_n,k), object_bounds B(S_n,k)].
    pub lods: Vec<[LodRef; 2]>,
}

impl NodeRecord {
    /// The stored box (f32, rounded outward).
    pub fn aabb(&self) -> Aabb {
        let a = self.aabb;
        Aabb::from_f32([a[0], a[1], a[2]], [a[3], a[4], a[5]])
    }

    /// True for a leaf.
    pub fn is_leaf(&self) -> bool {
        self.children.is_none()
    }

    /// The block reads a cold fetch of entry (`k`, `objects`) takes with
    /// this record in hand: the paper's bFits/bPage (BFits/BPage) prediction.
    pub fn predicted_reads(&self, k: u8, objects: bool) -> Option<u64> {
        self.entry(k, objects).map(|(_, _, e)| e.reads())
    }

    /// Entry `k` (1-based) of b(S_n,k) or, with `objects`, B(S_n,k), with a
    /// `Same` followed: the level and kind it resolves to, and its entry.
    /// Decoding guarantees the target exists and is not itself `Same`.
    pub fn entry(&self, k: u8, objects: bool) -> Option<(u8, bool, LodRef)> {
        let e = *self.lods.get(usize::from(k).checked_sub(1)?)?.get(usize::from(objects))?;
        match e {
            LodRef::Same { level, objects } => {
                let t = self.lods.get(usize::from(level) - 1)?[usize::from(objects)];
                Some((level, objects, t))
            }
            e => Some((k, objects, e)),
        }
    }

    fn encode(&self, out: &mut [u8]) {
        let f = |x: f32| F32::new(x);
        let (kids, split) = match &self.children {
            Some((c, s)) => (Some(c), Some(s)),
            None => (None, None),
        };
        let child = |i: usize| {
            kids.map(|c| c[i]).unwrap_or(ChildRef { block: 0, slot: 0, checksum: 0, aabb: [0.0; 6] })
        };
        let fixed = NodeFixed {
            node_id: self.node_id.into(),
            kind: if kids.is_some() { 1 } else { 2 },
            split_axis: split.map_or(0, |s| s.axis.index() as u8),
            split_order: split.map_or(0, |s| s.order),
            reserved0: 0,
            aabb: self.aabb.map(f),
            split_overlap: f(split.map_or(0.0, |s| s.overlap)),
            split_gap: f(split.map_or(0.0, |s| s.gap)),
            level: self.level.into(),
            reserved1: [0; 2],
            object_count: self.object_count.into(),
            child0_block: child(0).block.into(),
            child0_checksum: child(0).checksum.into(),
            child1_block: child(1).block.into(),
            child1_checksum: child(1).checksum.into(),
            child0_slot: child(0).slot.into(),
            child1_slot: child(1).slot.into(),
            reserved2: [0; 4],
            child0_box: child(0).aabb.map(f),
            child1_box: child(1).aabb.map(f),
        };
        out[..FIXED_LEN].copy_from_slice(fixed.as_bytes());
        for (k, pair) in self.lods.iter().enumerate() {
            for (j, lod) in pair.iter().enumerate() {
                let at = FIXED_LEN + k * LOD_PAIR_LEN + j * 16;
                out[at..at + 16].copy_from_slice(lod.encode().as_bytes());
            }
        }
    }

    fn decode(block: u32, slot: u32, bytes: &[u8], lod_levels: u8) -> Result<NodeRecord, StorageError> {
        let bad = |field, detail: String| StorageError::corrupt_record(block, slot, field, detail);
        let fixed =
            NodeFixed::ref_from_bytes(&bytes[..FIXED_LEN]).map_err(|_| bad("record", "short".into()))?;
        if fixed.reserved0 != 0 || fixed.reserved1 != [0; 2] || fixed.reserved2 != [0; 4] {
            return Err(bad("reserved", "reserved bytes are not zero".into()));
        }
        let aabb = fixed.aabb.map(|x| x.get());
        if aabb.iter().any(|x| !x.is_finite()) || (0..3).any(|i| aabb[i] > aabb[i + 3]) {
            return Err(bad("box", format!("{aabb:?} is not a box")));
        }
        let object_count = fixed.object_count.get();
        if object_count == 0 {
            return Err(bad("object_count", "a node holds no object".into()));
        }
        let children = match fixed.kind {
            1 => {
                let axis = Axis::from_index(fixed.split_axis.into())
                    .ok_or_else(|| bad("split_axis", format!("{} is not an axis", fixed.split_axis)))?;
                if fixed.split_order > 2 {
                    return Err(bad("split_order", format!("{} is not 0, 1 or 2", fixed.split_order)));
                }
                let (overlap, gap) = (fixed.split_overlap.get(), fixed.split_gap.get());
                if !overlap.is_finite() || overlap < 0.0 || !gap.is_finite() {
                    return Err(bad("split_overlap", format!("overlap {overlap}, gap {gap}")));
                }
                let c = |b: &U32, s: &U16, c: &U32, a: &[F32; 6]| ChildRef {
                    block: b.get(),
                    slot: s.get(),
                    checksum: c.get(),
                    aabb: a.map(|x| x.get()),
                };
                let kids = [
                    c(&fixed.child0_block, &fixed.child0_slot, &fixed.child0_checksum, &fixed.child0_box),
                    c(&fixed.child1_block, &fixed.child1_slot, &fixed.child1_checksum, &fixed.child1_box),
                ];
                if kids.iter().any(|k| k.block == 0) {
                    return Err(bad("child_block", "an internal node points to block 0".into()));
                }
                if let Some(k) = kids.iter().find(|k| {
                    k.aabb.iter().any(|x| !x.is_finite()) || (0..3).any(|i| k.aabb[i] > k.aabb[i + 3])
                }) {
                    return Err(bad("child_box", format!("{:?} is not a box", k.aabb)));
                }
                Some((kids, SplitInfo { axis, order: fixed.split_order, overlap, gap }))
            }
            2 => {
                let rest = &fixed.as_bytes()[5..8];
                let kids = &fixed.as_bytes()[32..40];
                let links = &fixed.as_bytes()[48..68];
                let boxes = &fixed.as_bytes()[72..120];
                if !all_zero(rest) || !all_zero(kids) || !all_zero(links) || !all_zero(boxes) {
                    return Err(bad("kind", "a leaf carries split or child fields".into()));
                }
                None
            }
            k => return Err(bad("kind", format!("{k} is neither internal (1) nor leaf (2)"))),
        };
        let lods: Vec<[LodRef; 2]> = (0..lod_levels as usize)
            .map(|k| {
                let at = FIXED_LEN + k * LOD_PAIR_LEN;
                let pair = <[LodEntryRaw; 2]>::ref_from_bytes(&bytes[at..at + LOD_PAIR_LEN])
                    .map_err(|_| bad("lods", "short".into()))?;
                let dec = |e: &LodEntryRaw| {
                    LodRef::decode(e).ok_or_else(|| bad("lods", format!("bad entry at k = {}", k + 1)))
                };
                Ok([dec(&pair[0])?, dec(&pair[1])?])
            })
            .collect::<Result<_, StorageError>>()?;
        check_entries(&lods, children.is_none()).map_err(|d| bad("lods", d))?;
        Ok(NodeRecord {
            node_id: fixed.node_id.get(),
            aabb,
            level: fixed.level.get(),
            object_count,
            children,
            lods,
        })
    }
}

/// The rules that tie a record's entries together (format-spec/node.md): a
/// `Same` names a stored entry of another level or kind, `InRecord` is only
/// b(S_n,1), a leaf has no children to spread over.
fn check_entries(lods: &[[LodRef; 2]], leaf: bool) -> Result<(), String> {
    for (k, pair) in lods.iter().enumerate() {
        for (j, e) in pair.iter().enumerate() {
            let at = || format!("k = {}, {}", k + 1, if j == 1 { "objects" } else { "group" });
            match *e {
                LodRef::Same { level, objects } => {
                    let target = lods.get(usize::from(level) - 1).map(|p| p[usize::from(objects)]);
                    if (usize::from(level) - 1, usize::from(objects)) == (k, j)
                        || matches!(target, None | Some(LodRef::Same { .. } | LodRef::Absent))
                    {
                        return Err(format!("{}: names level {level}, which is not stored", at()));
                    }
                }
                LodRef::InRecord if (k, j) != (0, 0) => {
                    return Err(format!("{}: only b(S_n,1) is the record's box", at()));
                }
                LodRef::Spread { .. } if leaf => return Err(format!("{}: a leaf has no children", at())),
                _ => {}
            }
        }
    }
    Ok(())
}

/// Writes `records` into a node block's payload.
pub fn encode_block(records: &[NodeRecord], lod_levels: u8, block: &mut [u8]) {
    let size = record_size(lod_levels);
    let h = NodeBlockHeader {
        record_count: (records.len() as u16).into(),
        record_size: (size as u16).into(),
        reserved: [0; 4],
    };
    block[FRAME_LEN..RECORDS_START].copy_from_slice(h.as_bytes());
    for (i, r) in records.iter().enumerate() {
        let at = RECORDS_START + i * size;
        r.encode(&mut block[at..at + size]);
    }
}

/// Decodes every record of node block `id` (checksum already verified),
/// checking each against the format's rules.
pub fn decode_block(id: u32, block: &[u8], lod_levels: u8) -> Result<Vec<NodeRecord>, StorageError> {
    let h = NodeBlockHeader::read_from_bytes(&block[FRAME_LEN..RECORDS_START])
        .map_err(|_| StorageError::corrupt(id, "node block", "too small"))?;
    let (count, size) = (h.record_count.get() as usize, h.record_size.get() as usize);
    if size != record_size(lod_levels) {
        return Err(StorageError::corrupt(
            id,
            "record_size",
            format!("{size}, expected {}", record_size(lod_levels)),
        ));
    }
    let end = RECORDS_START + count * size;
    if count == 0 || end > block.len() {
        return Err(StorageError::corrupt(id, "record_count", format!("{count} records of {size} bytes")));
    }
    if h.reserved != [0; 4] || !all_zero(&block[end..]) {
        return Err(StorageError::corrupt(id, "reserved", "reserved bytes are not zero"));
    }
    (0..count)
        .map(|i| {
            let at = RECORDS_START + i * size;
            let r = NodeRecord::decode(id, i as u32, &block[at..at + size], lod_levels)?;
            if let Some((kids, _)) = &r.children
                && let Some(k) = kids.iter().find(|k| k.block == id && usize::from(k.slot) >= count)
            {
                return Err(StorageError::corrupt_record(
                    id,
                    i as u32,
                    "child_slot",
                    format!("{} >= {count}", k.slot),
                ));
            }
            Ok(r)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_round_trip() {
        let leaf = NodeRecord {
            node_id: 2,
            aabb: [0.0, 1.0, 2.0, 3.0, 4.0, 5.0],
            level: 1,
            object_count: 3,
            children: None,
            lods: vec![[LodRef::Absent; 2], [LodRef::InBlock { block: 9, offset: 16, checksum: 5 }; 2]],
        };
        let inner = NodeRecord {
            node_id: 0,
            aabb: [0.0, 0.0, 0.0, 9.0, 9.0, 9.0],
            level: 0,
            object_count: 6,
            children: Some((
                [
                    ChildRef { block: 3, slot: 1, checksum: 0, aabb: [0.0, 1.0, 2.0, 3.0, 4.0, 5.0] },
                    ChildRef { block: 4, slot: 0, checksum: 77, aabb: [1.0; 6] },
                ],
                SplitInfo { axis: Axis::Y, order: 1, overlap: 0.5, gap: 0.5 },
            )),
            lods: vec![[LodRef::Absent; 2], [LodRef::Spread { reads: 4 }; 2]],
        };
        let mut block = vec![0u8; 1024];
        encode_block(&[inner.clone(), leaf.clone()], 2, &mut block);
        assert_eq!(decode_block(3, &block, 2).unwrap(), vec![inner, leaf]);
        assert!(decode_block(3, &block, 3).is_err(), "record size follows M");
    }
}
