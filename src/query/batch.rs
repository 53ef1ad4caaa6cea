//! Many queries in one read transaction, each a [`Request`] (the JSON lines
//! of `mktree batch`, through serde) answered as a [`Response`]: objects
//! meeting a box or a sphere, the k nearest to a point, the first hit (or
//! every hit) along a ray, and the objects touching one of the file's own
//! objects moved and turned. Each runs the one traversal, reading through
//! the cache the caller gives, so a block an earlier request read may be a
//! cache hit.

use serde::{Deserialize, Serialize};

use super::QueryError;
use super::collide::{CollideOptions, collide, object_mesh};
use super::region::query_region;
use super::select::Region;
use super::{QueryAnswer, QueryOptions, TraverseStats};
use crate::geom::{Aabb, Point, Pose, Ray, Sphere, Vector};
use crate::scene::{Key, ObjectId};
use crate::store::{BlockCache, ReadStats};
use crate::tree::ReadTransaction;

/// One query, as a JSON object tagged by `"query"`, e.g.
/// `{"query": "nearest", "point": [0, 0, 0], "k": 3}`. Lengths in mm.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(tag = "query", rename_all = "snake_case", deny_unknown_fields)]
pub enum Request {
    /// The objects meeting the closed box `[x0, y0, z0, x1, y1, z1]`.
    Box {
        /// The box, mm (`"box"` in JSON).
        #[serde(rename = "box")]
        aabb: [f64; 6],
        /// The level k to answer at; absent: M, the exact answer.
        #[serde(default)]
        lod: Option<u8>,
        /// At most this many block reads; absent: no limit.
        #[serde(default)]
        budget: Option<u64>,
    },
    /// The objects meeting a closed ball.
    Sphere {
        /// The ball's centre, mm.
        center: [f64; 3],
        /// The ball's radius, mm.
        radius: f64,
        /// The level k to answer at; absent: M.
        #[serde(default)]
        lod: Option<u8>,
        /// At most this many block reads; absent: no limit.
        #[serde(default)]
        budget: Option<u64>,
    },
    /// The `k` objects nearest `point`, nearest first, with their distances.
    Nearest {
        /// The point, mm.
        point: [f64; 3],
        /// How many objects.
        k: usize,
    },
    /// The first object the ray meets (`all`: every one, in order), with t
    /// and the point.
    Ray {
        /// The ray's origin, mm.
        origin: [f64; 3],
        /// The ray's direction (not zero; any length).
        direction: [f64; 3],
        /// How far along the ray to look, mm; absent: no end.
        #[serde(default)]
        max_distance: Option<f64>,
        /// Every object the ray meets, in order, not only the first.
        #[serde(default)]
        all: bool,
    },
    /// The objects within `clearance` of object `object`, rotated about its
    /// box centre by `rotate_deg` (x, then y, then z) and moved by
    /// `translate`; the object itself is left out. Its mesh is read first,
    /// and those reads are not counted.
    Collide {
        /// The id of the file's object to move.
        object: u32,
        /// The move, mm.
        #[serde(default)]
        translate: [f64; 3],
        /// The rotation about x, then y, then z, degrees.
        #[serde(default)]
        rotate_deg: [f64; 3],
        /// The distance (mm) within which an object counts as touching.
        #[serde(default)]
        clearance: f64,
        /// The level k to answer at; absent: M.
        #[serde(default)]
        lod: Option<u8>,
        /// At most this many block reads; absent: no limit.
        #[serde(default)]
        budget: Option<u64>,
    },
}

/// A request's answer.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Response {
    /// Sorted ids (box, sphere, collide); nearest first (nearest, ray).
    pub objects: Vec<ObjectId>,
    /// The application's key of each of `objects`, in the same order.
    pub keys: Vec<Key>,
    /// Nearest: each object's distance; ray: each hit's t.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub distances: Option<Vec<f64>>,
    /// Ray: the points hit.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub points: Option<Vec<[f64; 3]>>,
    /// Budgeted: objects not refined to the level asked for.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub maybe: Vec<ObjectId>,
    /// Blocks read from the device, by kind, and found in the cache.
    pub reads: ReadStats,
}

impl Response {
    fn of(a: QueryAnswer) -> Response {
        Response {
            objects: a.objects,
            keys: a.keys,
            distances: None,
            points: None,
            maybe: a.maybe,
            reads: a.stats.reads,
        }
    }

    /// Objects with their keys and distances (or t), nearest first.
    fn ranked(found: Vec<(ObjectId, Key, f64)>, stats: &TraverseStats) -> Response {
        let mut r = Response {
            objects: Vec::with_capacity(found.len()),
            keys: Vec::with_capacity(found.len()),
            distances: Some(Vec::with_capacity(found.len())),
            points: None,
            maybe: Vec::new(),
            reads: stats.reads,
        };
        for (o, k, d) in found {
            r.objects.push(o);
            r.keys.push(k);
            r.distances.get_or_insert_default().push(d);
        }
        r
    }
}

/// Answers `request` in `txn`, reading through `cache` when given.
pub fn answer_request(
    txn: &ReadTransaction,
    request: &Request,
    cache: Option<&BlockCache>,
) -> Result<Response, QueryError> {
    let opts = |lod: &Option<u8>, budget: &Option<u64>| QueryOptions {
        lod: *lod,
        budget: *budget,
        ..Default::default()
    };
    Ok(match request {
        Request::Box { aabb, lod, budget } => {
            Response::of(query_region(txn, &Region::Box(Aabb::from_array(*aabb)), &opts(lod, budget), cache)?)
        }
        Request::Sphere { center, radius, lod, budget } => {
            let region = Region::Sphere(Sphere::new(Point::from(*center), *radius)?);
            Response::of(query_region(txn, &region, &opts(lod, budget), cache)?)
        }
        Request::Nearest { point, k } => {
            let mut it = txn.nearest(Point::from(*point), cache)?;
            let found = it.by_ref().take(*k).collect::<Result<Vec<_>, _>>()?;
            Response::ranked(found.into_iter().map(|n| (n.object, n.key, n.distance)).collect(), &it.stats())
        }
        Request::Ray { origin, direction, max_distance, all } => {
            let ray = Ray::new(Point::from(*origin), Vector::from(*direction), *max_distance)?;
            let mut it = txn.ray(&ray, cache)?;
            let hits = it.by_ref().take(if *all { usize::MAX } else { 1 }).collect::<Result<Vec<_>, _>>()?;
            let mut r =
                Response::ranked(hits.iter().map(|h| (h.object, h.key.clone(), h.t)).collect(), &it.stats());
            r.points = Some(hits.iter().map(|h| h.point).collect());
            r
        }
        Request::Collide { object, translate, rotate_deg, clearance, lod, budget } => {
            let id = ObjectId(*object);
            let mesh = object_mesh(txn, id)?;
            let pose = Pose::from_degrees(*translate, *rotate_deg)?;
            let o = CollideOptions { query: opts(lod, budget), clearance: *clearance, exclude: Some(id) };
            Response::of(collide(txn, &mesh, &pose, &o, cache)?)
        }
    })
}
