//! Region queries (box, sphere, frustum) at a level k through the one
//! traversal: the objects whose exact geometry (their triangles, as
//! surfaces) meets the region at level M, a superset below. Region and
//! triangles are closed sets: an object that only touches a box region (a
//! face on the box's face, a corner on its edge) is in the answer, decided
//! exactly. Spheres and frusta are tested in floating point, so an exact
//! tie with them may go either way.

use super::QueryError;
use super::select::Region;
use super::{QueryAnswer, QueryOptions, traverse};
use crate::store::BlockCache;
use crate::tree::ReadTransaction;

/// A box, sphere or frustum query at `opts`' level and budget, reading
/// through `cache` (a pool kept across queries) when given.
pub fn query_region(
    txn: &ReadTransaction,
    region: &Region,
    opts: &QueryOptions,
    cache: Option<&BlockCache>,
) -> Result<QueryAnswer, QueryError> {
    traverse(txn, region, opts, cache)
}
