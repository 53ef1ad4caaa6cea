//! `mktree.ReadTransaction`: a snapshot and its queries. Every query runs
//! detached from the interpreter, so threads query one file in parallel;
//! by default it reads through the database's shared block cache
//! (`cache=False`: from the file, every block counted as the CLI counts).

use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use mktree::geom::{Camera, Frustum, Ray, Sphere};
use mktree::query::{
    ClashOptions, CollideOptions, Everything, QueryOptions, Region, Triangles, clash, collide, query_region,
};
use mktree::scene::{Key, Mesh};
use mktree::{Aabb, ObjectId};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyString, PyTuple};

use crate::answers::{Answer, Clashes, Info, Near, RayHit, Record};
use crate::convert::{
    bounds, key_from_py, key_to_py, mesh_from_py, mesh_to_py, object_to_py, placement_from_py, point_from_py,
    vector_from_py,
};
use crate::errors::{Failure, Kind, py_err, value_error};
use crate::lazy::{HitIterator, NearIterator, RayIterator};

/// A snapshot of the committed tree, unaffected by later commits, and its
/// queries. Use it as a context manager, or `close` it, to let writers
/// reuse the blocks it pins.
#[pyclass(frozen, module = "mktree")]
pub struct ReadTransaction {
    txn: Mutex<Option<Arc<mktree::ReadTransaction>>>,
}

impl ReadTransaction {
    pub fn new(txn: mktree::ReadTransaction) -> ReadTransaction {
        ReadTransaction { txn: Mutex::new(Some(Arc::new(txn))) }
    }

    pub fn snapshot(&self, py: Python<'_>) -> PyResult<Arc<mktree::ReadTransaction>> {
        let txn = self.txn.lock().unwrap_or_else(|e| e.into_inner());
        txn.clone().ok_or_else(|| Failure::new(Kind::Closed, "the read transaction is closed").into_py(py))
    }

    fn region(&self, py: Python<'_>, region: Region, opts: QueryOptions, cache: bool) -> PyResult<Answer> {
        let txn = self.snapshot(py)?;
        py.detach(|| query_region(&txn, &region, &opts, cache.then(|| txn.cache())))
            .map(Answer::of)
            .map_err(py_err(py))
    }

