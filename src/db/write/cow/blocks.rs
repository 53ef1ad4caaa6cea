//! The node blocks holding changed records written anew (format-spec/commit.md,
//! "Change commits"), children's blocks before their parent's, since a
//! block names its children's blocks and has one parent block
//! (format-spec/node.md, "Packing"). A block its records outgrow moves its
//! largest leaves out to new blocks.

use std::sync::Arc;

use rustc_hash::FxHashMap as HashMap;

use super::{Deltas, Mod, Step, Structural};
use crate::db::write::WriteTransaction;
use crate::store::format::frame::BlockType;
use crate::store::format::node::{self, NodeView, RecordDraft, RecordPart, RecordRef};
use crate::store::{Block, StorageError};
use crate::tree::view;

impl WriteTransaction<'_> {
    /// Writes every node block holding a changed record, children's blocks
    /// before their parent's (one parent block each, format-spec/node.md,
    /// "Packing"); returns where the root went.
    pub(super) fn rewrite_blocks(
        &mut self,
        mods: &mut HashMap<(u32, u32), Mod>,
        root_at: (u32, u32),
        bs: u32,
        deltas: &mut Deltas,
        freed: &mut Vec<u32>,
    ) -> Step<RecordRef> {
        let capacity = node::capacity(bs);
        let mut rw = Rewrite::of(mods, root_at);
        for b in rw.order() {
            let old = rw.blocks[&b].clone();
            let mut drafts = rw.records(&old, mods)?;
            let Some(bins) = rw.records_to_move(mods, b, &mut drafts, capacity)? else {
                return Ok(Err(Structural));
            };
            let (moving, kept): (Vec<_>, Vec<_>) =
                drafts.into_iter().partition(|(o, _)| bins.iter().any(|(_, records)| records.contains(o)));
            self.write_moved(&bins, moving, b, bs, deltas, &mut rw.relocated)?;
            self.write_block_anew(&old, kept, &mut rw.relocated, bs, deltas, freed)?;
        }
        let root = rw
            .relocated
            .get(&root_at)
            .copied()
            .ok_or_else(|| StorageError::Invalid("the root's block was not rewritten".into()))?;
        Ok(Ok(root))
    }

    /// Writes the new blocks `bins` of the records moved out of block `b`
    /// (`moving`), each reference they hold led to where its record went,
    /// and notes where each went.
    fn write_moved(
        &mut self,
        bins: &[Bin],
        mut moving: Vec<(u32, Rec)>,
        b: u32,
        bs: u32,
        deltas: &mut Deltas,
        relocated: &mut HashMap<(u32, u32), RecordRef>,
    ) -> Result<(), StorageError> {
        for (used, records) in bins {
            let (mut group, rest): (Vec<_>, Vec<_>) =
                moving.into_iter().partition(|(o, _)| records.contains(o));
            moving = rest;
            let new_offset = renumber(&mut group, b, relocated)?;
            let parts: Vec<RecordPart> = group.iter().map(|(_, d)| d.part()).collect();
            let (id, checksum, _) = self.write_node_block(&parts, bs)?;
            deltas.node_bytes += *used as i64;
            deltas.node_blocks += 1;
            for (o, _) in &group {
                relocated.insert((b, *o), RecordRef { block: id, checksum, offset: new_offset[o] });
            }
        }
        Ok(())
    }

    /// Writes the records `drafts` block `old` keeps in a new block, each
    /// reference they hold led to where its record went, and frees the old
    /// block; notes where each record went.
    fn write_block_anew(
        &mut self,
        old: &Block,
        mut drafts: Vec<(u32, Rec)>,
        relocated: &mut HashMap<(u32, u32), RecordRef>,
        bs: u32,
        deltas: &mut Deltas,
        freed: &mut Vec<u32>,
    ) -> Result<(), StorageError> {
        let b = old.id();
        let new_offset = renumber(&mut drafts, b, relocated)?;
        let records: Vec<RecordPart> = drafts.iter().map(|(_, d)| d.part()).collect();
        freed.push(b);
        // Its group bounds go with it: the subtrees below a rewritten
        // block changed, and the block written anew names no group block.
        if let Some((g, _)) = node::group_ref(old.bytes()) {
            freed.push(g);
        }
        if records.is_empty() {
            // Its records left the tree with a merge, and no record names the block.
            deltas.node_blocks -= 1;
            deltas.node_bytes -= old_used(old);
            return Ok(());
        }
        let (id, checksum, _) = self.write_node_block(&records, bs)?;
        let used = records.iter().map(RecordPart::encoded_len).sum::<usize>() as i64;
        deltas.node_bytes += used - old_used(old);
        for (o, _) in &drafts {
            relocated.insert((b, *o), RecordRef { block: id, checksum, offset: new_offset[o] });
        }
        Ok(())
    }

    /// Writes a new node block of `records`; returns its id, its checksum
    /// and the records' offsets.
    fn write_node_block(
        &mut self,
        records: &[RecordPart],
        bs: u32,
    ) -> Result<(u32, u32, Vec<u32>), StorageError> {
        let id = self.allocate(1)?;
        let mut bytes = vec![0u8; bs as usize];
        let offsets = node::encode_block_parts(records, &mut bytes).map_err(StorageError::Invalid)?;
        let checksum = self.put(id, &mut bytes, BlockType::Node)?;
        // The offsets are the ones validation finds (a test in the node
        // format holds them so), so the block is cached as verified.
        self.keep_for_cache(Block {
            id,
            checksum,
            bytes: bytes.into(),
            records: offsets.clone(),
            groups: Vec::new(),
        });
        Ok((id, checksum, offsets))
    }
}

