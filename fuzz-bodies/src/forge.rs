//! A forger's view of a file image, after format-spec/: where each block's
//! checksum is vouched for (the commit slots name the meta and first
//! free-list blocks, the meta block the root node block and the names run,
//! node records their children's blocks and their leaves' geometry blocks,
//! a run or a free list each next block), and a re-seal that makes every
//! checksum up those chains match again after bytes were changed, as an
//! attacker who knows the format would. Nothing here trusts the image: a
//! reference that leaves it is skipped, and a chain that loops is sealed
//! once (its stale link is for the reader to catch).

use mktree::store::format::frame::block_checksum;
use mktree::store::format::header::{SLOT_LEN, SlotRead, decode_slots, slot_offset};

/// How a block is read, as its referrer expects it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    Meta,
    Node,
    Geometry,
    FreeList,
    /// A group-bound block (format-spec/group.md), named from a node block's head.
    Group,
    /// A key index block `level` levels above the leaves (0: a key leaf).
    Key {
        level: u32,
    },
}

/// Where block `target`'s checksum is held: the 4 bytes at `field`
/// (absolute), in a block that reads `target` as `kind`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Reference {
    pub field: usize,
    pub target: u32,
    pub kind: Kind,
}

/// A record of a node block, as its bytes describe it (absolute offsets).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Record {
    Internal { at: usize },
    Leaf(LeafAt),
}

/// A leaf record's layout (format-spec/node.md), absolute offsets.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LeafAt {
    pub at: usize,
    pub objects: usize,
    pub span: usize,
    /// The span blocks' checksums (after the record's own frame, if any).
    pub sums_at: usize,
    /// The first object entry.
    pub objects_at: usize,
    /// The `end` word, just after the object entries.
    pub end_at: usize,
    /// The bounds area and its length.
    pub bounds_at: usize,
    pub bounds_len: usize,
    /// The keys area (after the bounds) and its length.
    pub keys_at: usize,
    pub keys_len: usize,
}

impl Record {
    pub fn at(&self) -> usize {
        match self {
            Record::Internal { at } => *at,
            Record::Leaf(l) => l.at,
        }
    }
}

/// An entry of a key block (format-spec/keys.md), absolute offsets.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct KeyEntryAt {
    /// Where the entry starts.
    pub at: usize,
    /// Its key's stored form and length (none for a branch's first child).
    pub key: Option<(usize, usize)>,
    /// A leaf entry's payload length word; its payload follows.
    pub payload: Option<usize>,
    /// A leaf entry's name length word; its name follows.
    pub name: Option<usize>,
    /// The fixed part: a leaf's object id, path bits, path length,
    /// reserved and box; a branch's child block and checksum.
    pub fixed: usize,
    /// Just past the entry.
    pub end: usize,
}

/// A bound entry of a leaf (format-spec/node.md, "Bounds"): its head and blob.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BoundAt {
    pub head: usize,
    pub target: u16,
    pub level: u8,
    pub blob: usize,
    pub len: usize,
}

const INTERNAL_LEN: usize = 84;
const FRAME_BOX_LEN: usize = 48;
/// Node block records start after the frame and the 16-byte head (format-spec/node.md, version 9).
const RECORDS_START: usize = 32;

/// A file's bytes in blocks of `bs` bytes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Image {
    pub bytes: Vec<u8>,
    pub bs: usize,
}

impl Image {
    /// Whole blocks in the image.
    pub fn blocks(&self) -> u32 {
        u32::try_from(self.bytes.len() / self.bs).unwrap_or(u32::MAX)
    }

    /// The absolute offset of block `id`, when the image holds it.
    pub fn base(&self, id: u32) -> Option<usize> {
        (id >= 1 && id < self.blocks()).then(|| id as usize * self.bs)
    }

    pub fn u8(&self, at: usize) -> u8 {
        self.bytes.get(at).copied().unwrap_or(0)
    }

    pub fn u16(&self, at: usize) -> u16 {
        u16::from_le_bytes([self.u8(at), self.u8(at + 1)])
    }

    pub fn u32(&self, at: usize) -> u32 {
        u32::from_le_bytes([self.u8(at), self.u8(at + 1), self.u8(at + 2), self.u8(at + 3)])
    }