    /// The query mesh `mesh` placed by `pose`, and the object to leave out
    /// of the answer when `mesh` is the key of a stored object.
    fn probe(
        &self,
        py: Python<'_>,
        txn: &mktree::ReadTransaction,
        mesh: &Bound<'_, PyAny>,
        pose: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<(Mesh, mktree::geom::Pose, Option<ObjectId>)> {
        let placement = placement_from_py(pose)?;
        if is_key(mesh) {
            let key = key_from_py(mesh)?;
            let (record, stored) = py
                .detach(|| Ok::<_, Failure>((txn.get(&key)?, txn.mesh(&key)?)))
                .map_err(|e| e.into_py(py))?;
            let (Some(record), Some(stored)) = (record, stored) else {
                return Err(Failure::new(Kind::KeyNotFound, format!("no object has key {key}")).into_py(py));
            };
            let mut raw = crate::convert::RawMesh {
                vertices: stored.vertices().collect(),
                triangles: stored.triangles().to_vec(),
            };
            let pose = placement.apply(&mut raw);
            let mesh = raw.into_mesh().map_err(value_error)?;
            return Ok((mesh, pose, Some(record.id)));
        }
        let mut raw = mesh_from_py(mesh)?;
        let pose = placement.apply(&mut raw);
        Ok((raw.into_mesh().map_err(value_error)?, pose, None))
    }
}

/// A key rather than a mesh: an int, str or bytes.
fn is_key(obj: &Bound<'_, PyAny>) -> bool {
    obj.is_instance_of::<PyString>()
        || obj.is_instance_of::<PyBytes>()
        || (!obj.is_instance_of::<PyTuple>() && obj.hasattr("__index__").unwrap_or(false))
}

fn options(lod: Option<u8>, budget: Option<u64>) -> QueryOptions {
    QueryOptions { lod, budget, ..Default::default() }
}

fn sphere(center: &Bound<'_, PyAny>, radius: f64) -> PyResult<Region> {
    let c = point_from_py(center, "a sphere's centre")?;
    Sphere::new(c, radius).map(Region::Sphere).map_err(|e| value_error(e.to_string()))
}

fn aabb(lo: &Bound<'_, PyAny>, hi: &Bound<'_, PyAny>) -> PyResult<Region> {
    Ok(Region::Box(Aabb::new(point_from_py(lo, "a box's lo")?, point_from_py(hi, "a box's hi")?)))
}

#[allow(clippy::too_many_arguments)]
fn frustum(
    eye: &Bound<'_, PyAny>,
    target: &Bound<'_, PyAny>,
    fov_deg: f64,
    aspect: f64,
    near: f64,
    far: f64,
) -> PyResult<Region> {
    let camera = Camera {
        eye: point_from_py(eye, "a camera's eye")?,
        target: point_from_py(target, "a camera's target")?,
        fov_deg,
        aspect,
        near,
        far,
    };
    Frustum::from_camera(&camera)
        .map(|f| Region::Frustum(Box::new(f)))
        .map_err(|e| value_error(e.to_string()))
}

fn ray(origin: &Bound<'_, PyAny>, direction: &Bound<'_, PyAny>, max_distance: Option<f64>) -> PyResult<Ray> {
    Ray::new(
        point_from_py(origin, "a ray's origin")?,
        vector_from_py(direction, "a ray's direction")?,
        max_distance,
    )
    .map_err(|e| value_error(e.to_string()))
}

#[pymethods]
impl ReadTransaction {
    /// The objects whose triangles meet the closed box `lo`..`hi` (at level
    /// `lod`, a superset below M; with `budget`, at most that many block reads).
    #[pyo3(signature = (lo, hi, *, lod = None, budget = None, cache = true))]
    fn r#box(
        &self,
        py: Python<'_>,
        lo: &Bound<'_, PyAny>,
        hi: &Bound<'_, PyAny>,
        lod: Option<u8>,
        budget: Option<u64>,
        cache: bool,
    ) -> PyResult<Answer> {
        self.region(py, aabb(lo, hi)?, options(lod, budget), cache)
    }

    /// The objects whose triangles meet the closed ball of `radius` about `center`.
    #[pyo3(signature = (center, radius, *, lod = None, budget = None, cache = true))]
    fn sphere(
        &self,
        py: Python<'_>,
        center: &Bound<'_, PyAny>,
        radius: f64,
        lod: Option<u8>,
        budget: Option<u64>,
        cache: bool,
    ) -> PyResult<Answer> {
        self.region(py, sphere(center, radius)?, options(lod, budget), cache)
    }

    /// The objects whose triangles meet a camera's view frustum.
    #[pyo3(signature = (eye, target, fov_deg, aspect, near, far, *, lod = None, budget = None, cache = true))]
    #[allow(clippy::too_many_arguments)]
    fn frustum(
        &self,
        py: Python<'_>,
        eye: &Bound<'_, PyAny>,
        target: &Bound<'_, PyAny>,
        fov_deg: f64,
        aspect: f64,
        near: f64,
        far: f64,
        lod: Option<u8>,
        budget: Option<u64>,
        cache: bool,
    ) -> PyResult<Answer> {
        self.region(py, frustum(eye, target, fov_deg, aspect, near, far)?, options(lod, budget), cache)
    }

