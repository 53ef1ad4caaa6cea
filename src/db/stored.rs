//! The stored tree read back whole: every object with its mesh, key,
//! payload and name, and the tree's shape over them. A write transaction
//! that changes objects one by one starts from it.

use std::collections::HashMap;
use std::sync::Arc;

use super::{ReadTransaction, Reads, read_hierarchy, view};
use crate::build::Hierarchy;
use crate::geom::Aabb;
use crate::query::{Everything, QueryError, QueryOptions, Visitor, walk};
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
    /// Every object of the snapshot, by id, with its exact mesh, key,
    /// payload and name: the scene the tree holds (empty without a tree).
    /// Reads the whole file.
    pub fn scene(&self) -> Result<Scene, StorageError> {
        Ok(self.scene_and_tree()?.0)
    }

    /// [`ReadTransaction::scene`] and the tree's shape over it, with the
    /// stored (quantized) boxes.
    pub(crate) fn scene_and_tree(&self) -> Result<(Scene, Hierarchy), StorageError> {
        let Some(root) = self.root() else { return Ok((Scene::default(), Hierarchy::default())) };
        let tree = read_hierarchy(self)?;
        let mut gather = Gather { txn: self, reads: Reads::new(Some(self.cache())), found: HashMap::new() };
        let all = QueryOptions { lod: Some(1), budget: None, ..Default::default() };
        walk(self, root, &Everything, &all, &mut Reads::new(None), &mut gather).map_err(|e| match e {
            QueryError::Storage(s) => s,
            other => StorageError::Invalid(other.to_string()),
        })?;
        let names = self.names()?;
        let mut found = gather.found;
        let count = self.info().map_or(0, |i| i.objects);
        let mut objects = Vec::new();
        for id in 0..count {
            let missing = || StorageError::Invalid(format!("object {id} is in no leaf"));
            let (key, parts) = found.remove(&id).ok_or_else(missing)?;
            let key = key.ok_or_else(|| StorageError::Invalid(format!("object {id} has no key")))?;
            let mesh = geometry::join(&parts)
                .ok_or_else(|| StorageError::Invalid(format!("object {id}: its parts do not join")))?;
            let payload = self.get(&key)?.map(|r| r.payload).unwrap_or_default();
            let name = names.get(id as usize).cloned().unwrap_or_default();
            objects.push(Object { name, mesh, key: Some(key), payload });
        }
        if let Some(&id) = found.keys().next() {
            return Err(StorageError::Invalid(format!("object {} is past the tree's {count}", ObjectId(id))));
        }
        Ok((Scene::new(objects), tree))
    }
}
