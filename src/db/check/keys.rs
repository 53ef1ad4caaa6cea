//! `check` of the key index (format-spec/keys.md): every block reached
//! once at its level, keys strictly increasing across the leaves, each
//! branch's separators the least keys below them, and one entry per object
//! that agrees with the tree: the key its leaf stores, the path to the leaf
//! that holds it, and the union of its parts' boxes.

use std::collections::{HashMap, HashSet};

use super::{Checker, Owner};
use crate::db::{ReadTransaction, Reads};
use crate::geom::Aabb;
use crate::scene::Key;
use crate::store::StorageError;
use crate::store::format::frame::BlockType;
use crate::store::format::keys::{KeyBlock, TreePath};
use crate::store::format::meta::Meta;

/// An object as the tree walk met it.
pub(crate) struct KeyedObject {
    /// The key its leaf stores.
    pub key: Option<Key>,
    /// The path from the root to its leaf.
    pub path: TreePath,
    /// The union of its parts' boxes, from their geometry.
    pub aabb: Aabb,
}

pub(super) fn check_keys(
    c: &mut Checker,
    txn: &ReadTransaction,
    meta: &Meta,
    objects: &HashMap<u32, KeyedObject>,
) -> Result<(), StorageError> {
    let mut reads = Reads::new(None);
    // Blocks of the next level down: (block, checksum, the least key the
    // branch above says it holds; none on the leftmost path).
    let mut level: Vec<(u32, u32, Option<Key>)> = vec![(meta.keys_block, meta.keys_checksum, None)];
    let (mut blocks, mut last): (u64, Option<Key>) = (0, None);
    let mut met = HashSet::new();
    for height in (1..=meta.keys_height).rev() {
        let leaf = height == 1;
        let t = if leaf { BlockType::KeyLeaf } else { BlockType::KeyBranch };
        let mut below = Vec::new();
        for (block, checksum, least) in level {
            // A block met twice is a fault (`claim` reports it) and is not walked again.
            let unseen = c.owner.get(block as usize) == Some(&Owner::Unseen);
            c.claim(block, Owner::Used(t));
            if !unseen {
                continue;
            }
            blocks += 1;
            let here = format!("key block {block} (level {height})");
            let kb = match txn.key_block(block, checksum, leaf, &mut reads) {
                Ok(kb) => kb,
                Err(e) => {
                    c.fault(format!("{here}: {e}"));
                    continue;
                }
            };
            if let (Some(least), KeyBlock::Leaf(es)) = (&least, &kb)
                && es.first().map(|e| &e.key) != Some(least)
            {
                c.fault(format!("{here}: its first key is not the separator {least} its branch holds"));
            }
            match kb {
                KeyBlock::Leaf(entries) => {
                    for e in entries {
                        if last.as_ref().is_some_and(|l| *l >= e.key) {
                            c.fault(format!("{here}: key {} does not follow the key before it", e.key));
                        }
                        last = Some(e.key.clone());
                        let id = e.object_id;
                        if !met.insert(id) {
                            c.fault(format!("{here}: object {id} has two keys"));
                        }
                        match objects.get(&id) {
                            None => c.fault(format!("{here}: key {} names object {id}, in no leaf", e.key)),
                            Some(o) => {
                                if o.key.as_ref() != Some(&e.key) {
                                    c.fault(format!(
                                        "{here}: key {} names object {id}, whose leaf stores {:?}",
                                        e.key, o.key
                                    ));
                                }
                                // A split below a path leaves it leading to an ancestor (format-spec/keys.md).
                                if !e.path.is_prefix_of(&o.path) {
                                    c.fault(format!(
                                        "{here}: key {}'s path to object {id} is {:?}, the tree holds it at {:?}",
                                        e.key, e.path, o.path
                                    ));
                                }
                                if o.aabb != e.aabb {
                                    c.fault(format!(
                                        "{here}: key {}'s box {:?} is not object {id}'s {:?}",
                                        e.key, e.aabb, o.aabb
                                    ));
                                }
                            }
                        }
                    }
                }
                KeyBlock::Branch(children) => {
                    for (i, ch) in children.into_iter().enumerate() {
                        let least = if i == 0 { least.clone() } else { Some(ch.first_key) };
                        below.push((ch.block, ch.checksum, least));
                    }
                }
            }
        }
        level = below;
    }
    if blocks != u64::from(meta.keys_blocks) {
        c.fault(format!("meta says {} key index blocks, the index has {blocks}", meta.keys_blocks));
    }
    if let Some(id) = objects.keys().find(|id| !met.contains(id)) {
        c.fault(format!("object {id} has no key in the key index"));
    }
    Ok(())
}