    /// The objects a mesh placed by `pose` touches (or comes within
    /// `clearance` mm of). `mesh` is an `mktree.Mesh`, a `(vertices,
    /// triangles)` pair, a trimesh, or the key of a stored object (left out
    /// of its own answer).
    #[pyo3(signature = (mesh, pose = None, *, clearance = 0.0, lod = None, budget = None, cache = true))]
    #[allow(clippy::too_many_arguments)]
    fn collide(
        &self,
        py: Python<'_>,
        mesh: &Bound<'_, PyAny>,
        pose: Option<&Bound<'_, PyAny>>,
        clearance: f64,
        lod: Option<u8>,
        budget: Option<u64>,
        cache: bool,
    ) -> PyResult<Answer> {
        let txn = self.snapshot(py)?;
        let (mesh, pose, exclude) = self.probe(py, &txn, mesh, pose)?;
        let opts = CollideOptions { query: options(lod, budget), clearance, exclude };
        py.detach(|| collide(&txn, &mesh, &pose, &opts, cache.then(|| txn.cache())))
            .map(Answer::of)
            .map_err(py_err(py))
    }

    /// The objects within `distance` mm of a mesh placed by `pose`: `collide` with a clearance.
    #[pyo3(signature = (mesh, distance, pose = None, *, lod = None, budget = None, cache = true))]
    #[allow(clippy::too_many_arguments)]
    fn clearance(
        &self,
        py: Python<'_>,
        mesh: &Bound<'_, PyAny>,
        distance: f64,
        pose: Option<&Bound<'_, PyAny>>,
        lod: Option<u8>,
        budget: Option<u64>,
        cache: bool,
    ) -> PyResult<Answer> {
        self.collide(py, mesh, pose, distance, lod, budget, cache)
    }

    /// Every pair of stored objects that touch (or come within `clearance` mm).
    #[pyo3(signature = (*, clearance = 0.0, lod = None))]
    fn clash(&self, py: Python<'_>, clearance: f64, lod: Option<u8>) -> PyResult<Clashes> {
        let txn = self.snapshot(py)?;
        let run = || -> Result<Clashes, Failure> {
            let answer = clash(&txn, &ClashOptions { lod, clearance }, Some(txn.cache()))?;
            // The pairs are ids: their keys are in the leaves the run read.
            let mut keys: HashMap<u32, Key> = HashMap::new();
            if !answer.pairs.is_empty() {
                let every = options(Some(1), None);
                for hit in txn.select(&Everything, &every, Some(txn.cache()))? {
                    let hit = hit?;
                    keys.insert(hit.object.0, hit.key);
                }
            }
            Ok(Clashes::of(answer, clearance, |id| keys.get(&id).cloned().unwrap_or(Key::Int(u64::from(id)))))
        };
        py.detach(run).map_err(|e| e.into_py(py))
    }

    /// The `k` objects nearest `point` (by exact distance to their
    /// triangles), nearest first.
    #[pyo3(signature = (point, k = 1, *, cache = true))]
    fn nearest(
        &self,
        py: Python<'_>,
        point: &Bound<'_, PyAny>,
        k: usize,
        cache: bool,
    ) -> PyResult<Vec<Near>> {
        let txn = self.snapshot(py)?;
        let p = point_from_py(point, "a point")?;
        let found = py
            .detach(|| -> Result<Vec<_>, Failure> {
                let it = txn.nearest(p, cache.then(|| txn.cache()))?;
                Ok(it.take(k).collect::<Result<Vec<_>, _>>()?)
            })
            .map_err(|e| e.into_py(py))?;
        found
            .into_iter()
            .map(|n| Ok(Near { key: key_to_py(py, &n.key)?.unbind(), id: n.object.0, distance: n.distance }))
            .collect()
    }

    /// The objects a ray from `origin` along `direction` meets (up to
    /// `max_distance` mm), in order of distance: all of them, or the first `k`.
    #[pyo3(signature = (origin, direction, *, max_distance = None, k = None, cache = true))]
    #[allow(clippy::too_many_arguments)]
    fn ray(
        &self,
        py: Python<'_>,
        origin: &Bound<'_, PyAny>,
        direction: &Bound<'_, PyAny>,
        max_distance: Option<f64>,
        k: Option<usize>,
        cache: bool,
    ) -> PyResult<Vec<RayHit>> {
        let txn = self.snapshot(py)?;
        let r = ray(origin, direction, max_distance)?;
        let found = py
            .detach(|| -> Result<Vec<_>, Failure> {
                let it = txn.ray(&r, cache.then(|| txn.cache()))?;
                Ok(it.take(k.unwrap_or(usize::MAX)).collect::<Result<Vec<_>, _>>()?)
            })
            .map_err(|e| e.into_py(py))?;
        found
            .into_iter()
            .map(|h| {
                Ok(RayHit {
                    key: key_to_py(py, &h.key)?.unbind(),
                    id: h.object.0,
                    t: h.t,
                    point: (h.point[0], h.point[1], h.point[2]),
                })
            })
            .collect()
    }

