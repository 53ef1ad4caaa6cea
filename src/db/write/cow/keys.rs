//! The key index written copy on write (format-spec/keys.md;
//! format-spec/commit.md, "Change commits"): the key leaves the changes
//! fall in and the branches above them are written anew; the entries a
//! leaf keeps are copied as they lie.

use std::collections::BTreeMap;

use crate::db::write::WriteTransaction;
use crate::db::{ReadTransaction, Reads};
use crate::scene::{Key, KeyError, ObjectId};
use crate::store::format::frame::BlockType;
use crate::store::format::keys::{self, ChildRef, KeyBlock, KeyEntry};
use crate::store::format::meta::Meta;
use crate::store::{Block, StorageError};
use crate::tree::Owner;

/// The key index as a change commit leaves it.
pub(super) struct NewKeys {
    pub(super) block: u32,
    pub(super) checksum: u32,
    pub(super) height: u32,
    pub(super) blocks: u32,
}

/// A key block's replacement after changes: the blocks (with their least
/// keys) that stand where it stood, at its level; none when it emptied.
type Replacement = Vec<ChildRef>;

impl WriteTransaction<'_> {
    /// Applies `changes` (a key's new entry, or `None` to drop it) to the
    /// key index copy on write: the leaves they fall in and the branches
    /// above them are written anew; a leaf that fills splits, and one that
    /// empties goes (a branch may be left with one child: format-spec/keys.md).
    pub(super) fn rewrite_keys(
        &mut self,
        r: &ReadTransaction,
        meta: &Meta,
        changes: BTreeMap<Key, Option<KeyEntry>>,
        reads: &mut Reads,
        freed: &mut Vec<u32>,
    ) -> Result<NewKeys, crate::Error> {
        let mut blocks = i64::from(meta.keys_blocks);
        if changes.is_empty() {
            return Ok(NewKeys {
                block: meta.keys_block,
                checksum: meta.keys_checksum,
                height: meta.keys_height,
                blocks: meta.keys_blocks,
            });
        }
        let changes: Vec<(Key, Option<KeyEntry>)> = changes.into_iter().collect();
        let root = ChildRef { first_key: Key::Int(0), block: meta.keys_block, checksum: meta.keys_checksum };
        let mut level =
            self.update_key_block(r, &root, meta.keys_height, &changes, reads, freed, &mut blocks)?;
        let mut height = meta.keys_height;
        if level.is_empty() {
            return Err(StorageError::Invalid("a change commit emptied the key index".into()).into());
        }
        // Levels above the old root while more than one block stands there.
        while level.len() > 1 {
            level = self.write_branches(&level, &mut blocks)?;
            height += 1;
        }
        let top = &level[0];
        Ok(NewKeys {
            block: top.block,
            checksum: top.checksum,
            height,
            blocks: u32::try_from(blocks)
                .map_err(|_| StorageError::Invalid("a key index of fewer than no blocks".into()))?,
        })
    }

    /// The replacement of key block `at` (`height` levels: 1 a leaf) with
    /// `changes` (all within its key range) applied.
    #[allow(clippy::too_many_arguments)]
    fn update_key_block(
        &mut self,
        r: &ReadTransaction,
        at: &ChildRef,
        height: u32,
        changes: &[(Key, Option<KeyEntry>)],
        reads: &mut Reads,
        freed: &mut Vec<u32>,
        blocks: &mut i64,
    ) -> Result<Replacement, crate::Error> {
        freed.push(at.block);
        *blocks -= 1;
        if height == 1 {
            return self.update_key_leaf(r, at, changes, reads, blocks);
        }
        match r.key_block(at.block, at.checksum, false, reads)? {
            KeyBlock::Leaf(_) => {
                Err(StorageError::corrupt(at.block, "keys_height", "a leaf above the leaves' level").into())
            }
            KeyBlock::Branch(children) => {
                // Each child's share of the changes, in key order.
                let mut next: Vec<ChildRef> = Vec::new();
                let mut i = 0;
                for (c, child) in children.iter().enumerate() {
                    let upper = children.get(c + 1).map(|n| &n.first_key);
                    let start = i;
                    while i < changes.len() && upper.is_none_or(|u| changes[i].0 < *u) {
                        i += 1;
                    }
                    // The least key below the first child is this block's own.
                    let least = if c == 0 { at.first_key.clone() } else { child.first_key.clone() };
                    if start == i {
                        next.push(ChildRef { first_key: least, ..child.clone() });
                        continue;
                    }
                    let child = ChildRef { first_key: least, ..child.clone() };
                    next.extend(self.update_key_block(
                        r,
                        &child,
                        height - 1,
                        &changes[start..i],
                        reads,
                        freed,
                        blocks,
                    )?);
                }
                if next.is_empty() {
                    return Ok(Vec::new());
                }
                self.write_branches(&next, blocks).map_err(Into::into)
            }
        }
    }

    /// The replacement of key leaf `at` with `changes` applied: the entries
    /// it keeps are copied as they lie, and only the changed ones encoded.
    fn update_key_leaf(
        &mut self,
        r: &ReadTransaction,
        at: &ChildRef,
        changes: &[(Key, Option<KeyEntry>)],
        reads: &mut Reads,
        blocks: &mut i64,
    ) -> Result<Replacement, crate::Error> {
        let pager = self.inner.pager().clone();
        let capacity = keys::capacity(pager.block_size());
        let leaf = r.block(at.block, BlockType::KeyLeaf, at.checksum, reads)?;
        let old = keys::leaf_entries(leaf.id(), &leaf.bytes, &leaf.records)?;
        // Both in key order: merge, the change winning on an equal key.
        let mut encoded: Vec<(Vec<u8>, u32, &Key)> = Vec::new();
        let mut order: Vec<(Option<usize>, usize)> = Vec::with_capacity(old.len() + changes.len());
        let (mut i, mut j) = (0, 0);
        while i < old.len() || j < changes.len() {
            let next_old = old.get(i).map(|(k, _)| *k);
            let next_change = changes.get(j);
            let take_old = match (next_old, next_change) {
                (Some(k), Some((c, _))) => k.cmp(&c.as_ref()),
                (Some(_), None) => std::cmp::Ordering::Less,
                (None, _) => std::cmp::Ordering::Greater,
            };
            if take_old.is_lt() {
                order.push((None, i));
                i += 1;
                continue;
            }
            if take_old.is_eq() {
                i += 1;
            }
            if let Some((key, Some(e))) = next_change {
                let bytes = keys::encode_entry(e).map_err(StorageError::Invalid)?;
                order.push((Some(encoded.len()), 0));
                encoded.push((bytes, e.object_id, key));
            }
            j += 1;
        }
        if order.is_empty() {
            // A leaf its removals empty goes; its branch drops it.
            return Ok(Vec::new());
        }
        let parts: Vec<&[u8]> =
            order.iter().map(|&(new, at)| new.map_or(old[at].1, |n| encoded[n].0.as_slice())).collect();
        if let Some((bytes, object, _)) = encoded.iter().find(|(b, ..)| b.len() > capacity) {
            return Err(KeyError::PayloadTooLong { object: ObjectId(*object), len: bytes.len() }.into());
        }
        let sizes: Vec<usize> = parts.iter().map(|p| p.len()).collect();
        let mut out = Vec::new();
        for group in keys::pack(&sizes, capacity) {
            let first_key = match order[group.start] {
                (None, at) => old[at].0.to_key(),
                (Some(n), _) => encoded[n].2.clone(),
            };
            let mut block = vec![0u8; pager.block_size() as usize];
            keys::encode_leaf_bytes(&parts[group], &mut block).map_err(StorageError::Invalid)?;
            let id = self.allocate(1)?;
            let checksum = self.put(id, &mut block, BlockType::KeyLeaf)?;
            *blocks += 1;
            out.push(ChildRef { first_key, block: id, checksum });
        }
        Ok(out)
    }

    /// Branch blocks over `children` (in key order), packed as a bulk load
    /// packs them.
    fn write_branches(
        &mut self,
        children: &[ChildRef],
        blocks: &mut i64,
    ) -> Result<Vec<ChildRef>, StorageError> {
        let pager = self.inner.pager().clone();
        let capacity = keys::capacity(pager.block_size());
        let sizes: Vec<usize> =
            children.iter().enumerate().map(|(i, c)| keys::child_len(&c.first_key, i == 0)).collect();
        let mut out = Vec::new();
        for group in keys::pack(&sizes, capacity) {
            let part = &children[group];
            let mut block = vec![0u8; pager.block_size() as usize];
            keys::encode_branch(part, &mut block).map_err(StorageError::Invalid)?;
            let id = self.allocate(1)?;
            let checksum = self.put(id, &mut block, BlockType::KeyBranch)?;
            // Every change reads the branches again: cached, as a read would.
            let records = keys::validate(id, &block, false)?;
            self.keep_for_cache(Block { id, checksum, bytes: block.into(), records, groups: Vec::new() });
            *blocks += 1;
            out.push(ChildRef { first_key: part[0].first_key.clone(), block: id, checksum });
        }
        Ok(out)
    }
}