/// The changed node blocks, and what rewriting them has settled so far.
struct Rewrite {
    /// Each changed block by id.
    blocks: HashMap<u32, Arc<Block>>,
    /// A changed block's parent block, when it is another block.
    parent_block: HashMap<u32, u32>,
    /// The root record's place.
    root_at: (u32, u32),
    /// Where each record of a block written so far went.
    relocated: HashMap<(u32, u32), RecordRef>,
    /// Node blocks records outside the changed paths gain below them (leaves moved out).
    extra: HashMap<(u32, u32), [u32; 2]>,
}

impl Rewrite {
    /// The blocks holding the records of `mods`, none written yet.
    fn of(mods: &HashMap<(u32, u32), Mod>, root_at: (u32, u32)) -> Self {
        let mut blocks: HashMap<u32, Arc<Block>> = HashMap::default();
        let mut parent_block: HashMap<u32, u32> = HashMap::default();
        for md in mods.values() {
            blocks.insert(md.block.id(), md.block.clone());
            if let Some((p, _)) = md.parent
                && p.0 != md.block.id()
            {
                parent_block.insert(md.block.id(), p.0);
            }
        }
        Rewrite { blocks, parent_block, root_at, relocated: HashMap::default(), extra: HashMap::default() }
    }

    /// The changed blocks, children blocks first: deeper blocks (more
    /// parent blocks above) first.
    fn order(&self) -> Vec<u32> {
        let depth = |mut b: u32| {
            let mut d = 0;
            while let Some(&p) = self.parent_block.get(&b) {
                b = p;
                d += 1;
                if d > self.blocks.len() {
                    break;
                }
            }
            d
        };
        let mut order: Vec<u32> = self.blocks.keys().copied().collect();
        order.sort_by_key(|&b| (std::cmp::Reverse(depth(b)), b));
        order
    }