    /// `box`, one hit at a time: blocks are read as the iteration needs them.
    #[pyo3(signature = (lo, hi, *, lod = None, budget = None, cache = true))]
    fn iter_box(
        &self,
        py: Python<'_>,
        lo: &Bound<'_, PyAny>,
        hi: &Bound<'_, PyAny>,
        lod: Option<u8>,
        budget: Option<u64>,
        cache: bool,
    ) -> PyResult<HitIterator> {
        HitIterator::new(py, self.snapshot(py)?, Box::new(aabb(lo, hi)?), options(lod, budget), cache)
    }

    /// `sphere`, one hit at a time.
    #[pyo3(signature = (center, radius, *, lod = None, budget = None, cache = true))]
    fn iter_sphere(
        &self,
        py: Python<'_>,
        center: &Bound<'_, PyAny>,
        radius: f64,
        lod: Option<u8>,
        budget: Option<u64>,
        cache: bool,
    ) -> PyResult<HitIterator> {
        HitIterator::new(
            py,
            self.snapshot(py)?,
            Box::new(sphere(center, radius)?),
            options(lod, budget),
            cache,
        )
    }

    /// `frustum`, one hit at a time.
    #[pyo3(signature = (eye, target, fov_deg, aspect, near, far, *, lod = None, budget = None, cache = true))]
    #[allow(clippy::too_many_arguments)]
    fn iter_frustum(
        &self,
        py: Python<'_>,
        eye: &Bound<'_, PyAny>,
        target: &Bound<'_, PyAny>,
        fov_deg: f64,
        aspect: f64,
        near: f64,
        far: f64,
        lod: Option<u8>,
        budget: Option<u64>,
        cache: bool,
    ) -> PyResult<HitIterator> {
        let region = frustum(eye, target, fov_deg, aspect, near, far)?;
        HitIterator::new(py, self.snapshot(py)?, Box::new(region), options(lod, budget), cache)
    }

    /// `collide`, one hit at a time (a stored object given by key is not left out).
    #[pyo3(signature = (mesh, pose = None, *, clearance = 0.0, lod = None, budget = None, cache = true))]
    #[allow(clippy::too_many_arguments)]
    fn iter_collide(
        &self,
        py: Python<'_>,
        mesh: &Bound<'_, PyAny>,
        pose: Option<&Bound<'_, PyAny>>,
        clearance: f64,
        lod: Option<u8>,
        budget: Option<u64>,
        cache: bool,
    ) -> PyResult<HitIterator> {
        let txn = self.snapshot(py)?;
        let (mesh, pose, _) = self.probe(py, &txn, mesh, pose)?;
        let probe = Triangles::posed(&mesh, &pose, clearance).map_err(|e| value_error(e.to_string()))?;
        HitIterator::new(py, txn, Box::new(probe), options(lod, budget), cache)
    }

    /// Every object by distance from `point`, nearest first, lazily.
    #[pyo3(signature = (point, *, cache = true))]
    fn iter_nearest(&self, py: Python<'_>, point: &Bound<'_, PyAny>, cache: bool) -> PyResult<NearIterator> {
        NearIterator::new(py, self.snapshot(py)?, point_from_py(point, "a point")?, cache)
    }

