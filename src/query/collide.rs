//! Collision and proximity (clearance) of a query object under a rigid pose
//! against the scene, through the traversal of `traverse.rs`: bounds grown
//! by the clearance d below M, exact triangle contacts and distances (parry)
//! at M.

use super::QueryError;
use std::collections::{HashMap, HashSet};

use super::shape::Triangles;
use super::traverse::{QueryAnswer, QueryOptions, traverse};
use crate::db::ReadTransaction;
use crate::geom::Pose;
use crate::scene::{Mesh, ObjectId};
use crate::store::format::node::LodRef;
use crate::store::{BlockCache, ReadStats};

/// A collision or clearance query's settings.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct CollideOptions {
    /// Level and block budget.
    pub query: QueryOptions,
    /// d, mm: objects within d of the query object collide (0: touching).
    pub clearance: f64,
    /// An object left out of the answer: the query object itself when it is
    /// one of the scene's objects.
    pub exclude: Option<ObjectId>,
}

/// The objects whose surfaces come within `opts.clearance` of `mesh` placed
/// by `pose` (rotated about its box centre, then moved).
pub fn collide(
    txn: &ReadTransaction,
    mesh: &Mesh,
    pose: &Pose,
    opts: &CollideOptions,
    cache: Option<&mut BlockCache>,
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

/// The exact meshes of `ids`, in their order: each leaf's object boxes are
/// read, and the geometry of the leaves holding a wanted object.
pub fn object_meshes(txn: &ReadTransaction, ids: &[ObjectId]) -> Result<Vec<Mesh>, QueryError> {
    let info = txn.info().ok_or(QueryError::NoTree)?;
    if let Some(bad) = ids.iter().find(|id| id.0 >= info.objects) {
        return Err(QueryError::NoObject { id: bad.0, objects: info.objects });
    }
    let wanted: HashSet<ObjectId> = ids.iter().copied().collect();
    let mut cache = BlockCache::new(usize::MAX);
    let mut stats = ReadStats::default();
    let mut leaves = Vec::new();
    txn.walk_nodes(&mut stats, |_, rec| {
        if rec.is_leaf() {
            leaves.push(rec.clone());
        }
        Ok(())
    })?;
    let mut found: HashMap<ObjectId, Mesh> = HashMap::new();
    for rec in leaves {
        let Some((level, objects, entry)) = rec.entry(1, true) else { continue };
        let piece = txn.read_entry(&rec, level, objects, entry, &mut stats, Some(&mut cache))?;
        if !piece.and_then(|p| p.object_ids()).is_some_and(|v| v.iter().any(|id| wanted.contains(id))) {
            continue;
        }
        let exact = rec.lods.last().map_or(LodRef::Absent, |pair| pair[1]);
        for (id, mesh) in txn.read_objects(&exact, &mut stats, Some(&mut cache))? {
            if wanted.contains(&id) {
                found.insert(id, mesh);
            }
        }
    }
    ids.iter()
        .map(|id| found.get(id).cloned().ok_or(QueryError::NoObject { id: id.0, objects: info.objects }))
        .collect()
}