    pub fn u64(&self, at: usize) -> u64 {
        u64::from(self.u32(at)) | u64::from(self.u32(at + 4)) << 32
    }

    /// Writes `bytes` at `at`, as much of them as the image holds.
    pub fn put(&mut self, at: usize, bytes: &[u8]) {
        if let Some(dst) = self.bytes.get_mut(at..) {
            let n = dst.len().min(bytes.len());
            dst[..n].copy_from_slice(&bytes[..n]);
        }
    }

    pub fn put_u32(&mut self, at: usize, v: u32) {
        self.put(at, &v.to_le_bytes());
    }

    /// The records of node block `id` as its head and record heads lay them
    /// out, up to the first that does not fit.
    pub fn records(&self, id: u32) -> Vec<Record> {
        let Some(base) = self.base(id) else { return Vec::new() };
        let used = self.u32(base + 16) as usize;
        let end = (base + RECORDS_START).saturating_add(used).min(base + self.bs);
        let mut out = Vec::new();
        let mut at = base + RECORDS_START;
        for _ in 0..self.u16(base + 20) {
            // A record with a frame of its own holds it after its fixed head.
            let len = match self.u8(at) {
                1 => INTERNAL_LEN + FRAME_BOX_LEN * usize::from(self.u8(at + 2) & 1),
                2 => {
                    let (n, span) = (usize::from(self.u16(at + 2)), usize::from(self.u16(at + 12)));
                    let sums_at = at + 20 + FRAME_BOX_LEN * usize::from(self.u8(at + 1) & 1);
                    let objects_at = sums_at + 4 * span;
                    let end_at = objects_at + 20 * n;
                    let bounds_at = end_at + 4;
                    let bounds_len = self.u32(at + 16) as usize;
                    let keys_at = bounds_at.saturating_add(bounds_len);
                    let keys_len = usize::from(self.u16(at + 14));
                    let leaf = LeafAt {
                        at,
                        objects: n,
                        span,
                        sums_at,
                        objects_at,
                        end_at,
                        bounds_at,
                        bounds_len,
                        keys_at,
                        keys_len,
                    };
                    let len = keys_at.saturating_add(keys_len) - at;
                    if at.saturating_add(len) <= end {
                        out.push(Record::Leaf(leaf));
                    }
                    len
                }
                _ => break,
            };
            if at.saturating_add(len) > end {
                break;
            }
            if self.u8(at) == 1 {
                out.push(Record::Internal { at });
            }
            at += len;
        }
        out
    }

    /// The bound entries of a leaf's bounds area, while their heads and
    /// blobs fit it.
    pub fn bounds(&self, leaf: &LeafAt) -> Vec<BoundAt> {
        let end = leaf.bounds_at + leaf.bounds_len;
        let mut at = leaf.bounds_at;
        let mut out = Vec::new();
        while at + 4 <= end {
            let lb = self.u16(at + 2);
            let len = usize::from(lb >> 4);
            if at + 4 + len > end {
                break;
            }
            out.push(BoundAt { head: at, target: self.u16(at), level: (lb & 0xf) as u8, blob: at + 4, len });
            at += 4 + len;
        }
        out
    }

    /// The references block `id`, read as `kind`, holds.
    pub fn references(&self, id: u32, kind: Kind) -> Vec<Reference> {
        let Some(base) = self.base(id) else { return Vec::new() };
        let r = |field: usize, target: u32, kind: Kind| Reference { field, target, kind };
        match kind {
            Kind::Meta => {
                let mut out = vec![r(base + 20, self.u32(base + 16), Kind::Node)];
                let (keys, height) = (self.u32(base + 904), self.u32(base + 912));
                if keys != 0 && height >= 1 {
                    out.push(r(base + 908, keys, Kind::Key { level: height - 1 }));
                }
                out
            }
            Kind::Node => {
                let mut out = Vec::new();
                // The head's group block (at 24) and its checksum (at 28).
                let group = self.u32(base + 24);
                if group != 0 {
                    out.push(r(base + 28, group, Kind::Group));
                }
                for rec in self.records(id) {
                    match rec {
                        Record::Internal { at } => {
                            for c in 0..2 {
                                let e = at + 20 + 32 * c;
                                let b = self.u32(e + 12);
                                if b != 0 {
                                    out.push(r(e + 16, b, Kind::Node));
                                }
                            }
                        }
                        Record::Leaf(l) => {
                            let first = self.u32(l.at + 8);
                            for i in 0..l.span {
                                if let Some(g) = u32::try_from(i).ok().and_then(|i| first.checked_add(i)) {
                                    out.push(r(l.sums_at + 4 * i, g, Kind::Geometry));
                                }
                            }
                        }
                    }
                }
                out
            }
            Kind::FreeList => match self.u32(base + 16) {
                0 => Vec::new(),
                next => vec![r(base + 20, next, Kind::FreeList)],
            },
            Kind::Key { level } => self.key_references(base, level),
            Kind::Geometry | Kind::Group => Vec::new(),
        }
    }

