//! The objects nearest a point, in order of exact distance (best first over
//! the one traversal: node boxes, then object boxes, then each object's
//! triangles, read at level M). The distance is to the object's surface,
//! its triangles as closed sets, measured in floating point (parry's
//! point-triangle distance); equal distances come by id, so the order is
//! deterministic. `take(k)` reads only what the k nearest need.

use super::QueryError;
use super::rank::Rank;
use super::select::Selection;
use super::{QueryOptions, Select, TraverseStats};
use crate::geom::{Point, ShapeError};
use crate::scene::{Key, ObjectId};
use crate::store::BlockCache;
use crate::tree::{ReadTransaction, Reads};

/// An object at its distance from the point asked about.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Near {
    /// The object.
    pub object: ObjectId,
    /// The application's key for it.
    pub key: Key,
    /// From the point to the object's surface, mm.
    pub distance: f64,
}

/// The objects of a tree by distance from a point, nearest first
/// ([`ReadTransaction::nearest`]).
pub struct Nearest<'a> {
    select: Select<'a, Rank>,
}

impl Nearest<'_> {
    /// What the objects so far cost: blocks read, nodes, geometry tests.
    pub fn stats(&self) -> TraverseStats {
        self.select.stats()
    }
}

impl Iterator for Nearest<'_> {
    type Item = Result<Near, QueryError>;

    fn next(&mut self) -> Option<Self::Item> {
        let d = self.select.next_accepted()?;
        Some(
            d.map(|d| Near { object: d.hit.object, key: d.hit.key, distance: d.distance.unwrap_or(0.0) })
                .map_err(QueryError::from),
        )
    }
}

impl ReadTransaction {
    /// Every object by its exact distance from `point` (finite), nearest
    /// first, ties by id; reads through `cache` when given. Lazy: the k
    /// nearest (`.take(k)`) read only the blocks they need.
    ///
    /// ```
    /// # use mktree::db::{CreateOptions, Database};
    /// # use mktree::bulk::BuildParams;
    /// # use mktree::geom::Point;
    /// # use mktree::scene::generate::{GenOptions, Preset, generate_scene};
    /// # let dir = tempfile::tempdir()?;
    /// # let scene = generate_scene(&GenOptions { preset: Preset::Tanker1, objects: None, seed: 1 })?;
    /// # let db = Database::create(dir.path().join("t1.mkt"), CreateOptions::default())?;
    /// # let mut w = db.begin_write()?;
    /// # w.bulk_load(&scene, &BuildParams::paper(), &|_| {})?;
    /// # w.commit()?;
    /// let r = db.begin_read()?;
    /// let three: Vec<_> = r.nearest(Point::new(0.0, 0.0, 0.0), None)?.take(3).collect::<Result<_, _>>()?;
    /// let d: Vec<f64> = three.iter().map(|n: &mktree::query::Near| n.distance).collect();
    /// assert!(three.len() == 3 && d[0] <= d[1] && d[1] <= d[2]);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn nearest<'a>(
        &'a self,
        point: Point,
        cache: Option<&'a BlockCache>,
    ) -> Result<Nearest<'a>, QueryError> {
        if !point.iter().all(|c| c.is_finite()) {
            return Err(ShapeError::NotFinite { what: "a point" }.into());
        }
        let rank = Rank::Nearest(point);
        rank.check_input()?;
        let select =
            Select::new(self, self.root(), rank, &QueryOptions::default(), Reads::new(cache), Some(rank))?;
        Ok(Nearest { select })
    }
}
