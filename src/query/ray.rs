//! Ray casting: the objects a ray meets, in order of the distance t at
//! which it first meets each, best first over the one traversal (node boxes
//! by the distance the ray enters them, then object boxes, then each
//! object's triangles, read at level M). Surfaces are closed sets: a ray
//! through an edge or a vertex hits; what is exact is set out in `geom::ray`.
//! Equal distances come by id.

use serde::Serialize;

use super::QueryError;
use super::rank::Rank;
use super::select::Selection;
use super::{QueryOptions, Select, TraverseStats};
use crate::geom::{Point, Ray};
use crate::scene::{Key, ObjectId};
use crate::store::BlockCache;
use crate::tree::{ReadTransaction, Reads};

/// Where a ray meets an object first.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RayHit {
    /// The object.
    pub object: ObjectId,
    /// The application's key for it.
    pub key: Key,
    /// The distance from the ray's origin, mm.
    pub t: f64,
    /// The point at distance t.
    pub point: [f64; 3],
}

/// The objects a ray meets, nearest first ([`ReadTransaction::ray`]).
pub struct RayHits<'a> {
    select: Select<'a, Rank>,
    ray: Ray,
}

impl RayHits<'_> {
    /// What the hits so far cost: blocks read, nodes, geometry tests.
    pub fn stats(&self) -> TraverseStats {
        self.select.stats()
    }
}

impl Iterator for RayHits<'_> {
    type Item = Result<RayHit, QueryError>;

    fn next(&mut self) -> Option<Self::Item> {
        let d = self.select.next_accepted()?;
        Some(
            d.map(|d| hit(&self.ray, (d.hit.object, d.hit.key), d.distance.unwrap_or(0.0)))
                .map_err(QueryError::from),
        )
    }
}

/// The distance `ray` is followed in a tree whose objects lie in `scene`.
pub(crate) fn rank(ray: &Ray, scene: &crate::geom::Aabb) -> Rank {
    Rank::Ray { ray: *ray, reach: ray.reach(scene) }
}

impl ReadTransaction {
    /// The objects `ray` meets, in order of distance (ties by id), reading
    /// through `cache` when given. Lazy: the first hit reads only what it
    /// needs ([`first_hit`](Self::first_hit)).
    pub fn ray<'a>(&'a self, ray: &Ray, cache: Option<&'a BlockCache>) -> Result<RayHits<'a>, QueryError> {
        let root = self.root();
        let scene = root.map_or(crate::geom::Aabb::EMPTY, |r| r.aabb);
        let rank = rank(ray, &scene);
        rank.check_input()?;
        let select = Select::new(self, root, rank, &QueryOptions::default(), Reads::new(cache), Some(rank))?;
        Ok(RayHits { select, ray: *ray })
    }

    /// The first object `ray` meets, with its distance and point.
    pub fn first_hit(&self, ray: &Ray, cache: Option<&BlockCache>) -> Result<Option<RayHit>, QueryError> {
        self.ray(ray, cache)?.next().transpose()
    }
}

/// `object` met by `ray` at `t`.
pub(crate) fn hit(ray: &Ray, (object, key): (ObjectId, Key), t: f64) -> RayHit {
    let p: Point = ray.at(t);
    RayHit { object, key, t, point: [p.x, p.y, p.z] }
}
