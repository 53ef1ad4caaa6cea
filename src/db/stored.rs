//! The stored tree read back whole: every object with its mesh, key,
//! payload and name. A change commit that must write the tree whole (see
//! `write/cow/mod.rs`) starts from it.

use std::collections::HashMap;
use std::sync::Arc;

use super::{ReadTransaction, Reads, view, walk_everything};
use crate::geom::Aabb;
use crate::query::Visitor;
use crate::scene::{Key, Mesh, Object, ObjectId, Scene};
use crate::store::format::geometry;
use crate::store::format::node::NodeView;
use crate::store::{Block, StorageError};

/// Each object's key and parts, gathered leaf by leaf.
struct Gather<'t> {
    txn: &'t ReadTransaction,
    reads: Reads<'t>,
    found: HashMap<u32, (Option<Key>, Vec<Mesh>)>,
}

impl Visitor for Gather<'_> {
    fn node(&mut self, block: &Arc<Block>, offset: u32, _: &Aabb) -> Result<(), StorageError> {
        let NodeView::Leaf(leaf) = view(block, offset)? else { return Ok(()) };
        for i in 0..leaf.len() {
            let (id, mesh) = self.txn.read_object(block.id(), &leaf, i, &mut self.reads)?;
            let entry = self.found.entry(id.0).or_default();
            if entry.1.is_empty() {
                entry.0 = leaf.key(i);
            }
            entry.1.push(mesh);
        }
        Ok(())
    }
}

impl ReadTransaction {
    /// Every object of the snapshot in the order of their ids, with its
    /// exact mesh, key, payload and name: the scene the tree holds (empty
    /// without a tree). Reads the whole file; ids a change commit left
    /// unused are skipped, so the scene numbers the objects densely.
    pub fn scene(&self) -> Result<Scene, StorageError> {
        let Some(root) = self.root() else { return Ok(Scene::default()) };
        let mut gather = Gather { txn: self, reads: Reads::new(Some(self.cache())), found: HashMap::new() };
        walk_everything(self, root, &mut Reads::new(None), &mut gather)?;
        let mut found: Vec<_> = gather.found.into_iter().collect();
        found.sort_unstable_by_key(|(id, _)| *id);
        let mut objects = Vec::with_capacity(found.len());
        for (id, (key, parts)) in found {
            let id = ObjectId(id);
            let key = key.ok_or_else(|| StorageError::Invalid(format!("object {id} has no key")))?;
            let mesh = geometry::join(&parts)
                .ok_or_else(|| StorageError::Invalid(format!("object {id}: its parts do not join")))?;
            let entry = self.key_entry(&key, &mut Reads::new(Some(self.cache())))?.ok_or_else(|| {
                StorageError::Invalid(format!("object {id}'s key {key} is not in the key index"))
            })?;
            objects.push(Object { name: entry.name, mesh, key: Some(key), payload: entry.payload });
        }
        Ok(Scene::new(objects))
    }
}
