//! Reading the key index (format-spec/keys.md): lookups descend it and
//! never walk the MKtree. A bulk load writes it (`load/keys.rs`).

use std::sync::Arc;

use super::{ReadTransaction, Reads};
use crate::geom::Aabb;
use crate::scene::{Key, Mesh, Object, ObjectId};
use crate::store::format::frame::BlockType;
use crate::store::format::geometry;
use crate::store::format::keys::{self, KeyBlock, KeyEntry};
use crate::store::format::node::NodeView;
use crate::store::{Block, StorageError};

/// What a lookup by key finds: the object's id, key, exact box and payload.
#[derive(Debug, Clone, PartialEq)]
pub struct ObjectRecord {
    /// The object's id.
    pub id: ObjectId,
    /// The application's key.
    pub key: Key,
    /// The object's exact box, mm.
    pub aabb: Aabb,
    /// The application's bytes kept with the key.
    pub payload: Vec<u8>,
}

impl ReadTransaction {
    /// Every object's name, by id (reads the key index, which holds them);
    /// an id no object has gets an empty name. Ids sparser than 16 per
    /// object (past the first 65,536) are refused, not listed.
    pub fn names(&self) -> Result<Vec<String>, StorageError> {
        let Some(m) = self.snapshot.meta.as_ref() else { return Ok(Vec::new()) };
        let entries = self.key_entries(&mut Reads::new(None))?;
        let len = entries.iter().map(|e| e.object_id as usize + 1).max().unwrap_or(0);
        if len > m.object_ids as usize {
            return Err(StorageError::corrupt(
                m.keys_block,
                "object_id",
                format!("an id past the tree's {}", m.object_ids),
            ));
        }
        // The list is sized by the ids the entries hold: a file whose ids
        // are far sparser than its objects (forged, or after a great many
        // removals) is refused rather than listed.
        if len > 16 * entries.len() + (1 << 16) {
            return Err(StorageError::Invalid(format!(
                "ids up to {len} for {} objects are too sparse to list by id",
                entries.len()
            )));
        }
        let mut names = vec![String::new(); len];
        for e in entries {
            if let Some(slot) = names.get_mut(e.object_id as usize) {
                *slot = e.name;
            }
        }
        Ok(names)
    }

    /// The key block `id` of the snapshot, decoded.
    pub(crate) fn key_block(
        &self,
        id: u32,
        checksum: u32,
        leaf: bool,
        reads: &mut Reads,
    ) -> Result<KeyBlock, StorageError> {
        let t = if leaf { BlockType::KeyLeaf } else { BlockType::KeyBranch };
        let b = self.block(id, t, checksum, reads)?;
        keys::decode_validated(id, &b.bytes, &b.records, leaf)
    }

    /// The key leaf whose range holds `key`, read, descending the key index
    /// (its height in reads); none without a tree. Each block is validated
    /// once, when it is read, and searched in place.
    fn key_leaf(&self, key: &Key, reads: &mut Reads) -> Result<Option<Arc<Block>>, StorageError> {
        let Some(m) = self.snapshot.meta.as_ref() else { return Ok(None) };
        let (mut block, mut checksum) = (m.keys_block, m.keys_checksum);
        for _ in 2..=m.keys_height {
            let b = self.block(block, BlockType::KeyBranch, checksum, reads)?;
            (block, checksum) = keys::search_branch(b.id(), &b.bytes, &b.records, key)?;
        }
        Ok(Some(self.block(block, BlockType::KeyLeaf, checksum, reads)?))
    }

    /// The entry of `key`, descending the key index (its height in reads at
    /// most); only that entry of its leaf is copied out.
    pub(crate) fn key_entry(&self, key: &Key, reads: &mut Reads) -> Result<Option<KeyEntry>, StorageError> {
        match self.key_leaf(key, reads)? {
            Some(leaf) => keys::search_leaf(leaf.id(), &leaf.bytes, &leaf.records, key),
            None => Ok(None),
        }
    }

    /// Every entry of the key index, in key order: each block read once.
    pub(crate) fn key_entries(&self, reads: &mut Reads) -> Result<Vec<KeyEntry>, StorageError> {
        let Some(m) = self.snapshot.meta.as_ref() else { return Ok(Vec::new()) };
        let mut level = vec![(m.keys_block, m.keys_checksum)];
        let mut entries = Vec::new();
        for height in (1..=m.keys_height).rev() {
            // Blocks are bounded by the meta block's count, which opening bounds by the file.
            if level.len() > m.keys_blocks as usize {
                return Err(StorageError::corrupt(m.keys_block, "keys_blocks", "the index has more blocks"));
            }
            let mut below = Vec::new();
            for (block, checksum) in level {
                match self.key_block(block, checksum, height == 1, reads)? {
                    KeyBlock::Leaf(es) => entries.extend(es),
                    KeyBlock::Branch(children) => {
                        below.extend(children.iter().map(|c| (c.block, c.checksum)))
                    }
                }
            }
            level = below;
        }
        Ok(entries)
    }

