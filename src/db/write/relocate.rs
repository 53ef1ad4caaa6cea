//! A compaction's move: the committed tree copied into new blocks as it is.
//! Every block it holds is read and verified against the checksum its
//! parent holds, then written under a new id. Only references change; a
//! block's checksum covers its id, so each parent's copy of a child's
//! checksum changes too, and children are written before their parents.
//! Nothing is laid out or computed again (the levels of detail, the
//! packing, the stored bounds stay as committed): a move costs the tree's
//! reads and writes, not a bulk load's work.

use std::collections::{BTreeMap, HashMap};

use super::WriteTransaction;
use crate::store::alloc::FreeSpace;
use crate::store::format::frame::BlockType;
use crate::store::format::group;
use crate::store::format::keys::{self, KeyBlock};
use crate::store::format::meta::Meta;
use crate::store::format::node::{self, Limits};
use crate::store::{Pager, ReadStats, StorageError};
use crate::tree::Owner;

/// Where the blocks of one kind go: old id -> new id, and the checksum
/// each carries once written.
#[derive(Default)]
struct Moves {
    to: HashMap<u32, u32>,
    sums: HashMap<u32, u32>,
}

impl Moves {
    /// Copies `blocks` (id and checksum) of type `t`, which name no other
    /// block, to their new places; a group block is validated first.
    fn copy(
        &mut self,
        pager: &Pager,
        blocks: &BTreeMap<u32, u32>,
        t: BlockType,
        txn: u64,
    ) -> Result<(), StorageError> {
        for (&old, &sum) in blocks {
            let (mut bytes, _) = pager.read(old, t, Some(sum), &mut ReadStats::default())?;
            if t == BlockType::Group {
                group::validate(old, &bytes, pager.lod_levels())?;
            }
            let to = self.to[&old];
            self.sums.insert(old, pager.write(to, &mut bytes, t, txn)?);
        }
        Ok(())
    }

    /// The new id and checksum of old block `old`, already written.
    fn written(&self, old: u32, what: &str) -> Result<(u32, u32), StorageError> {
        match (self.to.get(&old), self.sums.get(&old)) {
            (Some(&to), Some(&sum)) => Ok((to, sum)),
            _ => Err(StorageError::corrupt(
                old,
                "reference",
                format!("a {what} reference to a block not yet moved"),
            )),
        }
    }
}

/// A reference past the file's last block.
fn past_end(block: u32) -> StorageError {
    StorageError::corrupt(block, "reference", "a block past the file's end")
}

/// A block of a walk met a second time through another checksum, or on a
/// path through itself.
fn met_twice(block: u32, what: &str) -> StorageError {
    StorageError::corrupt(block, "reference", format!("{what} block reached twice, or by a cycle"))
}