    /// The records of block `old` as they will be written, but those a
    /// merge took out of the tree: changed ones and internal ones (whose
    /// child offsets may move) as drafts, the unchanged leaves as their
    /// stored bytes.
    fn records<'a>(
        &self,
        old: &'a Block,
        mods: &HashMap<(u32, u32), Mod>,
    ) -> Result<Vec<(u32, Rec<'a>)>, StorageError> {
        let b = old.id();
        let mut drafts: Vec<(u32, Rec)> = Vec::with_capacity(old.records.len());
        for &o in &old.records {
            if mods.get(&(b, o)).is_some_and(|x| x.gone) {
                continue;
            }
            let d = match mods.get(&(b, o)).and_then(|x| x.draft.clone()) {
                Some(d) => Rec::Draft(d),
                None => match view(old, o)? {
                    v @ NodeView::Leaf(_) => Rec::Stored(
                        v.stored_bytes(old.bytes(), o).map_err(|d| StorageError::corrupt(b, "record", d))?,
                    ),
                    v @ NodeView::Internal(_) => {
                        let mut d = v.to_draft();
                        if let (Some(more), RecordDraft::Internal { children, .. }) =
                            (self.extra.get(&(b, o)), &mut d)
                        {
                            for (c, m) in children.iter_mut().zip(more) {
                                c.node_blocks = c.node_blocks.saturating_add(*m);
                            }
                        }
                        Rec::Draft(d)
                    }
                },
            };
            drafts.push((o, d));
        }
        Ok(drafts)
    }

    /// What block `b` moves out so that the rest of its records `drafts`
    /// fit `capacity`, as new blocks of (bytes used, records); `None` when
    /// nothing can. Leaves go while they can make room, largest first: a
    /// leaf has no children, so no other block's parent block changes. A
    /// block whose internal records alone outgrow it (an upper block whose
    /// records took frames of their own) moves whole subtrees of its
    /// records instead ([`pieces`]).
    fn records_to_move(
        &mut self,
        mods: &mut HashMap<(u32, u32), Mod>,
        b: u32,
        drafts: &mut [(u32, Rec)],
        capacity: usize,
    ) -> Result<Option<Vec<Bin>>, StorageError> {
        let len = |d: &Rec| d.part().encoded_len();
        let mut total: usize = drafts.iter().map(|(_, d)| len(d)).sum();
        if total <= capacity {
            return Ok(Some(Vec::new()));
        }
        let leaves: usize = drafts.iter().filter(|(_, d)| d.is_leaf()).map(|(_, d)| len(d)).sum();
        // The records whose subtrees move: the leaves, or each piece's root.
        let (bins, tops) = if total - leaves <= capacity {
            // Largest first; of equal ones, the last in the block.
            let mut by_size: Vec<(usize, usize, u32)> = drafts
                .iter()
                .enumerate()
                .filter(|(_, (_, d))| d.is_leaf())
                .map(|(i, (o, d))| (len(d), i, *o))
                .collect();
            by_size.sort_by_key(|&(len, i, _)| std::cmp::Reverse((len, i)));
            let mut moved = Vec::new();
            for (size, _, o) in by_size {
                if total <= capacity {
                    break;
                }
                moved.push(o);
                total -= size;
            }
            (share_blocks(drafts, &moved, b, capacity), moved)
        } else {
            let Some(pieces) = pieces(drafts, b, capacity) else { return Ok(None) };
            let (bins, tops): (Vec<Bin>, Vec<Vec<u32>>) =
                pieces.into_iter().map(|p| ((p.bytes, p.records), p.tops)).unzip();
            (bins, tops.concat())
        };
        for &top in &tops {
            self.count_moved(mods, (b, top), drafts)?;
        }
        // The counts above changed drafts of this block too: take them again.
        for (o, d) in drafts.iter_mut() {
            if let Some(x) = mods.get(&(b, *o)).and_then(|x| x.draft.clone()) {
                *d = Rec::Draft(x);
            }
        }
        Ok(Some(bins))
    }

    /// Counts the node block record `moved` (with its subtree in the block)
    /// moves to in every entry above it: in the changed records' drafts, in
    /// those of its block (`drafts`), or for a record outside the changed
    /// paths in `extra`.
    fn count_moved(
        &mut self,
        mods: &mut HashMap<(u32, u32), Mod>,
        moved: (u32, u32),
        drafts: &mut [(u32, Rec)],
    ) -> Result<(), StorageError> {
        let b = moved.0;
        let mut at = moved;
        while let Some((p, c)) = match mods.get(&at) {
            Some(x) => x.parent,
            None if at == self.root_at => None,
            None => Some(parent_record(&self.blocks, &self.parent_block, at)?),
        } {
            // A child of a merged sibling counts under the record in its parent's place.
            let p = mods.get(&p).and_then(|x| x.merged_into).unwrap_or(p);
            if let Some(RecordDraft::Internal { children, .. }) =
                mods.get_mut(&p).and_then(|x| x.draft.as_mut())
            {
                children[c].node_blocks = children[c].node_blocks.saturating_add(1);
            } else if p.0 == b {
                if let Some((_, Rec::Draft(RecordDraft::Internal { children, .. }))) =
                    drafts.iter_mut().find(|(x, _)| *x == p.1)
                {
                    children[c].node_blocks = children[c].node_blocks.saturating_add(1);
                }
            } else {
                self.extra.entry(p).or_insert([0; 2])[c] += 1;
            }
            at = p;
        }
        Ok(())
    }
}