    /// The object with key `key`: its id, exact box and payload, in the
    /// index's height of block reads (counted in `reads`).
    pub fn get_with(&self, key: &Key, reads: &mut Reads) -> Result<Option<ObjectRecord>, StorageError> {
        Ok(self.key_entry(key, reads)?.map(|e| ObjectRecord {
            id: ObjectId(e.object_id),
            key: e.key,
            aabb: e.aabb,
            payload: e.payload,
        }))
    }

    /// The object with key `key` (see [`ReadTransaction::get_with`]).
    pub fn get(&self, key: &Key) -> Result<Option<ObjectRecord>, StorageError> {
        self.get_with(key, &mut Reads::new(Some(self.cache())))
    }

    /// The exact box of the object with key `key`.
    pub fn aabb(&self, key: &Key) -> Result<Option<Aabb>, StorageError> {
        Ok(self.get(key)?.map(|r| r.aabb))
    }

    /// The exact mesh of the object with key `key`: the index's path, the
    /// node blocks from the root to the object's leaf record and the
    /// object's geometry blocks (counted in `reads`).
    pub fn mesh_with(&self, key: &Key, reads: &mut Reads) -> Result<Option<Mesh>, StorageError> {
        let Some(e) = self.key_entry(key, reads)? else { return Ok(None) };
        self.mesh_of_entry(&e, reads).map(Some)
    }

    /// The exact mesh of the object of key entry `e` (the snapshot's own):
    /// the node blocks from the root to its leaf record and its geometry
    /// blocks (counted in `reads`).
    pub(crate) fn mesh_of_entry(&self, e: &KeyEntry, reads: &mut Reads) -> Result<Mesh, StorageError> {
        let steps = self.path_to(e.object_id, e.path, &e.aabb, reads)?;
        let leaf_step = steps.last().ok_or_else(|| StorageError::Invalid("an empty path".into()))?;
        let b: &Arc<Block> = &leaf_step.block;
        let NodeView::Leaf(leaf) = super::view(b, leaf_step.offset)? else {
            return Err(StorageError::corrupt(b.id(), "path", "the key's path ends at no leaf"));
        };
        let first = (0..leaf.len())
            .find(|&i| leaf.object(i).is_some_and(|o| o.object_id == e.object_id))
            .ok_or_else(|| {
                StorageError::corrupt(b.id(), "path", "the key's leaf does not hold its object")
            })?;
        let mut parts = Vec::new();
        for i in first..leaf.len() {
            match leaf.object(i) {
                Some(o) if o.object_id == e.object_id => {
                    parts.push(self.read_object(b.id(), &leaf, i, reads)?.1);
                }
                _ => break,
            }
        }
        if leaf.key(first).as_ref() != Some(&e.key) {
            return Err(StorageError::corrupt(
                b.id(),
                "keys",
                format!("entry {first} of the leaf is not the object of key {}", e.key),
            ));
        }
        geometry::join(&parts)
            .ok_or_else(|| StorageError::corrupt(b.id(), "parts", "an object's parts do not join"))
    }

    /// The object with key `key` whole: its name, exact mesh, key and
    /// payload (the key index's path, the tree's path to its leaf, its
    /// geometry blocks).
    pub fn object(&self, key: &Key) -> Result<Option<Object>, StorageError> {
        let mut reads = Reads::new(Some(self.cache()));
        let Some(e) = self.key_entry(key, &mut reads)? else { return Ok(None) };
        let mesh = self
            .mesh_with(key, &mut reads)?
            .ok_or_else(|| StorageError::corrupt(e.object_id, "key", "a key found once and not twice"))?;
        Ok(Some(Object { name: e.name, mesh, key: Some(e.key), payload: e.payload }))
    }

    /// Levels of the key index (1: its root is a leaf); 0 without a tree.
    pub fn key_index_height(&self) -> u32 {
        self.snapshot.meta.as_ref().map_or(0, |m| m.keys_height)
    }

    /// The largest integer key of the tree: the last integer in key order
    /// (integers order before byte strings), in the leaf whose range holds
    /// the largest integer there can be; one path of the index.
    pub(crate) fn largest_int_key(&self) -> Result<Option<u64>, StorageError> {
        let Some(leaf) = self.key_leaf(&Key::Int(u64::MAX), &mut Reads::new(Some(self.cache())))? else {
            return Ok(None);
        };
        let KeyBlock::Leaf(entries) = keys::decode(leaf.id(), &leaf.bytes, true)? else {
            return Err(StorageError::corrupt(leaf.id(), "keys_height", "a branch at level 1"));
        };
        Ok(entries.into_iter().rev().find_map(|e| if let Key::Int(i) = e.key { Some(i) } else { None }))
    }

    /// The exact mesh of the object with key `key` (see [`ReadTransaction::mesh_with`]).
    pub fn mesh(&self, key: &Key) -> Result<Option<Mesh>, StorageError> {
        self.mesh_with(key, &mut Reads::new(Some(self.cache())))
    }
}
