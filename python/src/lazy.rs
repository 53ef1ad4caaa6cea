//! Lazy answers: the engine's iterators (`Select`, `Nearest`, `RayHits`)
//! as Python iterators. Nothing is read before the first `next`; a loop
//! that stops early reads only what its hits needed, and `stats` tells so.
//!
//! The engine's iterators borrow the read transaction (and the selection
//! they run). Each Python iterator owns an `Arc` of the transaction and the
//! boxed selection beside the iterator, declared after it so dropped after
//! it, and holds the iterator as `'static` (argued at each `transmute`).
//! They are `unsendable`: the engine's traversal state stays on the thread
//! that made it, and each step is short, so it runs attached.

use std::sync::Arc;

use mktree::ReadTransaction;
use mktree::geom::{Point, Ray};
use mktree::query::{Nearest, QueryOptions, RayHits, Select, Selection};
use pyo3::prelude::*;

use crate::answers::{Hit, Near, RayHit, Stats};
use crate::convert::{bounds, key_to_py};
use crate::errors::{Failure, py_err};

type StaticSelect = Select<'static, &'static dyn Selection>;

/// Hits of a region or collision query, one at a time.
#[pyclass(unsendable, module = "mktree")]
pub struct HitIterator {
    // Declared (so dropped) before what it borrows.
    iter: StaticSelect,
    _selection: Box<dyn Selection>,
    _txn: Arc<ReadTransaction>,
}

impl HitIterator {
    pub fn new(
        py: Python<'_>,
        txn: Arc<ReadTransaction>,
        selection: Box<dyn Selection>,
        opts: QueryOptions,
        cache: bool,
    ) -> PyResult<HitIterator> {
        let iter = txn.select(&*selection, &opts, cache.then(|| txn.cache())).map_err(py_err(py))?;
        // SAFETY: `iter` borrows the transaction inside `txn`'s `Arc`
        // allocation (and its cache) and the selection inside `selection`'s
        // `Box` allocation; neither moves when the `Arc` and the `Box` move
        // into the struct, which keeps both until `iter`, declared first,
        // has been dropped.
        let iter = unsafe { std::mem::transmute::<Select<'_, &dyn Selection>, StaticSelect>(iter) };
        Ok(HitIterator { iter, _selection: selection, _txn: txn })
    }
}

#[pymethods]
impl HitIterator {
    fn __iter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    fn __next__(&mut self, py: Python<'_>) -> PyResult<Option<Hit>> {
        let Some(hit) = self.iter.next() else { return Ok(None) };
        let hit = hit.map_err(py_err(py))?;
        let proof = serde_json::to_value(hit.proof).ok().and_then(|v| v.as_str().map(str::to_string));
        Ok(Some(Hit {
            key: key_to_py(py, &hit.key)?.unbind(),
            id: hit.object.0,
            bounds: bounds(&hit.aabb),
            level: hit.level,
            proof: proof.unwrap_or_default(),
        }))
    }

    /// What the hits so far cost.
    #[getter]
    fn stats(&self) -> Stats {
        Stats::of(&self.iter.stats())
    }
}

type StaticNearest = Nearest<'static>;

/// Objects by distance from a point, nearest first, one at a time.
#[pyclass(unsendable, module = "mktree")]
pub struct NearIterator {
    iter: StaticNearest,
    _txn: Arc<ReadTransaction>,
}

impl NearIterator {
    pub fn new(
        py: Python<'_>,
        txn: Arc<ReadTransaction>,
        point: Point,
        cache: bool,
    ) -> PyResult<NearIterator> {
        let iter = txn.nearest(point, cache.then(|| txn.cache())).map_err(py_err(py))?;
        // SAFETY: as for `HitIterator::new`: `iter` borrows only what `txn`'s
        // allocation holds, and is dropped before `_txn`.
        let iter = unsafe { std::mem::transmute::<Nearest<'_>, StaticNearest>(iter) };
        Ok(NearIterator { iter, _txn: txn })
    }
}

#[pymethods]
impl NearIterator {
    fn __iter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    fn __next__(&mut self, py: Python<'_>) -> PyResult<Option<Near>> {
        let Some(near) = self.iter.next() else { return Ok(None) };
        let n = near.map_err(|e| Failure::from(e).into_py(py))?;
        Ok(Some(Near { key: key_to_py(py, &n.key)?.unbind(), id: n.object.0, distance: n.distance }))
    }

    /// What the objects so far cost.
    #[getter]
    fn stats(&self) -> Stats {
        Stats::of(&self.iter.stats())
    }
}

type StaticRayHits = RayHits<'static>;

/// Objects a ray meets, nearest first, one at a time.
#[pyclass(unsendable, module = "mktree")]
pub struct RayIterator {
    iter: StaticRayHits,
    _txn: Arc<ReadTransaction>,
}

impl RayIterator {
    pub fn new(py: Python<'_>, txn: Arc<ReadTransaction>, ray: Ray, cache: bool) -> PyResult<RayIterator> {
        let iter = txn.ray(&ray, cache.then(|| txn.cache())).map_err(py_err(py))?;
        // SAFETY: as for `NearIterator::new`.
        let iter = unsafe { std::mem::transmute::<RayHits<'_>, StaticRayHits>(iter) };
        Ok(RayIterator { iter, _txn: txn })
    }
}

#[pymethods]
impl RayIterator {
    fn __iter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    fn __next__(&mut self, py: Python<'_>) -> PyResult<Option<RayHit>> {
        let Some(hit) = self.iter.next() else { return Ok(None) };
        let h = hit.map_err(|e| Failure::from(e).into_py(py))?;
        Ok(Some(RayHit {
            key: key_to_py(py, &h.key)?.unbind(),
            id: h.object.0,
            t: h.t,
            point: (h.point[0], h.point[1], h.point[2]),
        }))
    }

    /// What the hits so far cost.
    #[getter]
    fn stats(&self) -> Stats {
        Stats::of(&self.iter.stats())
    }
}
