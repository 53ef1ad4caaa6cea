//! `check` of the key index (format-spec/keys.md): every block reached
//! once at its level, keys strictly increasing across the leaves, each
//! branch's separators the least keys below them, and one entry per object
//! that agrees with the tree: the key its leaf stores, the path to the leaf
//! that holds it, and the union of its parts' boxes.

use std::collections::HashSet;

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

/// Every object the tree walk met, by id: listed as met, then sorted. A
/// list, not a map: a map's buckets, a power of two, held about twice what
/// the objects need (ship 10^6: 203 MB, massif), and while it grew, the old
/// table beside the new.
pub(crate) struct KeyedObjects {
    list: Vec<(u32, KeyedObject)>,
    sorted: bool,
}

impl KeyedObjects {
    /// An empty list with room for `objects`.
    pub fn with_capacity(objects: usize) -> KeyedObjects {
        KeyedObjects { list: Vec::with_capacity(objects), sorted: true }
    }

    /// Object `id`'s entry: the last one, when the last object met is `id`
    /// (its parts are consecutive entries of one leaf), else a new one made
    /// by `make`.
    pub fn entry(&mut self, id: u32, make: impl FnOnce() -> KeyedObject) -> &mut KeyedObject {
        if self.list.last().is_none_or(|&(last, _)| last != id) {
            self.sorted &= self.list.last().is_none_or(|&(last, _)| last < id);
            self.list.push((id, make()));
        }
        let last = self.list.len() - 1;
        &mut self.list[last].1
    }

    /// Sorts the list by id. An id met in more than one place (a fault
    /// the walk reports) keeps the key and path of where it was met first,
    /// and the union of every box.
    pub fn sort(&mut self) {
        if self.sorted {
            return;
        }
        self.list.sort_by_key(|&(id, _)| id);
        self.list.dedup_by(|later, first| {
            let same = later.0 == first.0;
            if same {
                first.1.aabb = first.1.aabb.union(&later.1.aabb);
            }
            same
        });
        self.sorted = true;
    }

    /// Object `id`'s entry, once sorted.
    pub fn get(&self, id: u32) -> Option<&KeyedObject> {
        debug_assert!(self.sorted);
        let at = self.list.binary_search_by_key(&id, |&(o, _)| o).ok()?;
        Some(&self.list[at].1)
    }

    /// The ids met, in order once sorted.
    pub fn ids(&self) -> impl ExactSizeIterator<Item = u32> + '_ {
        self.list.iter().map(|&(id, _)| id)
    }
}

pub(super) fn check_keys(
    c: &mut Checker,
    txn: &ReadTransaction,
    meta: &Meta,
    objects: &KeyedObjects,
) -> Result<(), StorageError> {
    let mut reads = Reads::new(None);
    // Blocks of the next level down: (block, checksum, the least key the
    // branch above says it holds; none on the leftmost path).
    let mut level: Vec<(u32, u32, Option<Key>)> = vec![(meta.keys_block, meta.keys_checksum, None)];
    let (mut blocks, mut last): (u64, Option<Key>) = (0, None);
    let mut met = HashSet::with_capacity(objects.ids().len());
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
                        match objects.get(id) {
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
    if let Some(id) = objects.ids().find(|id| !met.contains(id)) {
        c.fault(format!("object {id} has no key in the key index"));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::collections::HashMap;

    proptest! {
        /// In whatever order the walk meets ids, and however often: the
        /// sorted list holds each id once, with the key and path of where
        /// it was met first and the union of its boxes, as a map of the
        /// ids met does.
        #[test]
        fn the_sorted_list_holds_what_a_map_of_the_ids_met_holds(
            mut met in proptest::collection::vec((0u32..40, 0u64..1000, -100.0f64..100.0), 0..200),
            presorted in any::<bool>(),
        ) {
            if presorted {
                met.sort_by_key(|&(id, _, _)| id);
            }
            let mut list = KeyedObjects::with_capacity(0);
            let mut map: HashMap<u32, KeyedObject> = HashMap::new();
            for (i, &(id, key, x)) in met.iter().enumerate() {
                let make = || KeyedObject {
                    key: Some(Key::Int(key)),
                    path: TreePath { bits: i as u64, len: 8 },
                    aabb: Aabb::EMPTY,
                };
                let b = Aabb::from_array([x, 0.0, 0.0, x + 1.0, 1.0, 1.0]);
                let e = list.entry(id, make);
                e.aabb = e.aabb.union(&b);
                let e = map.entry(id).or_insert_with(make);
                e.aabb = e.aabb.union(&b);
            }
            list.sort();
            let mut ids: Vec<u32> = map.keys().copied().collect();
            ids.sort_unstable();
            prop_assert_eq!(list.ids().collect::<Vec<_>>(), ids);
            for (&id, o) in &map {
                let got = list.get(id);
                prop_assert!(got.is_some());
                let got = got.unwrap();
                prop_assert_eq!((&got.key, got.path, got.aabb), (&o.key, o.path, o.aabb));
            }
        }
    }
}