/// The leaves `moved` out of block `b` (their records in `drafts`) in new
/// blocks of `capacity`, as (bytes used, records): those whose parents
/// stay in this block share new blocks, first fit, so that each new block
/// is named from this one only (format-spec/node.md, "Packing"); a leaf
/// named from another block moves alone. The counts of
/// `Rewrite::records_to_move` took one block per leaf, which stays an
/// upper bound.
fn share_blocks(drafts: &[(u32, Rec)], moved: &[u32], b: u32, capacity: usize) -> Vec<Bin> {
    let named_here = |o: u32| {
        drafts.iter().any(|(_, d)| match d {
            Rec::Draft(RecordDraft::Internal { children, .. }) => {
                children.iter().any(|c| c.at.offset == o && (c.at.block == 0 || c.at.block == b))
            }
            _ => false,
        })
    };
    let mut bins: Vec<Bin> = Vec::new();
    for &o in moved {
        let Some((_, d)) = drafts.iter().find(|(x, _)| *x == o) else { continue };
        let len = d.part().encoded_len();
        let shared = named_here(o);
        match bins.iter_mut().find(|(used, records)| {
            shared && used + len <= capacity && records.iter().all(|&r| named_here(r))
        }) {
            Some((used, records)) => {
                *used += len;
                records.push(o);
            }
            None => bins.push((len, vec![o])),
        }
    }
    bins
}

/// A new node block of moved records: its bytes used, and the records.
type Bin = (usize, Vec<u32>);

/// Records that move out of a block together, to a block of their own.
struct Piece {
    /// Their bytes.
    bytes: usize,
    /// Those whose parents stay behind.
    tops: Vec<u32>,
    /// All of them, in block order.
    records: Vec<u32>,
}

