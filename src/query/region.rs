//! Region queries (box, sphere, frustum) at a level k through the shared
//! traversal, and the level-M box query of the first issue, kept for its
//! callers. Box queries: the objects whose exact geometry (their triangles, as
//! surfaces) meets an axis-aligned box. The traversal prunes a child from its
//! parent's copy of the child's box, so a block is read only when some node in
//! it may hold an answer; blocks are clustered subtrees, so a depth-first
//! descent reads each block at most once.

use std::sync::Arc;
use std::time::Instant;

use super::QueryError;
use super::shape::Region;
use super::traverse::{QueryAnswer, QueryOptions, traverse};
use crate::db::{NodeLocation, ReadTransaction};
use crate::geom::{Aabb, intersects_triangle_box};
use crate::scene::{Mesh, ObjectId, Scene};
use crate::store::format::node::NodeRecord;
use crate::store::{BlockCache, ReadStats, StorageError};

/// Work done by a query besides its reads.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct QueryStats {
    pub reads: ReadStats,
    pub nodes_visited: u64,
    pub leaves_visited: u64,
    pub objects_tested: u64,
    pub triangles_tested: u64,
    pub seconds: f64,
}

/// The answer to a box query.
#[derive(Debug, Clone, PartialEq)]
pub struct BoxQuery {
    /// Sorted ids of the objects that meet the box.
    pub objects: Vec<ObjectId>,
    pub stats: QueryStats,
}

/// True when some triangle of `mesh` meets `query`.
fn mesh_meets_box(mesh: &Mesh, query: &Aabb, triangles_tested: &mut u64) -> bool {
    if !mesh.aabb().intersects(query) {
        return false;
    }
    mesh.triangle_points().any(|t| {
        *triangles_tested += 1;
        intersects_triangle_box(&t, query)
    })
}

/// The box query of `txn`'s tree, reading through `cache` when given.
pub fn query_box(
    txn: &ReadTransaction,
    query: &Aabb,
    mut cache: Option<&mut BlockCache>,
) -> Result<BoxQuery, StorageError> {
    let started = Instant::now();
    let mut stats = QueryStats::default();
    let mut objects = Vec::new();
    if let Some(root) = txn.root() {
        let records =
            txn.read_node_block(root.block, root.checksum, &mut stats.reads, cache.as_deref_mut())?;
        let mut stack: Vec<(Arc<Vec<NodeRecord>>, NodeLocation)> = Vec::new();
        if crate::db::record_at(&records, root.block, root.slot)?.aabb().intersects(query) {
            stack.push((records, root));
        }
        let mut guard = crate::db::TraversalGuard::new(txn);
        while let Some((records, at)) = stack.pop() {
            guard.visit(at)?;
            let rec = crate::db::record_at(&records, at.block, at.slot)?;
            stats.nodes_visited += 1;
            match &rec.children {
                Some((kids, _)) => {
                    for c in kids.iter().rev().filter(|c| c.aabb().intersects(query)) {
                        let loc = NodeLocation { block: c.block, slot: c.slot, checksum: None };
                        if c.block == at.block {
                            stack.push((records.clone(), loc));
                        } else {
                            let child = txn.read_node_block(
                                c.block,
                                Some(c.checksum),
                                &mut stats.reads,
                                cache.as_deref_mut(),
                            )?;
                            stack.push((child, loc));
                        }
                    }
                }
                None => {
                    stats.leaves_visited += 1;
                    let exact = rec.lods.last().map(|pair| pair[1]).unwrap_or_default();
                    for (id, mesh) in txn.read_objects(&exact, &mut stats.reads, cache.as_deref_mut())? {
                        stats.objects_tested += 1;
                        if mesh_meets_box(&mesh, query, &mut stats.triangles_tested) {
                            objects.push(id);
                        }
                    }
                }
            }
        }
    }
    objects.sort_unstable();
    stats.seconds = started.elapsed().as_secs_f64();
    Ok(BoxQuery { objects, stats })
}

/// A box, sphere or frustum query at `opts`' level and budget, through the
/// shared traversal (`traverse.rs`).
pub fn query_region(
    txn: &ReadTransaction,
    region: &Region,
    opts: &QueryOptions,
    cache: Option<&mut BlockCache>,
) -> Result<QueryAnswer, QueryError> {
    traverse(txn, region, opts, cache)
}

/// The same answer by testing every object of `scene`: the oracle for tests.
pub fn brute_force_box(scene: &Scene, query: &Aabb) -> Vec<ObjectId> {
    let mut n = 0;
    (0..scene.len() as u32)
        .map(ObjectId)
        .filter(|&id| scene.objects().get(id.index()).is_some_and(|o| mesh_meets_box(&o.mesh, query, &mut n)))
        .collect()
}