    /// A key block's references (format-spec/keys.md): a branch's
    /// children (a leaf's entries name no block).
    fn key_references(&self, base: usize, level: u32) -> Vec<Reference> {
        if level == 0 {
            return Vec::new();
        }
        self.key_entries(base, true)
            .into_iter()
            .map(|at| Reference { field: at + 4, target: self.u32(at), kind: Kind::Key { level: level - 1 } })
            .collect()
    }

    /// Where each entry of the key block at `base` has its fixed part (a
    /// leaf's: the object id, node block, checksum, record offset, ...; a
    /// branch's: the child's block and checksum), while entries fit its
    /// used bytes.
    fn key_entries(&self, base: usize, branch: bool) -> Vec<usize> {
        self.key_block_entries(base, branch).into_iter().map(|e| e.fixed).collect()
    }

    /// The stored length of the key at `at` (format-spec/keys.md): none for an unknown tag.
    pub fn key_len(&self, at: usize) -> Option<usize> {
        match self.u8(at) {
            0 => Some(9),
            1 => Some(2 + usize::from(self.u8(at + 1))),
            _ => None,
        }
    }

    /// The entries of the key block at `base` (absolute) as its head lays
    /// them out, while they fit its used bytes and the block.
    pub fn key_block_entries(&self, base: usize, branch: bool) -> Vec<KeyEntryAt> {
        let end = (base + 24).saturating_add(self.u32(base + 20) as usize).min(base + self.bs);
        let mut out = Vec::new();
        let mut at = base + 24;
        for i in 0..self.u16(base + 16) {
            let (key, payload, name, fixed, next) = if branch {
                let key = if i == 0 { None } else { Some(self.key_len(at)) };
                let Some(k) = key.unwrap_or(Some(0)) else { break };
                (key.map(|_| (at, k)), None, None, at + k, at + k + 8)
            } else {
                let Some(k) = self.key_len(at) else { break };
                let name = at + k + 2 + usize::from(self.u16(at + k));
                let fixed = name + 2 + usize::from(self.u16(name));
                (Some((at, k)), Some(at + k), Some(name), fixed, fixed + 64)
            };
            if next > end {
                break;
            }
            out.push(KeyEntryAt { at, key, payload, name, fixed, end: next });
            at = next;
        }
        out
    }

    /// The keys of a leaf record's keys area (format-spec/node.md, "Keys"):
    /// (offset, stored length), while they fit the area.
    pub fn stored_keys(&self, leaf: &LeafAt) -> Vec<(usize, usize)> {
        let end = leaf.keys_at.saturating_add(leaf.keys_len);
        let mut out = Vec::new();
        let mut at = leaf.keys_at;
        while let Some(k) = self.key_len(at).filter(|k| at + k <= end) {
            out.push((at, k));
            at += k;
        }
        out
    }

    /// The slot copies in use: (slot, copy, absolute offset), all-zero (empty) ones left out.
    pub fn slot_copies(&self) -> Vec<(usize, usize, usize)> {
        let mut out = Vec::new();
        for copy in 0..2 {
            for slot in 0..2 {
                let at = slot_offset(slot, copy);
                if self.bytes.get(at..at + SLOT_LEN).is_some_and(|s| s.iter().any(|&b| b != 0)) {
                    out.push((slot, copy, at));
                }
            }
        }
        out
    }