/// Whole subtrees of block `b`'s records (records and every record below
/// them in the block) to move out, each piece to a block of its own, until
/// the rest of `drafts` fits `capacity`. Every block keeps one parent
/// block (format-spec/node.md, "Packing"): a piece takes in the subtree of
/// every other record that names one of its child blocks, its tops hang
/// from one block (this one, or its parent block), and no piece holds
/// another's parent. Of the pieces that fit a block and make room enough,
/// the one closest to half the records goes; else the largest, and again.
/// `None`: none fits.
fn pieces(drafts: &[(u32, Rec)], b: u32, capacity: usize) -> Option<Vec<Piece>> {
    let n = drafts.len();
    let index: HashMap<u32, usize> = drafts.iter().enumerate().map(|(i, (o, _))| (*o, i)).collect();
    let len: Vec<usize> = drafts.iter().map(|(_, d)| d.part().encoded_len()).collect();
    let mut kids: Vec<Vec<usize>> = vec![Vec::new(); n];
    let mut parent: Vec<Option<usize>> = vec![None; n];
    // The other blocks each record names, and the records naming each.
    let mut names: Vec<Vec<u32>> = vec![Vec::new(); n];
    let mut namers: HashMap<u32, Vec<usize>> = HashMap::default();
    for (i, (_, d)) in drafts.iter().enumerate() {
        let Rec::Draft(RecordDraft::Internal { children, .. }) = d else { continue };
        for c in children {
            match index.get(&c.at.offset) {
                Some(&j) if c.at.block == 0 || c.at.block == b => {
                    kids[i].push(j);
                    parent[j] = Some(i);
                }
                _ => {
                    names[i].push(c.at.block);
                    namers.entry(c.at.block).or_default().push(i);
                }
            }
        }
    }
    // The piece from `top`: its subtree, grown by the subtree of each other
    // namer of a block it names, until none is left out.
    let piece = |top: usize| {
        let mut member = vec![false; n];
        let mut stack = vec![top];
        while let Some(i) = stack.pop() {
            if std::mem::replace(&mut member[i], true) {
                continue;
            }
            stack.extend(&kids[i]);
            stack.extend(names[i].iter().flat_map(|x| &namers[x]));
        }
        (0..n).filter(|&i| member[i]).collect::<Vec<usize>>()
    };
    let mut total: usize = len.iter().sum();
    // In a piece taken, or above one.
    let mut taken = vec![false; n];
    let mut out = Vec::new();
    while total > capacity {
        let need = total - capacity;
        // (makes room enough, then nearest half or largest; tops; records)
        type Choice = ((bool, usize), Vec<usize>, Vec<usize>);
        let mut best: Option<Choice> = None;
        for top in (0..n).filter(|&i| !taken[i]) {
            let members = piece(top);
            let size: usize = members.iter().map(|&m| len[m]).sum();
            if size > capacity || members.iter().any(|&m| taken[m]) {
                continue;
            }
            let tops: Vec<usize> = members
                .iter()
                .copied()
                .filter(|&m| parent[m].is_none_or(|p| !members.contains(&p)))
                .collect();
            let hung_here = tops.iter().filter(|&&t| parent[t].is_some()).count();
            if hung_here != 0 && hung_here != tops.len() {
                continue;
            }
            let score =
                if size >= need { (true, usize::MAX - size.abs_diff(total / 2)) } else { (false, size) };
            if best.as_ref().is_none_or(|(s, _, _)| score > *s) {
                best = Some((score, tops, members));
            }
        }
        let (_, tops, members) = best?;
        for &t in &tops {
            let mut up = Some(t);
            while let Some(i) = up {
                taken[i] = true;
                up = parent[i];
            }
        }
        let size: usize = members.iter().map(|&m| len[m]).sum();
        for &m in &members {
            taken[m] = true;
        }
        total -= size;
        let offsets = |v: &[usize]| v.iter().map(|&m| drafts[m].0).collect::<Vec<u32>>();
        out.push(Piece { bytes: size, tops: offsets(&tops), records: offsets(&members) });
    }
    Some(out)
}

/// The offsets of the records `drafts` in block `b` written anew, and
/// every reference they hold led there: within the block, to moved
/// records, and to the children's rewritten blocks (`relocated`).
fn renumber(
    drafts: &mut [(u32, Rec)],
    b: u32,
    relocated: &HashMap<(u32, u32), RecordRef>,
) -> Result<HashMap<u32, u32>, StorageError> {
    let mut new_offset: HashMap<u32, u32> = HashMap::default();
    let mut at = node::RECORDS_START as u32;
    for (o, d) in drafts.iter() {
        new_offset.insert(*o, at);
        at += d.part().encoded_len() as u32;
    }
    for (_, d) in drafts.iter_mut() {
        let Rec::Draft(RecordDraft::Internal { children, .. }) = d else { continue };
        for c in children.iter_mut() {
            let target = if c.at.block == 0 { (b, c.at.offset) } else { (c.at.block, c.at.offset) };
            if let Some(r) = relocated.get(&target) {
                c.at = *r;
            } else if c.at.block == 0 {
                let o = new_offset.get(&c.at.offset).ok_or_else(|| {
                    StorageError::corrupt(b, "child_offset", "a child that is no record of its block")
                })?;
                c.at = RecordRef { block: 0, checksum: 0, offset: *o };
            }
        }
    }
    Ok(new_offset)
}

/// A record of a node block being rewritten: a draft, or an unchanged
/// leaf's stored bytes (in the old block, which the caller holds).
enum Rec<'a> {
    Draft(RecordDraft),
    Stored(&'a [u8]),
}