impl WriteTransaction<'_> {
    /// Refuses a tree a move could not carry whole: one that shares a block
    /// with the free space its commit records (the free list's blocks or
    /// its ranges), or whose meta block counts other blocks than it holds.
    /// A commit trusts that record, and a compaction's commits cut the
    /// file's free end off, so they would cut such a tree short; an opening
    /// bounds the counts by the file's size, which a compaction shrinks.
    /// Reads and verifies every block of the tree, as a move does.
    pub(crate) fn check_movable(&self) -> Result<(), crate::Error> {
        let Some(meta) = self.inner.lock_state().snapshot.meta.clone() else { return Ok(()) };
        let pager = self.inner.pager().clone();
        let tree = TreeBlocks::walk(&pager, &meta)?;
        let chain = &self.base_chain;
        let free = FreeSpace::new(self.base.block_count, self.base_free.iter().map(|r| (r.first, r.count)));
        let keys = tree.keys.iter().flatten().map(|&(b, _)| b);
        let blocks = tree
            .nodes
            .order
            .iter()
            .copied()
            .chain(tree.nodes.geometry.keys().copied())
            .chain(tree.nodes.groups.keys().copied());
        let counts = [
            ("node_blocks", u64::from(meta.node_blocks), tree.nodes.order.len()),
            ("geometry_blocks", meta.geometry_blocks, tree.nodes.geometry.len()),
            ("keys_blocks", u64::from(meta.keys_blocks), tree.keys.iter().map(Vec::len).sum()),
        ];
        for (field, says, holds) in counts {
            if says != holds as u64 {
                let detail = format!("the meta block says {says}, the tree holds {holds} (run check)");
                return Err(StorageError::corrupt(self.base.meta_block, field, detail).into());
            }
        }
        for b in blocks.chain(keys).chain([self.base.meta_block]) {
            if chain.contains(&b) || free.contains(b) || b >= self.base.block_count {
                return Err(StorageError::corrupt(
                    b,
                    "free space",
                    "the tree holds a block the commit records as free or past the file's end (run check)",
                )
                .into());
            }
        }
        Ok(())
    }

    /// Moves the committed tree into the lowest free blocks, or past the
    /// file's end when `at_end` ([`Database::compact`](crate::Database::compact)):
    /// the same tree, byte for byte but for block ids, checksums and the
    /// transaction id of each block. A file without a tree has nothing to move.
    pub(crate) fn relocate(&mut self, at_end: bool) -> Result<(), crate::Error> {
        self.may_write_tree()?;
        let Some(meta) = self.inner.lock_state().snapshot.meta.clone() else { return Ok(()) };
        self.append_only = at_end;
        let pager = self.inner.pager().clone();
        let limits = limits(&pager, &meta);
        let TreeBlocks { nodes: NodeWalk { order, sums: node_sums, geometry, groups }, keys: levels } =
            TreeBlocks::walk(&pager, &meta)?;

        // New places, allocated in the order a bulk load allocates them, so
        // that a move into an empty file lays the tree out as a load would.
        let mut geometry_moves = Moves::default();
        if !geometry.is_empty() {
            let first = self.allocate(geometry.len() as u32)?;
            geometry_moves.to = geometry.keys().zip(first..).map(|(&old, new)| (old, new)).collect();
        }
        // Group blocks next, as a bulk load allocates them before the node blocks.
        let mut group_moves = Moves::default();
        if !groups.is_empty() {
            let first = self.allocate(groups.len() as u32)?;
            group_moves.to = groups.keys().zip(first..).map(|(&old, new)| (old, new)).collect();
        }
        let mut node_moves = Moves::default();
        let mut sorted: Vec<u32> = order.clone();
        sorted.sort_unstable();
        let first = self.allocate(sorted.len() as u32)?;
        node_moves.to = sorted.iter().zip(first..).map(|(&old, new)| (old, new)).collect();
        let mut key_moves = Moves::default();
        for level in levels.iter().rev() {
            for &(block, _) in level {
                let new = self.allocate(1)?;
                key_moves.to.insert(block, new);
            }
        }
        let meta_block = self.allocate(1)?;

        let txn = self.txn;
        geometry_moves.copy(&pager, &geometry, BlockType::Geometry, txn)?;
        group_moves.copy(&pager, &groups, BlockType::Group, txn)?;
        for &old in &order {
            let (mut bytes, _) =
                pager.read(old, BlockType::Node, Some(node_sums[&old]), &mut ReadStats::default())?;
            let records = node::validate_block(old, &bytes, &limits)?;
            let span = &mut |first: u32, sums: &[u32]| -> Result<(u32, Vec<u32>), StorageError> {
                let (to, _) = geometry_moves.written(first, "geometry")?;
                let mut new = Vec::with_capacity(sums.len());
                for i in 0..sums.len() as u32 {
                    let (at, sum) = geometry_moves.written(first.saturating_add(i), "geometry")?;
                    if to.checked_add(i) != Some(at) {
                        return Err(StorageError::corrupt(
                            old,
                            "span",
                            "a span's blocks are not consecutive",
                        ));
                    }
                    new.push(sum);
                }
                Ok((to, new))
            };
            // A child node block, or the block's group block (format-spec/group.md).
            let child = &mut |block: u32, _: u32| match group_moves.to.contains_key(&block) {
                true => group_moves.written(block, "group"),
                false => node_moves.written(block, "node"),
            };
            node::relocate_block(old, &mut bytes, &records, child, span)?;
            let to = node_moves.to[&old];
            node_moves.sums.insert(old, pager.write(to, &mut bytes, BlockType::Node, txn)?);
        }
        copy_key_blocks(&pager, &levels, &mut key_moves, txn)?;

        let mut moved = meta;
        (moved.root_block, moved.root_checksum) = node_moves.written(moved.root_block, "node")?;
        (moved.keys_block, moved.keys_checksum) = key_moves.written(moved.keys_block, "key")?;
        let mut block = vec![0u8; pager.block_size() as usize];
        moved.encode(&mut block);
        let sum = pager.write(meta_block, &mut block, BlockType::Meta, txn)?;
        self.meta = Some((meta_block, sum, moved));
        Ok(())
    }
}

/// Copies the key index's blocks, `levels` from the root down, to the
/// places `moves` gives them, leaves first: a branch names its children's
/// new places.
fn copy_key_blocks(
    pager: &Pager,
    levels: &[Vec<(u32, u32)>],
    moves: &mut Moves,
    txn: u64,
) -> Result<(), StorageError> {
    for (depth, level) in levels.iter().enumerate().rev() {
        let leaf = depth + 1 == levels.len();
        let t = if leaf { BlockType::KeyLeaf } else { BlockType::KeyBranch };
        for &(old, sum) in level {
            let (mut bytes, _) = pager.read(old, t, Some(sum), &mut ReadStats::default())?;
            match keys::decode(old, &bytes, leaf)? {
                // Key entries name no node block: a leaf moves as it is.
                KeyBlock::Leaf(_) => {}
                KeyBlock::Branch(mut children) => {
                    for c in &mut children {
                        (c.block, c.checksum) = moves.written(c.block, "key")?;
                    }
                    keys::encode_branch(&children, &mut bytes).map_err(StorageError::Invalid)?;
                }
            }
            let to = moves.to[&old];
            moves.sums.insert(old, pager.write(to, &mut bytes, t, txn)?);
        }
    }
    Ok(())
}