    /// The committed slot in force (format-spec/commit.md): (slot, the
    /// absolute offset of its copy 0, its transaction).
    pub fn newest(&self) -> Option<(usize, usize, u64)> {
        let slots = decode_slots(self.bytes.get(..1024)?);
        (0..2)
            .filter_map(|i| match slots[i].value() {
                SlotRead::Committed(c) => Some((i, slot_offset(i, 0), c.txn)),
                _ => None,
            })
            .max_by_key(|s| s.2)
    }

    /// The absolute offset of the meta block of the commit in force.
    pub fn meta(&self) -> Option<usize> {
        self.newest().and_then(|(_, at, _)| self.base(self.u32(at + 12)))
    }

    /// Every block the slot copies reach, children before the blocks that
    /// hold their checksums, each once (the first way it is reached), with
    /// the references it holds.
    pub fn reachable(&self) -> Vec<(u32, Kind, Vec<Reference>)> {
        let mut roots = Vec::new();
        for (_, _, at) in self.slot_copies() {
            roots.push(Reference { field: at + 16, target: self.u32(at + 12), kind: Kind::Meta });
            roots.push(Reference { field: at + 28, target: self.u32(at + 24), kind: Kind::FreeList });
        }
        self.postorder(&roots)
    }

    /// The blocks `roots` reach, in postorder (see [`Image::reachable`]).
    pub fn postorder(&self, roots: &[Reference]) -> Vec<(u32, Kind, Vec<Reference>)> {
        let mut seen = vec![false; self.blocks() as usize];
        let mut order = Vec::new();
        let mut stack: Vec<(u32, Kind, Vec<Reference>, usize)> = Vec::new();
        let enter = |r: &Reference, seen: &mut Vec<bool>, stack: &mut Vec<_>| {
            if self.base(r.target).is_some() && !seen[r.target as usize] {
                seen[r.target as usize] = true;
                stack.push((r.target, r.kind, self.references(r.target, r.kind), 0));
            }
        };
        for root in roots {
            enter(root, &mut seen, &mut stack);
            while let Some(top) = stack.last_mut() {
                if let Some(&r) = top.2.get(top.3) {
                    top.3 += 1;
                    enter(&r, &mut seen, &mut stack);
                } else if let Some((id, kind, refs, _)) = stack.pop() {
                    order.push((id, kind, refs));
                }
            }
        }
        order
    }

    /// The checksum block `id` carries (0 past the image).
    pub fn carried(&self, id: u32) -> u32 {
        self.base(id).map_or(0, |b| self.u32(b))
    }

    /// Seals block `id`: its checksum over its id and bytes (format-spec/blocks.md).
    pub fn seal(&mut self, id: u32) {
        if let Some(b) = self.base(id) {
            let sum = block_checksum(id, &self.bytes[b..b + self.bs]);
            self.put_u32(b, sum);
        }
    }

    /// Makes every checksum match again: each reachable block's own, each
    /// referrer's copy of it (children first, so a parent holds its
    /// children's final checksums), the slot copies' checksums of the meta
    /// and free-list blocks and their own, and the fixed header's.
    pub fn reseal(&mut self) {
        for (id, _, refs) in self.reachable() {
            for r in refs {
                let sum = self.carried(r.target);
                self.put_u32(r.field, sum);
            }
            self.seal(id);
        }
        for (slot, copy, at) in self.slot_copies() {
            for (pointer, field) in [(at + 12, at + 16), (at + 24, at + 28)] {
                let target = self.u32(pointer);
                if target != 0 && self.base(target).is_some() {
                    let sum = self.carried(target);
                    self.put_u32(field, sum);
                }
            }
            self.seal_slot(slot, copy);
        }
        self.seal_header();
    }

    /// Seals copy `copy` of slot `slot` (format-spec/header.md).
    pub fn seal_slot(&mut self, slot: usize, copy: usize) {
        let at = slot_offset(slot, copy);
        let Some(bytes) = self.bytes.get(at..at + SLOT_LEN - 4) else { return };
        let mut h = crc32fast::Hasher::new();
        h.update(bytes);
        h.update(&(slot as u32).to_le_bytes());
        h.update(&(copy as u32).to_le_bytes());
        let sum = h.finalize();
        self.put_u32(at + SLOT_LEN - 4, sum);
    }