impl Rec<'_> {
    fn part(&self) -> RecordPart<'_> {
        match self {
            Rec::Draft(d) => RecordPart::Draft(d),
            Rec::Stored(b) => RecordPart::StoredLeaf(b),
        }
    }

    fn is_leaf(&self) -> bool {
        matches!(self, Rec::Stored(_) | Rec::Draft(RecordDraft::Leaf { .. }))
    }
}

/// The record naming record `at` (not the root) as its child, and which
/// child: in `at`'s block, or in that block's parent block.
fn parent_record(
    blocks: &HashMap<u32, Arc<Block>>,
    parent_block: &HashMap<u32, u32>,
    at: (u32, u32),
) -> Result<((u32, u32), usize), StorageError> {
    let same = blocks.get(&at.0).map(|b| (b, RecordRef { block: 0, checksum: 0, offset: at.1 }));
    let above = parent_block
        .get(&at.0)
        .and_then(|p| blocks.get(p))
        .map(|b| (b, RecordRef { block: at.0, checksum: 0, offset: at.1 }));
    for (block, want) in same.into_iter().chain(above) {
        for &o in &block.records {
            if let NodeView::Internal(n) = view(block, o)? {
                for c in 0..2 {
                    let r = n.child_ref(c);
                    if (r.block, r.offset) == (want.block, want.offset) {
                        return Ok(((block.id(), o), c));
                    }
                }
            }
        }
    }
    Err(StorageError::corrupt(at.0, "child_block", format!("no record names record {} of the block", at.1)))
}

/// Bytes of the records of node block `block`.
fn old_used(block: &Block) -> i64 {
    node::used_bytes(&block.bytes) as i64
}

#[cfg(test)]
mod tests {
    use std::collections::{BTreeMap, BTreeSet};

    use proptest::prelude::*;

    use super::*;
    use crate::geom::Axis;
    use crate::store::format::node::{ChildEntry, SplitInfo};

    static BYTES: [u8; 4096] = [0; 4096];
    /// The block the records are in.
    const B: u32 = 9_999;

    /// A child entry naming `block` (0: this block) at `offset`.
    fn child(block: u32, offset: u32) -> ChildEntry {
        ChildEntry {
            qbox: [0; 6],
            at: RecordRef { block, checksum: 0, offset },
            node_blocks: 0,
            geometry_blocks: 0,
        }
    }

