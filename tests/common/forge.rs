//! Byte-level access to a file image, after format-spec/ (node.md, meta.md,
//! header.md): find records and bounds, and after changing a block's bytes
//! make every checksum that vouches for it match again, up the chain to the
//! committed slot, so that a reader gets past the checksums to the forged
//! content.

use mktree::store::format::frame::{BlockType, seal};
use mktree::store::format::header::{Commit, SlotRead, SlotState, decode_slots, put_slot};
use mktree::store::format::keys::{self, KeyBlock};

/// A file's bytes in blocks of `bs` bytes.
pub struct Image {
    pub bytes: Vec<u8>,
    pub bs: usize,
}

fn u16_at(b: &[u8], at: usize) -> usize {
    usize::from(u16::from_le_bytes([b[at], b[at + 1]]))
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

impl Image {
    /// Blocks whose frame says type `t`.
    pub fn blocks_of(&self, t: BlockType) -> Vec<usize> {
        (1..self.bytes.len() / self.bs).filter(|&i| self.bytes[i * self.bs + 4] == t as u8).collect()
    }

    /// Absolute offsets of the records of node block `b` (node.md: the
    /// record count at 20, records from 32, each sized by its head).
    pub fn records(&self, b: usize) -> Vec<usize> {
        let base = b * self.bs;
        let mut at = base + 32;
        (0..u16_at(&self.bytes, base + 20))
            .map(|_| {
                let r = at;
                at += self.record_len(r);
                r
            })
            .collect()
    }

    /// Bytes of the record at `r`: an internal record's 84, or a leaf's
    /// head, span checksums, objects, `end`, bounds and keys.
    pub fn record_len(&self, r: usize) -> usize {
        let f = &self.bytes;
        match f[r] {
            1 => 84,
            2 => {
                let (n, s) = (u16_at(f, r + 2), u16_at(f, r + 12));
                20 + 4 * s + 20 * n + 4 + u32_at(f, r + 16) as usize + u16_at(f, r + 14)
            }
            k => panic!("record kind {k} at {r}"),
        }
    }

    /// Every leaf record: (node block, absolute offset).
    pub fn leaves(&self) -> Vec<(usize, usize)> {
        self.blocks_of(BlockType::Node)
            .into_iter()
            .flat_map(|b| self.records(b).into_iter().map(move |r| (b, r)))
            .filter(|&(_, r)| self.bytes[r] == 2)
            .collect()
    }

    /// Absolute offsets of a leaf record's object entries (20 bytes each:
    /// `object_id` u32, `qbox` [u16; 6], `position` u32).
    pub fn leaf_entries(&self, r: usize) -> Vec<usize> {
        let (n, s) = (u16_at(&self.bytes, r + 2), u16_at(&self.bytes, r + 12));
        (0..n).map(|i| r + 20 + 4 * s + 20 * i).collect()
    }

    /// Where the geometry record of the object entry at `e` of the leaf at
    /// `r` starts (geometry.md: stream position `position` * 4 of the span
    /// from `first_block`, P = bs - 16 bytes a block): (block, absolute offset).
    pub fn record_of(&self, r: usize, e: usize) -> (usize, usize) {
        let p = self.bs - 16;
        let first = u32_at(&self.bytes, r + 8) as usize;
        let at = u32_at(&self.bytes, e + 16) as usize * 4;
        let b = first + at / p;
        (b, b * self.bs + 16 + at % p)
    }

    /// A leaf record's bound entries: (target, level, absolute blob offset,
    /// blob length). Each entry is a 4-byte head (`target` u16, then
    /// `level_bytes` u16: the level in bits 0-3, the blob's length in bits
    /// 4-15) and its blob, unpadded; fewer than 4 bytes left are the area's
    /// zero padding.
    pub fn leaf_bounds(&self, r: usize) -> Vec<(usize, u8, usize, usize)> {
        let f = &self.bytes;
        let (n, s) = (u16_at(f, r + 2), u16_at(f, r + 12));
        let mut at = r + 20 + 4 * s + 20 * n + 4;
        let end = at + u32_at(f, r + 16) as usize;
        let mut out = Vec::new();
        while at + 4 <= end {
            let level_bytes = u16_at(f, at + 2);
            let len = level_bytes >> 4;
            out.push((u16_at(f, at), (level_bytes & 0xf) as u8, at + 4, len));
            at += 4 + len;
        }
        assert!(end >= at && f[at..end].iter().all(|&b| b == 0), "the bounds' padding at {at}");
        out
    }

    /// The committed slot with the larger transaction id, and its commit.
    fn committed(&self) -> (usize, Commit) {
        decode_slots(&self.bytes)
            .iter()
            .enumerate()
            .filter_map(|(i, p)| match p.value() {
                SlotRead::Committed(c) => Some((i, c)),
                _ => None,
            })
            .max_by_key(|(_, c)| c.txn)
            .expect("a committed slot")
    }

    /// The committed meta block.
    pub fn meta(&self) -> usize {
        self.committed().1.meta_block as usize
    }

    fn seal(&mut self, b: usize, t: BlockType) -> u32 {
        let at = b * self.bs;
        let txn = u64::from_le_bytes(self.bytes[at + 8..at + 16].try_into().unwrap());
        seal(b as u32, &mut self.bytes[at..at + self.bs], t, txn)
    }

    /// Re-seals block `b` as type `t` and every checksum up the chain that
    /// vouches for it: a node block's parent entries (or the meta block's
    /// `root_checksum`), a geometry block's entry in its leaf's span, the
    /// meta block's in the committed slot.
    /// Block `b` itself is never parsed: its bytes may be the forgery.
    pub fn reseal(&mut self, b: usize, t: BlockType) {
        self.reseal_above(b, t, b);
    }

    fn reseal_above(&mut self, b: usize, t: BlockType, forged: usize) {
        let sum = self.seal(b, t);
        let meta = self.meta();
        match t {
            BlockType::Meta => {
                let (i, c) = self.committed();
                let c = Commit { meta_checksum: sum, ..c };
                put_slot(&mut self.bytes, i, SlotState::Committed, &c);
            }
            BlockType::Node | BlockType::Geometry | BlockType::Group => {
                let mut parents = Vec::new();
                // A group block is vouched for by its node block's head (group_block at 24, its checksum at 28).
                for p in self.blocks_of(BlockType::Node).into_iter().filter(|&p| p != forged) {
                    let head = p * self.bs + 24;
                    if t == BlockType::Group && u32_at(&self.bytes, head) == b as u32 {
                        self.bytes[head + 4..head + 8].copy_from_slice(&sum.to_le_bytes());
                        parents.push(p);
                    }
                }
                for p in self.blocks_of(BlockType::Node).into_iter().filter(|&p| p != forged) {
                    for r in self.records(p) {
                        for at in self.references(r, b) {
                            self.bytes[at..at + 4].copy_from_slice(&sum.to_le_bytes());
                            parents.push(p);
                        }
                    }
                }
                parents.sort_unstable();
                parents.dedup();
                for p in parents {
                    self.reseal_above(p, BlockType::Node, forged);
                }
                let root = meta * self.bs + 16;
                if t == BlockType::Node && u32_at(&self.bytes, root) == b as u32 {
                    self.bytes[root + 4..root + 8].copy_from_slice(&sum.to_le_bytes());
                    self.reseal_above(meta, BlockType::Meta, forged);
                }
            }
            BlockType::KeyLeaf | BlockType::KeyBranch => {
                // Branches are re-encoded with the new checksum (the encoding is canonical).
                for p in self.blocks_of(BlockType::KeyBranch).into_iter().filter(|&p| p != forged) {
                    let at = p * self.bs;
                    let Ok(KeyBlock::Branch(mut children)) =
                        keys::decode(p as u32, &self.bytes[at..at + self.bs], false)
                    else {
                        continue;
                    };
                    if let Some(c) = children.iter_mut().find(|c| c.block == b as u32) {
                        c.checksum = sum;
                        keys::encode_branch(&children, &mut self.bytes[at..at + self.bs]).unwrap();
                        self.reseal_above(p, BlockType::KeyBranch, forged);
                    }
                }
                let root = meta * self.bs + 904;
                if u32_at(&self.bytes, root) == b as u32 {
                    self.bytes[root + 4..root + 8].copy_from_slice(&sum.to_le_bytes());
                    self.reseal_above(meta, BlockType::Meta, forged);
                }
            }
            other => panic!("no chain for {other:?} blocks here"),
        }
    }

    /// Where record `r` holds block `b`'s checksum: a child entry naming
    /// it, or a leaf span's entry for it.
    fn references(&self, r: usize, b: usize) -> Vec<usize> {
        let f = &self.bytes;
        match f[r] {
            1 => (0..2)
                .map(|c| r + 20 + 32 * c)
                .filter(|&e| u32_at(f, e + 12) == b as u32)
                .map(|e| e + 16)
                .collect(),
            _ => {
                let (first, span) = (u32_at(f, r + 8) as usize, u16_at(f, r + 12));
                (first..first + span).zip(0..).filter(|&(g, _)| g == b).map(|(_, i)| r + 20 + 4 * i).collect()
            }
        }
    }
}

/// The golden file (format-spec/example.md: one node block holds the root
/// record, offset 32, and its two leaves; slot 1 holds the commit) with the
/// root's first child pointed back at the root, and, if given, the meta
/// block's `node_count` forged; every checksum resealed.
pub fn golden_with_looping_root(node_count: Option<u32>) -> Vec<u8> {
    let mut f = std::fs::read(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/golden/tiny-v10.mkt")).unwrap();
    let block = |i: usize| i * 1024..(i + 1) * 1024;
    let of_type = |f: &[u8], t: BlockType| (1..f.len() / 1024).find(|&i| f[i * 1024 + 4] == t as u8).unwrap();
    let (node, meta) = (of_type(&f, BlockType::Node), of_type(&f, BlockType::Meta));
    let txn = 2;
    // The root is an internal record (kind 1) at offset 32; its first child
    // entry starts at 20 in the record and names its record by `offset` at
    // 20 in the entry, with `block` 0 (this block): point it at the root.
    let root = node * 1024 + 32;
    assert_eq!(f[root], 1, "the root is an internal record");
    let entry = root + 20;
    assert_eq!(&f[entry + 12..entry + 16], &[0; 4], "the first child lives in the root's block");
    f[entry + 20..entry + 24].copy_from_slice(&32u32.to_le_bytes());
    let root_sum = seal(node as u32, &mut f[block(node)], BlockType::Node, txn);
    // The meta block holds the root block's checksum at offset 20, `node_count` at 32.
    f[meta * 1024 + 20..meta * 1024 + 24].copy_from_slice(&root_sum.to_le_bytes());
    if let Some(n) = node_count {
        f[meta * 1024 + 32..meta * 1024 + 36].copy_from_slice(&n.to_le_bytes());
    }
    let meta_sum = seal(meta as u32, &mut f[block(meta)], BlockType::Meta, txn);
    let SlotRead::Committed(c) = decode_slots(&f)[1].value() else { panic!("slot 1") };
    put_slot(&mut f, 1, SlotState::Committed, &Commit { meta_checksum: meta_sum, ..c });
    f
}