    /// Seals the fixed header: bytes 0 .. 508, then block 0's tail.
    pub fn seal_header(&mut self) {
        let Some(tail) = self.bytes.get(1024..self.bs) else { return };
        let mut h = crc32fast::Hasher::new();
        h.update(&self.bytes[..508]);
        h.update(tail);
        let sum = h.finalize();
        self.put_u32(508, sum);
    }

    /// Inserts (`delta` > 0) zero bytes or removes (`delta` < 0) bytes at
    /// absolute offset `at` of node block `id`, inside the record starting at
    /// `record`, shifting the records after it and every offset that names
    /// them: the block's `used_bytes`, its in-block child entries, other
    /// blocks' child entries into it, the meta block's root offset. False
    /// (and nothing changed) when the records would not fit the block.
    pub fn splice(&mut self, id: u32, record: usize, at: usize, delta: isize) -> bool {
        let Some(base) = self.base(id) else { return false };
        let used = self.u32(base + 16) as usize;
        let end = base + RECORDS_START + used;
        let Some(new_used) = used.checked_add_signed(delta) else { return false };
        if at < base + RECORDS_START || at > end || end > base + self.bs || new_used + RECORDS_START > self.bs
        {
            return false;
        }
        if delta < 0 && at + delta.unsigned_abs() > end {
            return false;
        }
        // Offsets of records after `record` move; the rest stay.
        let moved = |o: u32| (o as usize) > record - base && base + o as usize >= at;
        let shift = |o: u32| o.wrapping_add_signed(delta as i32);
        let mut fixes = Vec::new();
        for node in self.node_blocks() {
            for rec in self.records(node) {
                if let Record::Internal { at: r } = rec {
                    for c in 0..2 {
                        let e = r + 20 + 32 * c;
                        let (b, o) = (self.u32(e + 12), self.u32(e + 20));
                        let removed = delta < 0 && node == id && e >= at && e < at + delta.unsigned_abs();
                        if (b == id || (b == 0 && node == id)) && moved(o) && !removed {
                            // The entry itself moves with its record when it is after `at`.
                            let field = if node == id && e >= at { e.wrapping_add_signed(delta) } else { e };
                            fixes.push((field + 20, shift(o)));
                        }
                    }
                }
            }
        }
        // Key index entries name their object's leaf record by offset.
        for key_leaf in (1..self.blocks()).filter(|&b| self.base(b).is_some_and(|at| self.u8(at + 4) == 8)) {
            let Some(kb) = self.base(key_leaf) else { continue };
            for e in self.key_entries(kb, false) {
                if self.u32(e + 4) == id && moved(self.u32(e + 12)) {
                    fixes.push((e + 12, shift(self.u32(e + 12))));
                }
            }
        }
        // The block's group block names its records' group bounds by offset
        // (format-spec/group.md: entries of 12 bytes from 24, `record` first).
        if let Some(g) = self.base(self.u32(base + 24)).filter(|_| self.u32(base + 24) != 0) {
            for i in 0..usize::from(self.u16(g + 20)) {
                let e = g + 24 + 12 * i;
                if e + 4 <= g + self.bs && moved(self.u32(e)) {
                    fixes.push((e, shift(self.u32(e))));
                }
            }
        }
        for (_, _, slot) in self.slot_copies() {
            if let Some(meta) = self.base(self.u32(slot + 12))
                && self.u32(meta + 16) == id
                && moved(self.u32(meta + 24))
            {
                fixes.push((meta + 24, shift(self.u32(meta + 24))));
            }
        }
        let block = &mut self.bytes[base..base + self.bs];
        let (at, end) = (at - base, end - base);
        if delta > 0 {
            block.copy_within(at..end, at + delta as usize);
            block[at..at + delta as usize].fill(0);
        } else {
            let d = delta.unsigned_abs();
            block.copy_within(at + d..end, at);
            block[end - d..end].fill(0);
        }
        self.put_u32(base + 16, new_used as u32);
        for (field, v) in fixes {
            self.put_u32(field, v);
        }
        true
    }

    /// Blocks whose frame says node (type 2).
    pub fn node_blocks(&self) -> Vec<u32> {
        (1..self.blocks()).filter(|&b| self.base(b).is_some_and(|at| self.u8(at + 4) == 2)).collect()
    }
}