    /// Every object a ray meets, nearest first, lazily.
    #[pyo3(signature = (origin, direction, *, max_distance = None, cache = true))]
    fn iter_ray(
        &self,
        py: Python<'_>,
        origin: &Bound<'_, PyAny>,
        direction: &Bound<'_, PyAny>,
        max_distance: Option<f64>,
        cache: bool,
    ) -> PyResult<RayIterator> {
        RayIterator::new(py, self.snapshot(py)?, ray(origin, direction, max_distance)?, cache)
    }

    /// The object with `key`: its id, exact box and payload (the key index's path), or None.
    fn get(&self, py: Python<'_>, key: &Bound<'_, PyAny>) -> PyResult<Option<Record>> {
        let txn = self.snapshot(py)?;
        let k = key_from_py(key)?;
        let found = py.detach(|| txn.get(&k)).map_err(py_err(py))?;
        found
            .map(|r| {
                Ok(Record {
                    key: key_to_py(py, &r.key)?.unbind(),
                    id: r.id.0,
                    bounds: bounds(&r.aabb),
                    payload: PyBytes::new(py, &r.payload).into_any().unbind(),
                })
            })
            .transpose()
    }

    /// The exact mesh of the object with `key`, or None.
    fn mesh<'py>(&self, py: Python<'py>, key: &Bound<'py, PyAny>) -> PyResult<Option<Bound<'py, PyAny>>> {
        let txn = self.snapshot(py)?;
        let k = key_from_py(key)?;
        match py.detach(|| txn.mesh(&k)).map_err(py_err(py))? {
            Some(m) => mesh_to_py(py, &m).map(Some),
            None => Ok(None),
        }
    }

    /// The object with `key` whole (key, mesh, payload, name), or None.
    fn object<'py>(&self, py: Python<'py>, key: &Bound<'py, PyAny>) -> PyResult<Option<Bound<'py, PyAny>>> {
        let txn = self.snapshot(py)?;
        let k = key_from_py(key)?;
        match py.detach(|| txn.object(&k)).map_err(py_err(py))? {
            Some(o) => object_to_py(py, &o, &k).map(Some),
            None => Ok(None),
        }
    }

    /// The snapshot's tree: counts, blocks and fill; None with no tree.
    fn info(&self, py: Python<'_>) -> PyResult<Option<Info>> {
        Ok(self.snapshot(py)?.info().as_ref().map(Info::of))
    }

    /// Closes the snapshot (a lazy iterator still open keeps it until it ends).
    fn close(&self) {
        self.txn.lock().unwrap_or_else(|e| e.into_inner()).take();
    }

    /// True once closed.
    #[getter]
    fn closed(&self) -> bool {
        self.txn.lock().unwrap_or_else(|e| e.into_inner()).is_none()
    }

    fn __getitem__(&self, py: Python<'_>, key: &Bound<'_, PyAny>) -> PyResult<Record> {
        let k = key_from_py(key)?;
        self.get(py, key)?
            .ok_or_else(|| Failure::new(Kind::KeyNotFound, format!("no object has key {k}")).into_py(py))
    }

    fn __contains__(&self, py: Python<'_>, key: &Bound<'_, PyAny>) -> PyResult<bool> {
        Ok(self.get(py, key)?.is_some())
    }

    fn __len__(&self, py: Python<'_>) -> PyResult<usize> {
        Ok(self.snapshot(py)?.info().map_or(0, |i| i.objects as usize))
    }

    fn __enter__(slf: Py<Self>) -> Py<Self> {
        slf
    }

    #[pyo3(signature = (*_args))]
    fn __exit__(&self, _args: &Bound<'_, PyTuple>) -> bool {
        self.close();
        false
    }

    fn __repr__(&self) -> String {
        let txn = self.txn.lock().unwrap_or_else(|e| e.into_inner());
        match txn.as_ref() {
            None => "ReadTransaction(closed)".into(),
            Some(t) => match t.info() {
                Some(i) => format!("ReadTransaction(txn {}, {} objects)", i.txn, i.objects),
                None => "ReadTransaction(no tree)".into(),
            },
        }
    }
}
