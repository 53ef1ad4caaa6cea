//! A write transaction's changes object by object: the committed scene and
//! tree read back once, then inserts, updates and deletes by key on the
//! tree's shape ([`TreeEdit`]), never a new bulk load.

use std::collections::HashMap;

use super::ReadTransaction;
use super::source::check_object;
use crate::build::{BuildParams, Hierarchy, TreeEdit};
use crate::scene::{Key, KeyError, Object, ObjectId, Scene};
use crate::store::StorageError;
use crate::store::format::geometry;

/// The objects and tree a transaction is changing.
pub(crate) struct Changes {
    tree: TreeEdit,
    /// By the tree's object number; `None` once removed.
    objects: Vec<Option<Object>>,
    keys: HashMap<Key, u32>,
    params: BuildParams,
    build_seconds: f64,
    /// The largest integer key the transaction has seen.
    largest_int: Option<u64>,
    /// Made any change.
    changed: bool,
}

impl Changes {
    /// The state of `snapshot`; a file without a tree starts empty, to be
    /// built with `fresh`.
    pub(crate) fn load(snapshot: &ReadTransaction, fresh: BuildParams) -> Result<Changes, crate::Error> {
        let (scene, stored) = snapshot.scene_and_tree()?;
        let info = snapshot.info();
        let params = info.as_ref().and_then(|i| i.params.clone()).unwrap_or(fresh);
        let build_seconds = info.map_or(0.0, |i| i.build_seconds);
        let boxes = scene.object_boxes();
        let sizes = scene.objects().iter().map(|o| geometry::record_len(&o.mesh)).collect();
        let tree = TreeEdit::from_hierarchy(&stored, boxes, sizes, params.clone())
            .map_err(|e| StorageError::Invalid(format!("the stored tree: {e}")))?;
        let objects: Vec<Option<Object>> = scene.into_objects().into_iter().map(Some).collect();
        let mut c = Changes {
            tree,
            objects: Vec::new(),
            keys: HashMap::with_capacity(objects.len()),
            params,
            build_seconds,
            largest_int: None,
            changed: false,
        };
        for (i, o) in objects.iter().enumerate() {
            if let Some(key) = o.as_ref().and_then(|o| o.key.clone()) {
                c.note_key(key, i as u32);
            }
        }
        c.objects = objects;
        Ok(c)
    }

    /// Adds `object`. An object without a key gets the integer key one past
    /// the largest integer key in the tree; returns the key.
    pub(crate) fn insert(&mut self, mut object: Object) -> Result<Key, crate::Error> {
        let number = ObjectId(self.objects.len() as u32);
        check_object(number, &object)?;
        let key = match object.key.take() {
            Some(key) => key,
            None => Key::Int(self.next_int_key()?),
        };
        if self.keys.contains_key(&key) {
            return Err(KeyError::Exists { key }.into());
        }
        let n = self.tree.insert(object.aabb(), geometry::record_len(&object.mesh))?;
        debug_assert_eq!(n as usize, self.objects.len());
        object.key = Some(key.clone());
        self.objects.push(Some(object));
        self.note_key(key.clone(), n);
        self.changed = true;
        Ok(key)
    }

    /// Removes the object of key `key`, returning it.
    pub(crate) fn remove(&mut self, key: &Key) -> Option<Object> {
        let n = self.keys.remove(key)?;
        self.tree.remove(n);
        self.changed = true;
        self.objects.get_mut(n as usize).and_then(Option::take)
    }

    /// Replaces the object of `object`'s key (a delete, then an insert, so
    /// it moves to the leaf it now fits best); returns the old object.
    pub(crate) fn update(&mut self, object: Object) -> Result<Object, crate::Error> {
        let key =
            object.key.clone().ok_or(StorageError::Invalid("an update names its object by key".into()))?;
        let old = self.remove(&key).ok_or(KeyError::NotFound { key: key.clone() })?;
        match self.insert(object) {
            Ok(_) => Ok(old),
            Err(e) => {
                // The transaction keeps the old object when the new one is refused.
                self.insert(old)?;
                Err(e)
            }
        }
    }

    /// The object of key `key`, as the transaction now has it.
    pub(crate) fn get(&self, key: &Key) -> Option<&Object> {
        self.keys.get(key).and_then(|&n| self.objects.get(n as usize)).and_then(Option::as_ref)
    }

    fn note_key(&mut self, key: Key, n: u32) {
        if let Key::Int(i) = key {
            self.largest_int = self.largest_int.max(Some(i));
        }
        self.keys.insert(key, n);
    }

    fn next_int_key(&self) -> Result<u64, StorageError> {
        match self.largest_int {
            None => Ok(0),
            Some(i) => i.checked_add(1).ok_or(StorageError::Invalid("integer keys are exhausted".into())),
        }
    }

    /// Whether anything changed.
    pub(crate) fn changed(&self) -> bool {
        self.changed
    }

    /// The scene to write, objects renumbered densely in the order they
    /// were first added, and the tree over it, with its build parameters
    /// and the seconds the tree's bulk load took.
    pub(crate) fn finish(self) -> (Scene, Hierarchy, BuildParams, f64) {
        let mut ids = vec![None; self.objects.len()];
        let mut live = Vec::with_capacity(self.tree.len());
        for (n, o) in self.objects.into_iter().enumerate() {
            if let Some(o) = o {
                ids[n] = Some(ObjectId(live.len() as u32));
                live.push(o);
            }
        }
        let tree = self.tree.to_hierarchy(&ids);
        (Scene::new(live), tree, self.params, self.build_seconds)
    }
}
