//! Objects and scenes: S = {o_1, ..., o_N} (Definition 1.2.1).

use super::{Key, KeyTooLong, Mesh};
use crate::geom::Aabb;

/// An object's id: its 0-based position in the input.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize)]
#[serde(transparent)]
pub struct ObjectId(pub u32);

impl ObjectId {
    /// The id as an index into [`Scene::objects`].
    pub fn index(self) -> usize {
        self.0 as usize
    }
}

impl std::fmt::Display for ObjectId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        self.0.fmt(f)
    }
}

/// One object of a scene: a name and a triangle mesh in millimetres, with
/// the application's key and payload.
#[derive(Debug, Clone, PartialEq)]
pub struct Object {
    /// The object's name, from the input file or the generator.
    pub name: String,
    /// Its triangles, mm.
    pub mesh: Mesh,
    /// The application's key; `None` is the object's id as an integer key.
    pub key: Option<Key>,
    /// Opaque bytes kept with the key (at most [`Object::MAX_PAYLOAD`]),
    /// returned by a lookup by key, never read by a query.
    pub payload: Vec<u8>,
}

impl Object {
    /// The largest payload, bytes.
    pub const MAX_PAYLOAD: usize = 1024;

    /// An object named `name` with geometry `mesh`, keyed by its id.
    pub fn new(name: impl Into<String>, mesh: Mesh) -> Object {
        Object { name: name.into(), mesh, key: None, payload: Vec::new() }
    }

    /// This object with the application's key `key`.
    pub fn with_key(mut self, key: impl Into<Key>) -> Object {
        self.key = Some(key.into());
        self
    }

    /// This object with `payload` kept beside its key.
    pub fn with_payload(mut self, payload: impl Into<Vec<u8>>) -> Object {
        self.payload = payload.into();
        self
    }

    /// Refuses a payload over [`Object::MAX_PAYLOAD`], naming the object as `id`.
    pub(crate) fn check_payload(&self, id: ObjectId) -> Result<(), KeyError> {
        match self.payload.len() {
            len if len > Object::MAX_PAYLOAD => Err(KeyError::PayloadTooLong { object: id, len }),
            _ => Ok(()),
        }
    }

    /// The object's box.
    pub fn aabb(&self) -> Aabb {
        self.mesh.aabb()
    }
}

/// A scene: objects in input order, so an object's id is its index.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Scene {
    objects: Vec<Object>,
}

impl Scene {
    /// A scene of these objects, ids in this order.
    pub fn new(objects: Vec<Object>) -> Scene {
        Scene { objects }
    }

    /// The objects, by id, taken out of the scene.
    pub fn into_objects(self) -> Vec<Object> {
        self.objects
    }

    /// The objects; `objects()[id.index()]` is object `id`.
    pub fn objects(&self) -> &[Object] {
        &self.objects
    }

    /// Object `id`, if there is one.
    pub fn object(&self, id: ObjectId) -> Option<&Object> {
        self.objects.get(id.index())
    }

    /// Number of objects.
    pub fn len(&self) -> usize {
        self.objects.len()
    }

    /// True when the scene has no objects.
    pub fn is_empty(&self) -> bool {
        self.objects.is_empty()
    }

    /// Adds an object; it gets the next id.
    pub fn push(&mut self, object: Object) -> ObjectId {
        self.objects.push(object);
        ObjectId((self.objects.len() - 1) as u32)
    }

    /// Object `id`'s key: its own, or its id as an integer.
    pub fn key(&self, id: ObjectId) -> Option<Key> {
        let o = self.objects.get(id.index())?;
        Some(o.key.clone().unwrap_or(Key::Int(u64::from(id.0))))
    }

    /// Keys every object by its name (as bytes); `check_keys` then says
    /// whether the names are unique.
    pub fn key_by_names(&mut self) -> Result<(), KeyTooLong> {
        for o in &mut self.objects {
            o.key = Some(Key::bytes(o.name.as_bytes())?);
        }
        Ok(())
    }

    /// Checks that every key is unique and every payload short enough.
    pub fn check_keys(&self) -> Result<(), KeyError> {
        for (i, o) in self.objects.iter().enumerate() {
            o.check_payload(ObjectId(i as u32))?;
        }
        unique_keys(
            (0..self.objects.len() as u32)
                .map(|i| (self.key(ObjectId(i)).unwrap_or(Key::Int(u64::from(i))), ObjectId(i)))
                .collect(),
        )
    }

    /// The box of every object, indexed by id.
    pub fn object_boxes(&self) -> Vec<Aabb> {
        self.objects.iter().map(Object::aabb).collect()
    }

    /// R(S): the box of the whole scene.
    pub fn aabb(&self) -> Aabb {
        self.objects.iter().fold(Aabb::EMPTY, |b, o| b.union(&o.aabb()))
    }

    /// Total triangles.
    pub fn triangle_count(&self) -> usize {
        self.objects.iter().map(|o| o.mesh.triangle_count()).sum()
    }

    /// Total vertices.
    pub fn vertex_count(&self) -> usize {
        self.objects.iter().map(|o| o.mesh.vertex_count()).sum()
    }
}

/// Refuses the first pair of `keys` (key, object) with the same key, in key order.
pub(crate) fn unique_keys(mut keys: Vec<(Key, ObjectId)>) -> Result<(), KeyError> {
    keys.sort();
    match keys.windows(2).find(|w| w[0].0 == w[1].0) {
        Some(w) => Err(KeyError::Duplicate { key: w[0].0.clone(), first: w[0].1, second: w[1].1 }),
        None => Ok(()),
    }
}

/// Keys a scene cannot be stored with.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum KeyError {
    /// Two objects share a key.
    #[error("objects {first} and {second} share the key {key}: keys are unique")]
    Duplicate {
        /// The key.
        key: Key,
        /// The first object with it.
        first: ObjectId,
        /// The second object with it.
        second: ObjectId,
    },
    /// A payload longer than [`Object::MAX_PAYLOAD`].
    #[error("object {object}'s payload has {len} bytes (at most {max})", max = Object::MAX_PAYLOAD)]
    PayloadTooLong {
        /// The object.
        object: ObjectId,
        /// The payload's length, bytes.
        len: usize,
    },
    /// An insert of a key the tree already holds.
    #[error("an object with key {key} is already in the tree")]
    Exists {
        /// The key.
        key: Key,
    },
    /// An update of a key the tree does not hold.
    #[error("no object has key {key}")]
    NotFound {
        /// The key.
        key: Key,
    },
    /// An object whose key, payload and name together do not fit one key
    /// block (format-spec/keys.md): larger blocks hold it.
    #[error(
        "the key {key} with its payload and name takes {len} bytes and a key block holds {capacity}: use larger blocks"
    )]
    EntryTooLarge {
        /// The key.
        key: Key,
        /// The entry's length, bytes.
        len: usize,
        /// What a key block holds, bytes.
        capacity: usize,
    },
    /// An insert that asks for the next integer key when the largest the
    /// tree holds is `u64::MAX`.
    #[error("integer keys are exhausted")]
    IntegersExhausted,
    /// An update of an object that carries no key to name the one it replaces.
    #[error("an update names its object by key")]
    Unnamed,
    /// A key longer than [`Key::MAX_BYTES`].
    #[error(transparent)]
    TooLong(#[from] super::key::KeyTooLong),
}
