//! What a bulk load writes a tree from: per object, what the layout needs
//! in memory (box, record length, key, payload, name), and its mesh only
//! when its geometry is written or its levels of detail computed. A
//! [`Scene`] holds every mesh; a [`StagedScene`](super::StagedScene) keeps
//! them in a spill file, so a scene larger than memory loads the same tree.

use std::borrow::Cow;

use crate::geom::Aabb;

use crate::scene::{Key, KeyError, Mesh, Object, ObjectId, Scene, unique_keys};
use crate::store::StorageError;
use crate::store::format::geometry;

/// The objects of one bulk load, by id.
pub(crate) trait ObjectSource: Sync {
    fn len(&self) -> usize;
    fn aabb(&self, id: ObjectId) -> Aabb;
    /// Bytes of the object's geometry record.
    fn record_len(&self, id: ObjectId) -> u64;
    /// Its own key, or its id as an integer key.
    fn key(&self, id: ObjectId) -> Key;
    fn payload(&self, id: ObjectId) -> &[u8];
    fn name(&self, id: ObjectId) -> &str;
    fn mesh(&self, id: ObjectId) -> Result<Cow<'_, Mesh>, StorageError>;
    fn triangle_count(&self) -> u64;

    /// Appends the object's geometry record to `out`; returns its vertex count.
    fn encode_record(&self, id: ObjectId, out: &mut Vec<u8>) -> Result<u64, StorageError> {
        let mesh = self.mesh(id)?;
        geometry::encode_object(id, &mesh, out);
        Ok(mesh.vertex_count() as u64)
    }

    fn object_boxes(&self) -> Vec<Aabb> {
        (0..self.len()).map(|i| self.aabb(ObjectId(i as u32))).collect()
    }

    fn record_lens(&self) -> Vec<u64> {
        (0..self.len()).map(|i| self.record_len(ObjectId(i as u32))).collect()
    }

    /// Refuses duplicate keys (the first pair in key order).
    fn check_unique_keys(&self) -> Result<(), KeyError> {
        unique_keys((0..self.len() as u32).map(|i| (self.key(ObjectId(i)), ObjectId(i))).collect())
    }
}

impl ObjectSource for Scene {
    fn len(&self) -> usize {
        Scene::len(self)
    }

    fn aabb(&self, id: ObjectId) -> Aabb {
        self.object(id).map_or(Aabb::EMPTY, Object::aabb)
    }

    fn record_len(&self, id: ObjectId) -> u64 {
        self.object(id).map_or(0, |o| geometry::record_len(&o.mesh))
    }

    fn key(&self, id: ObjectId) -> Key {
        Scene::key(self, id).unwrap_or(Key::Int(u64::from(id.0)))
    }

    fn payload(&self, id: ObjectId) -> &[u8] {
        self.object(id).map_or(&[], |o| &o.payload)
    }

    fn name(&self, id: ObjectId) -> &str {
        self.object(id).map_or("", |o| &o.name)
    }

    fn mesh(&self, id: ObjectId) -> Result<Cow<'_, Mesh>, StorageError> {
        self.object(id)
            .map(|o| Cow::Borrowed(&o.mesh))
            .ok_or_else(|| StorageError::Invalid(format!("no object {id}")))
    }

    fn triangle_count(&self) -> u64 {
        Scene::triangle_count(self) as u64
    }
}

/// Checks one object as a write takes it: a payload within its limit,
/// coordinates within the format's range.
pub(crate) fn check_object(id: ObjectId, object: &Object) -> Result<(), crate::Error> {
    object.check_payload(id)?;
    crate::bulk::check_object_range(id, &object.mesh, geometry::MAX_COORDINATE)?;
    Ok(())
}
