//! Objects and scenes: S = {o_1, ..., o_N} (Definition 1.2.1).

use super::Mesh;
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

/// One object of a scene: a name and a triangle mesh in millimetres.
#[derive(Debug, Clone, PartialEq)]
pub struct Object {
    pub name: String,
    pub mesh: Mesh,
}

impl Object {
    /// An object named `name` with geometry `mesh`.
    pub fn new(name: impl Into<String>, mesh: Mesh) -> Object {
        Object { name: name.into(), mesh }
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
