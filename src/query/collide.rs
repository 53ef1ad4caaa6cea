//! Collision and proximity (clearance) of a query object under a rigid pose
//! against the scene, through the one traversal: bounds grown by the
//! clearance d below M, exact triangle contacts and distances (parry) at M.
//! Surfaces are closed sets: a shared face, edge or vertex is a contact,
//! and the test is symmetric, so object a's answer holds b exactly when
//! b's holds a.

use std::collections::{HashMap, HashSet};
use std::sync::Arc;

use super::QueryError;
use super::select::{Everything, Triangles};
use super::{QueryAnswer, QueryOptions, Visitor, traverse, walk};
use crate::geom::{Aabb, Pose};
use crate::scene::{Mesh, ObjectId};
use crate::store::format::geometry;
use crate::store::format::node::NodeView;
use crate::store::{Block, BlockCache, StorageError};
use crate::tree::{ReadTransaction, Reads, view};

/// A collision or clearance query's settings.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct CollideOptions {
    /// Level and block budget.
    pub query: QueryOptions,
    /// d, mm: objects within d of the query object collide (0: touching or
    /// intersecting).
    pub clearance: f64,
    /// An object left out of the answer: the query object itself when it is
    /// one of the scene's objects.
    pub exclude: Option<ObjectId>,
}

/// The objects whose surfaces come within `opts.clearance` of `mesh` placed
/// by `pose` (rotated about its box centre, then moved); at clearance 0 the
/// objects that share a point with it (touching counts, decided exactly).
pub fn collide(
    txn: &ReadTransaction,
    mesh: &Mesh,
    pose: &Pose,
    opts: &CollideOptions,
    cache: Option<&BlockCache>,
) -> Result<QueryAnswer, QueryError> {
    let probe = Triangles::posed(mesh, pose, opts.clearance)?;
    let answer = traverse(txn, &probe, &opts.query, cache)?;
    Ok(match opts.exclude {
        Some(id) => answer.without(id),
        None => answer,
    })
}

/// Object `id`'s exact mesh, read from the file (its reads are not a
/// query's).
pub fn object_mesh(txn: &ReadTransaction, id: ObjectId) -> Result<Mesh, QueryError> {
    let mut meshes = object_meshes(txn, &[id])?;
    meshes.pop().ok_or(QueryError::NoObject { id: id.0, objects: 0 })
}

/// Reads the meshes of the wanted objects from the leaves that hold them.
struct Fetch<'t, 'c> {
    txn: &'t ReadTransaction,
    wanted: HashSet<ObjectId>,
    reads: Reads<'c>,
    /// Each wanted object's parts, in record order.
    found: HashMap<ObjectId, Vec<Mesh>>,
}

impl Visitor for Fetch<'_, '_> {
    fn node(&mut self, block: &Arc<Block>, offset: u32, _: &Aabb) -> Result<(), StorageError> {
        let NodeView::Leaf(leaf) = view(block, offset)? else { return Ok(()) };
        for i in 0..leaf.len() {
            if leaf.object(i).is_some_and(|o| self.wanted.contains(&ObjectId(o.object_id))) {
                let (id, mesh) = self.txn.read_object(block.id(), &leaf, i, &mut self.reads)?;
                self.found.entry(id).or_default().push(mesh);
            }
        }
        Ok(())
    }
}

/// The exact meshes of `ids`, in their order: the tree's node blocks are
/// walked and the geometry of the wanted objects read.
pub fn object_meshes(txn: &ReadTransaction, ids: &[ObjectId]) -> Result<Vec<Mesh>, QueryError> {
    let objects = txn.info().map_or(0, |i| i.objects);
    let found = fetch_meshes(txn, ids.iter().copied().collect())?;
    // An id may be asked for more than once.
    ids.iter().map(|id| found.get(id).cloned().ok_or(QueryError::NoObject { id: id.0, objects })).collect()
}

/// The exact meshes of the `wanted` objects the tree holds (an id it does
/// not hold is left out): one walk of the node blocks, and the geometry of
/// the wanted objects read once each. A file with no tree holds none.
pub(crate) fn fetch_meshes(
    txn: &ReadTransaction,
    wanted: HashSet<ObjectId>,
) -> Result<HashMap<ObjectId, Mesh>, QueryError> {
    let Some(root) = txn.root() else { return Ok(HashMap::new()) };
    if wanted.is_empty() {
        return Ok(HashMap::new());
    }
    let mut fetch = Fetch { txn, wanted, reads: Reads::new(None), found: HashMap::new() };
    let all = QueryOptions { lod: Some(1), budget: None, ..Default::default() };
    walk(txn, root, &Everything, &all, &mut Reads::new(None), &mut fetch)?;
    let mut joined = HashMap::with_capacity(fetch.found.len());
    for (id, parts) in fetch.found {
        let mesh = geometry::join(&parts)
            .ok_or_else(|| StorageError::Invalid(format!("object {id}: its parts do not join")))?;
        joined.insert(id, mesh);
    }
    Ok(joined)
}