/// What node validation needs of the file.
fn limits(pager: &Pager, meta: &Meta) -> Limits {
    Limits { block_size: pager.block_size(), lod_levels: pager.lod_levels(), object_count: meta.object_ids }
}

/// Every block a committed tree holds but its meta block, each verified
/// against the checksum its parent holds.
struct TreeBlocks {
    nodes: NodeWalk,
    /// The key index, level by level from the root: (block, checksum).
    keys: Vec<Vec<(u32, u32)>>,
}

impl TreeBlocks {
    fn walk(pager: &Pager, meta: &Meta) -> Result<TreeBlocks, StorageError> {
        let nodes = node_walk(pager, &limits(pager, meta), meta.root_block, meta.root_checksum)?;
        let mut levels: Vec<Vec<(u32, u32)>> = vec![vec![(meta.keys_block, meta.keys_checksum)]];
        let mut seen = HashMap::new();
        for height in (1..=meta.keys_height).rev() {
            let mut below = Vec::new();
            for &(block, sum) in levels.last().into_iter().flatten() {
                if seen.insert(block, ()).is_some() {
                    return Err(met_twice(block, "key"));
                }
                let t = if height > 1 { BlockType::KeyBranch } else { BlockType::KeyLeaf };
                let (bytes, _) = pager.read(block, t, Some(sum), &mut ReadStats::default())?;
                if let KeyBlock::Branch(children) = keys::decode(block, &bytes, height == 1)? {
                    below.extend(children.iter().map(|c| (c.block, c.checksum)));
                }
            }
            if height > 1 {
                levels.push(below);
            }
        }
        Ok(TreeBlocks { nodes, keys: levels })
    }
}

/// The blocks a tree's node records reach.
struct NodeWalk {
    /// The node blocks, children before parents.
    order: Vec<u32>,
    /// Each node block's checksum, as its parents hold it.
    sums: HashMap<u32, u32>,
    /// The geometry blocks the leaves' spans name, in order, with their checksums.
    geometry: BTreeMap<u32, u32>,
    /// The group blocks the node blocks name, in order, with their checksums.
    groups: BTreeMap<u32, u32>,
}

/// The [`NodeWalk`] of the tree rooted in block `root` (checksum `sum`).
fn node_walk(pager: &Pager, limits: &Limits, root: u32, sum: u32) -> Result<NodeWalk, StorageError> {
    // Every map below holds blocks of the file, each once: bounded by its size.
    let end = u32::try_from(pager.block_count()?).unwrap_or(u32::MAX);
    let mut sums = HashMap::from([(root, sum)]);
    let mut geometry = BTreeMap::new();
    let mut groups = BTreeMap::new();
    // Per block: whether its children are done (false while they are walked).
    let mut done: HashMap<u32, bool> = HashMap::new();
    let mut order = Vec::new();
    let mut stack = vec![(root, false)];
    while let Some((block, expanded)) = stack.pop() {
        if expanded {
            done.insert(block, true);
            order.push(block);
            continue;
        }
        match done.get(&block) {
            Some(true) => continue,
            Some(false) => return Err(met_twice(block, "node")),
            None => {}
        }
        done.insert(block, false);
        stack.push((block, true));
        let (bytes, _) = pager.read(block, BlockType::Node, Some(sums[&block]), &mut ReadStats::default())?;
        let records = node::validate_block(block, &bytes, limits)?;
        if let Some((g, s)) = node::group_ref(&bytes) {
            if g >= end {
                return Err(past_end(g));
            }
            if groups.insert(g, s).is_some() || sums.contains_key(&g) {
                return Err(met_twice(g, "group"));
            }
        }
        for r in records {
            let view = node::NodeView::at(&bytes, r)
                .map_err(|e| StorageError::corrupt_record(block, r, "record", e))?;
            match view {
                node::NodeView::Internal(n) => {
                    for i in 0..2 {
                        let c = n.child_ref(i);
                        if c.block == 0 {
                            continue;
                        }
                        if c.block >= end {
                            return Err(past_end(c.block));
                        }
                        if *sums.entry(c.block).or_insert(c.checksum) != c.checksum {
                            return Err(met_twice(c.block, "node"));
                        }
                        match done.get(&c.block) {
                            Some(false) => return Err(met_twice(c.block, "node")),
                            Some(true) => {}
                            None => stack.push((c.block, false)),
                        }
                    }
                }
                node::NodeView::Leaf(l) => {
                    let (first, span) = l.geometry();
                    for (i, s) in span.enumerate() {
                        let g = first
                            .checked_add(i as u32)
                            .filter(|&g| g < end)
                            .ok_or_else(|| past_end(first))?;
                        if *geometry.entry(g).or_insert(s) != s {
                            return Err(met_twice(g, "geometry"));
                        }
                    }
                }
            }
        }
    }
    Ok(NodeWalk { order, sums, geometry, groups })
}