    /// A block's records, built bottom up from `seed`: a leaf of up to
    /// `leaf_max` bytes, or an internal record whose two children are
    /// records made before it and not yet named, or any of `blocks` other
    /// blocks (shared between records). Those left unnamed are named from
    /// the parent block.
    fn block(seed: u64, records: usize, blocks: u32, leaf_max: usize) -> Vec<(u32, Rec<'static>)> {
        let mut s = seed | 1;
        let mut next = move |n: u64| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            s % n.max(1)
        };
        let mut made: Vec<(u32, Rec<'static>)> = Vec::new();
        let mut unnamed: Vec<u32> = Vec::new();
        for i in 0..records {
            let offset = 64 + 16 * i as u32;
            let rec = if next(3) == 0 {
                Rec::Stored(&BYTES[..16 + next(leaf_max as u64) as usize])
            } else {
                let mut pick = || {
                    if !unnamed.is_empty() && next(3) != 0 {
                        child(0, unnamed.swap_remove(next(unnamed.len() as u64) as usize))
                    } else {
                        child(1 + next(u64::from(blocks)) as u32, 64)
                    }
                };
                let children = [pick(), pick()];
                Rec::Draft(RecordDraft::Internal {
                    node_id: i as u32,
                    object_count: 2,
                    split: SplitInfo { axis: Axis::X, order: 0, overlap: 0.0, gap: 0.0 },
                    children,
                    frame: None,
                })
            };
            made.push((offset, rec));
            unnamed.push(offset);
        }
        made.reverse();
        made
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

        /// Whatever pieces a block moves out, the rest fits, each fits a
        /// block, and every block, old or new, keeps one parent block.
        #[test]
        fn pieces_leave_the_rest_fitting_and_every_block_one_parent_block(
            seed in any::<u64>(),
            records in 2usize..40,
            blocks in 1u32..8,
            leaf_max in 1usize..600,
            share in 0.2f64..1.0,
        ) {
            let drafts = block(seed, records, blocks, leaf_max);
            let len: BTreeMap<u32, usize> = drafts.iter().map(|(o, d)| (*o, d.part().encoded_len())).collect();
            let total: usize = len.values().sum();
            let capacity = ((total as f64 * share) as usize).max(1);
            let Some(pieces) = pieces(&drafts, B, capacity) else { return Ok(()) };
            // Where each record ends: 0 stays, k + 1 in piece k.
            let mut home: BTreeMap<u32, usize> = drafts.iter().map(|(o, _)| (*o, 0)).collect();
            for (k, p) in pieces.iter().enumerate() {
                prop_assert!(p.bytes <= capacity);
                prop_assert_eq!(p.bytes, p.records.iter().map(|o| len[o]).sum::<usize>());
                for o in &p.records {
                    prop_assert_eq!(home.insert(*o, k + 1), Some(0), "record {} in two pieces", o);
                }
            }
            let kept: usize = home.iter().filter(|(_, h)| **h == 0).map(|(o, _)| len[o]).sum();
            prop_assert!(kept <= capacity, "{} bytes left in a block of {}", kept, capacity);
            // Each block's namers, by where they end: the parent block is usize::MAX.
            let mut namers: BTreeMap<(u32, u32), BTreeSet<usize>> = BTreeMap::new();
            let mut named: BTreeSet<u32> = BTreeSet::new();
            for (o, d) in &drafts {
                let Rec::Draft(RecordDraft::Internal { children, .. }) = d else { continue };
                for c in children {
                    // A record of this block names a new block where its child went.
                    let target = if c.at.block == 0 {
                        named.insert(c.at.offset);
                        if home[&c.at.offset] == home[o] {
                            continue;
                        }
                        (0, home[&c.at.offset] as u32)
                    } else {
                        (c.at.block, 0)
                    };
                    namers.entry(target).or_default().insert(home[o]);
                }
            }
            for (o, h) in &home {
                if !named.contains(o) && *h != 0 {
                    namers.entry((0, *h as u32)).or_default().insert(usize::MAX);
                }
            }
            for ((block, piece), from) in &namers {
                prop_assert!(from.len() == 1, "block {} / piece {} named from {:?}", block, piece, from);
            }
        }
    }

    #[test]
    fn an_upper_block_of_internal_records_moves_a_subtree_out() {
        // A record over two, each over two other blocks: one of the two goes.
        let internal = |children| {
            Rec::Draft(RecordDraft::Internal {
                node_id: 0,
                object_count: 2,
                split: SplitInfo { axis: Axis::X, order: 0, overlap: 0.0, gap: 0.0 },
                children,
                frame: None,
            })
        };
        let drafts = vec![
            (64, internal([child(0, 200), child(0, 300)])),
            (200, internal([child(1, 64), child(2, 64)])),
            (300, internal([child(3, 64), child(4, 64)])),
        ];
        let total: usize = drafts.iter().map(|(_, d)| d.part().encoded_len()).sum();
        let moved = pieces(&drafts, B, total - 1).expect("a piece moves out");
        assert_eq!(moved.len(), 1);
        assert!(moved[0].records == [200] || moved[0].records == [300], "{:?}", moved[0].records);
        // Blocks 1 and 2 named from a record each of two: none can move alone.
        let drafts = vec![
            (64, internal([child(0, 200), child(0, 300)])),
            (200, internal([child(1, 64), child(2, 64)])),
            (300, internal([child(1, 64), child(2, 64)])),
        ];
        let moved = pieces(&drafts, B, total - 1).expect("both go together");
        assert_eq!(moved[0].records, [200, 300]);
        assert_eq!(moved[0].tops, [200, 300]);
    }
}
