//! What queries and maintenance return, as read-only Python objects. An
//! answer keeps the engine's keys and ids in Rust and builds the Python
//! list of keys, or the numpy arrays, only when asked: a small answer reads
//! as a list, a large one as arrays without a Python object per key.

use mktree::query::{ClashAnswer, QueryAnswer, TraverseStats};
use mktree::scene::Key;
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1};
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{PyDict, PyList, PyTuple};

use crate::convert::key_to_py;

type Bounds = (f64, f64, f64, f64, f64, f64);

/// The Python list of `keys`.
fn key_list<'py>(py: Python<'py>, keys: &[Key]) -> PyResult<Bound<'py, PyList>> {
    let items = keys.iter().map(|k| key_to_py(py, k)).collect::<PyResult<Vec<_>>>()?;
    PyList::new(py, items)
}

/// A key as Python's repr shows it: 7, 'name', b'\\xe9'.
fn key_repr(key: &Key) -> String {
    match key {
        Key::Int(x) => x.to_string(),
        Key::Bytes(b) => match std::str::from_utf8(b) {
            Ok(s) => format!("{s:?}").replace('"', "'"),
            Err(_) => format!(
                "b'{}'",
                b.iter().map(|c| std::ascii::escape_default(*c).to_string()).collect::<String>()
            ),
        },
    }
}

/// Keys as one numpy array: uint64 when every key is an integer, else the
/// array numpy makes of the keys (str keys: a unicode array; mixed: object).
fn key_array<'py>(py: Python<'py>, keys: &[Key]) -> PyResult<Bound<'py, PyAny>> {
    let ints: Option<Vec<u64>> = keys.iter().map(Key::as_int).collect();
    match ints {
        Some(ints) => Ok(PyArray1::from_vec(py, ints).into_any()),
        None => {
            let list = key_list(py, keys)?;
            let np = py.import("numpy")?;
            let mixed = keys.iter().any(|k| k.as_int().is_some());
            if mixed {
                let object = py.import("builtins")?.getattr("object")?;
                np.call_method1("array", (list, object))
            } else {
                np.call_method1("array", (list,))
            }
        }
    }
}

/// What a query read and decided, as the engine counted it.
#[pyclass(frozen, get_all, module = "mktree")]
pub struct Stats {
    /// Blocks read from the file (node + geometry + key index + other); cache hits are not reads.
    pub block_reads: u64,
    pub node_reads: u64,
    pub geometry_reads: u64,
    pub key_reads: u64,
    pub cache_hits: u64,
    pub nodes_visited: u64,
    pub leaves_visited: u64,
    /// Per level k = 1 .. M: objects confirmed there.
    pub confirmed: Vec<u64>,
    /// Per level k = 1 .. M: objects rejected there.
    pub rejected: Vec<u64>,
    pub pruned: u64,
    pub geometry_tests: u64,
    pub triangles_tested: u64,
    pub seconds: f64,
}

impl Stats {
    pub fn of(s: &TraverseStats) -> Stats {
        Stats {
            block_reads: s.reads.total(),
            node_reads: s.reads.node,
            geometry_reads: s.reads.geometry,
            key_reads: s.reads.keys,
            cache_hits: s.reads.cache_hits,
            nodes_visited: s.nodes_visited,
            leaves_visited: s.leaves_visited,
            confirmed: s.confirmed.clone(),
            rejected: s.rejected.clone(),
            pruned: s.pruned,
            geometry_tests: s.geometry_tests,
            triangles_tested: s.triangles_tested,
            seconds: s.seconds,
        }
    }
}

#[pymethods]
impl Stats {
    fn __repr__(&self) -> String {
        format!(
            "Stats(block_reads={}, node_reads={}, geometry_reads={}, cache_hits={}, nodes_visited={}, geometry_tests={}, seconds={:.6})",
            self.block_reads,
            self.node_reads,
            self.geometry_reads,
            self.cache_hits,
            self.nodes_visited,
            self.geometry_tests,
            self.seconds
        )
    }
}

/// A region, collision or clearance query's answer: the keys of the objects
/// found (sorted by id), with what the query read.
#[pyclass(frozen, sequence, module = "mktree")]
pub struct Answer {
    keys: Vec<Key>,
    ids: Vec<u32>,
    maybe: Vec<u32>,
    #[pyo3(get)]
    level: u8,
    #[pyo3(get)]
    level_reached: u8,
    #[pyo3(get)]
    unexplored_nodes: u64,
    stats: TraverseStats,
    list: PyOnceLock<Py<PyList>>,
}

impl Answer {
    pub fn of(a: QueryAnswer) -> Answer {
        Answer {
            ids: a.objects.iter().map(|o| o.0).collect(),
            keys: a.keys,
            maybe: a.maybe.iter().map(|o| o.0).collect(),
            level: a.level,
            level_reached: a.level_reached,
            unexplored_nodes: a.unexplored_nodes,
            stats: a.stats,
            list: PyOnceLock::new(),
        }
    }

    fn list<'py>(&self, py: Python<'py>) -> PyResult<&Bound<'py, PyList>> {
        self.list.get_or_try_init(py, || key_list(py, &self.keys).map(Bound::unbind)).map(|l| l.bind(py))
    }
}

#[pymethods]
impl Answer {
    /// The keys found, sorted by object id.
    #[getter]
    fn keys<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        Ok(self.list(py)?.clone())
    }

    /// The object ids found (sorted), as a numpy uint32 array.
    #[getter]
    fn ids<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<u32>> {
        PyArray1::from_slice(py, &self.ids)
    }

    /// The keys as one numpy array (uint64 for integer keys).
    fn key_array<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        key_array(py, &self.keys)
    }

    /// With a budget: ids of objects seen but not refined to the level asked for.
    #[getter]
    fn maybe<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<u32>> {
        PyArray1::from_slice(py, &self.maybe)
    }

    #[getter]
    fn stats(&self) -> Stats {
        Stats::of(&self.stats)
    }

    fn __len__(&self) -> usize {
        self.keys.len()
    }

    fn __getitem__<'py>(&self, py: Python<'py>, i: isize) -> PyResult<Bound<'py, PyAny>> {
        self.list(py)?.get_item(normalize(i, self.keys.len())?)
    }

    fn __iter__<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        Ok(self.list(py)?.try_iter()?.into_any())
    }

    fn __contains__(&self, py: Python<'_>, key: &Bound<'_, PyAny>) -> PyResult<bool> {
        self.list(py)?.contains(key)
    }

    fn __repr__(&self) -> String {
        let shown: Vec<String> = self.keys.iter().take(8).map(key_repr).collect();
        let more = if self.keys.len() > 8 { ", ..." } else { "" };
        format!(
            "Answer([{}{more}], {} objects, {} block reads, level {})",
            shown.join(", "),
            self.keys.len(),
            self.stats.reads.total(),
            self.level
        )
    }
}

fn normalize(i: isize, len: usize) -> PyResult<usize> {
    let j = if i < 0 { i + len as isize } else { i };
    if j < 0 || j as usize >= len {
        return Err(pyo3::exceptions::PyIndexError::new_err("answer index out of range"));
    }
    Ok(j as usize)
}

/// Every clashing pair of objects, as keys (lower id first), with the run's reads.
#[pyclass(frozen, sequence, module = "mktree")]
pub struct Clashes {
    pairs: Vec<(Key, Key)>,
    ids: Vec<(u32, u32)>,
    #[pyo3(get)]
    level: u8,
    #[pyo3(get)]
    clearance: f64,
    /// Blocks in the file, to set the reads against.
    #[pyo3(get)]
    file_blocks: u32,
    stats: TraverseStats,
    list: PyOnceLock<Py<PyList>>,
}

impl Clashes {
    pub fn of(a: ClashAnswer, clearance: f64, key_of: impl Fn(u32) -> Key) -> Clashes {
        Clashes {
            pairs: a.pairs.iter().map(|&(x, y)| (key_of(x.0), key_of(y.0))).collect(),
            ids: a.pairs.iter().map(|&(x, y)| (x.0, y.0)).collect(),
            level: a.level,
            clearance,
            file_blocks: a.file_blocks,
            stats: a.stats,
            list: PyOnceLock::new(),
        }
    }

    fn list<'py>(&self, py: Python<'py>) -> PyResult<&Bound<'py, PyList>> {
        self.list
            .get_or_try_init(py, || {
                let items = self
                    .pairs
                    .iter()
                    .map(|(a, b)| PyTuple::new(py, [key_to_py(py, a)?, key_to_py(py, b)?]))
                    .collect::<PyResult<Vec<_>>>()?;
                Ok::<_, PyErr>(PyList::new(py, items)?.unbind())
            })
            .map(|l| l.bind(py))
    }
}

#[pymethods]
impl Clashes {
    /// The pairs (key a, key b), sorted by id, a's id below b's.
    #[getter]
    fn pairs<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        Ok(self.list(py)?.clone())
    }

    /// The pairs as object ids, a numpy uint32 array of shape (n, 2).
    #[getter]
    fn id_pairs<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let flat: Vec<u32> = self.ids.iter().flat_map(|&(a, b)| [a, b]).collect();
        let a = Array2::from_shape_vec((self.ids.len(), 2), flat)
            .map_err(|e| pyo3::exceptions::PyValueError::new_err(e.to_string()))?;
        Ok(a.into_pyarray(py).into_any())
    }

    /// The pairs' keys as two numpy arrays (uint64 for integer keys).
    fn key_arrays<'py>(&self, py: Python<'py>) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
        let a: Vec<Key> = self.pairs.iter().map(|p| p.0.clone()).collect();
        let b: Vec<Key> = self.pairs.iter().map(|p| p.1.clone()).collect();
        Ok((key_array(py, &a)?, key_array(py, &b)?))
    }

    #[getter]
    fn stats(&self) -> Stats {
        Stats::of(&self.stats)
    }

    fn __len__(&self) -> usize {
        self.pairs.len()
    }

    fn __getitem__<'py>(&self, py: Python<'py>, i: isize) -> PyResult<Bound<'py, PyAny>> {
        self.list(py)?.get_item(normalize(i, self.pairs.len())?)
    }

    fn __iter__<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        Ok(self.list(py)?.try_iter()?.into_any())
    }

    fn __repr__(&self) -> String {
        format!(
            "Clashes({} pairs within {} mm at level {}, {} block reads of the file's {})",
            self.pairs.len(),
            self.clearance,
            self.level,
            self.stats.reads.total(),
            self.file_blocks
        )
    }
}

/// An object a lazy query accepted: its key and id, its stored box, the
/// level and proof that decided it.
#[pyclass(frozen, get_all, module = "mktree")]
pub struct Hit {
    pub key: Py<PyAny>,
    pub id: u32,
    /// The object's box as stored (rounded outward): min x, y, z, max x, y, z.
    pub bounds: Bounds,
    pub level: u8,
    /// What decided it: "box_misses", "inside_node", "face", "voxels_miss", "cell", "exact", "candidate".
    pub proof: String,
}

#[pymethods]
impl Hit {
    fn __repr__(&self, py: Python<'_>) -> String {
        format!(
            "Hit(key={}, id={}, level={}, proof={:?})",
            self.key.bind(py),
            self.id,
            self.level,
            self.proof
        )
    }
}

/// An object at its distance from a point.
#[pyclass(frozen, get_all, module = "mktree")]
pub struct Near {
    pub key: Py<PyAny>,
    pub id: u32,
    /// From the point to the object's surface, mm.
    pub distance: f64,
}

#[pymethods]
impl Near {
    fn __repr__(&self, py: Python<'_>) -> String {
        format!("Near(key={}, id={}, distance={})", self.key.bind(py), self.id, self.distance)
    }
}

/// Where a ray first meets an object.
#[pyclass(frozen, get_all, module = "mktree")]
pub struct RayHit {
    pub key: Py<PyAny>,
    pub id: u32,
    /// The distance from the ray's origin, mm.
    pub t: f64,
    /// The point at distance t.
    pub point: (f64, f64, f64),
}

#[pymethods]
impl RayHit {
    fn __repr__(&self, py: Python<'_>) -> String {
        format!("RayHit(key={}, id={}, t={}, point={:?})", self.key.bind(py), self.id, self.t, self.point)
    }
}

/// One object found by its key: id, exact box and payload, from the key index.
#[pyclass(frozen, get_all, module = "mktree")]
pub struct Record {
    pub key: Py<PyAny>,
    pub id: u32,
    /// The object's exact box: min x, y, z, max x, y, z.
    pub bounds: Bounds,
    pub payload: Py<PyAny>,
}

#[pymethods]
impl Record {
    /// The payload parsed as JSON (a dict stored as JSON comes back a dict); None without one.
    fn json<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let payload = self.payload.bind(py);
        if payload.len()? == 0 {
            return Ok(py.None().into_bound(py));
        }
        py.import("json")?.call_method1("loads", (payload,))
    }

    fn __repr__(&self, py: Python<'_>) -> String {
        format!(
            "Record(key={}, id={}, bounds={:?}, payload={})",
            self.key.bind(py),
            self.id,
            self.bounds,
            self.payload.bind(py)
        )
    }
}

/// A file's tree: counts, blocks and fill, from its meta block.
#[pyclass(frozen, get_all, module = "mktree")]
pub struct Info {
    /// The committed transaction the snapshot is.
    pub txn: u64,
    pub block_size: u32,
    pub lod_levels: u8,
    pub file_blocks: u32,
    pub free_blocks: u32,
    pub objects: u32,
    pub nodes: u32,
    pub leaves: u32,
    pub depth: u32,
    pub node_blocks: u32,
    pub geometry_blocks: u64,
    pub node_fill: f64,
    pub geometry_fill: f64,
    pub triangles: u64,
    pub vertices: u64,
    /// The scene's box: min x, y, z, max x, y, z.
    pub scene_bounds: Bounds,
    pub build_seconds: f64,
}

impl Info {
    pub fn of(i: &mktree::TreeInfo) -> Info {
        let b = i.scene_box;
        Info {
            txn: i.txn,
            block_size: i.block_size,
            lod_levels: i.lod_levels,
            file_blocks: i.file_blocks,
            free_blocks: i.free_blocks,
            objects: i.objects,
            nodes: i.nodes,
            leaves: i.leaves,
            depth: i.depth,
            node_blocks: i.node_blocks,
            geometry_blocks: i.geometry_blocks,
            node_fill: i.node_fill,
            geometry_fill: i.geometry_fill,
            triangles: i.triangles,
            vertices: i.vertices,
            scene_bounds: (b[0], b[1], b[2], b[3], b[4], b[5]),
            build_seconds: i.build_seconds,
        }
    }
}

#[pymethods]
impl Info {
    fn __repr__(&self) -> String {
        format!(
            "Info(objects={}, nodes={}, leaves={}, depth={}, file_blocks={}, block_size={}, triangles={})",
            self.objects,
            self.nodes,
            self.leaves,
            self.depth,
            self.file_blocks,
            self.block_size,
            self.triangles
        )
    }
}

/// What `check` found: `ok` when no fault.
#[pyclass(frozen, get_all, module = "mktree")]
pub struct CheckReport {
    pub ok: bool,
    pub txn: u64,
    pub file_blocks: u32,
    pub blocks_by_type: Py<PyDict>,
    pub free_blocks: u64,
    pub objects: u64,
    pub nodes: u64,
    /// A write transaction was interrupted; the next one cleans up after it.
    pub interrupted: bool,
    pub warnings: Vec<String>,
    pub faults: Vec<String>,
}

impl CheckReport {
    pub fn of(py: Python<'_>, r: mktree::CheckReport) -> PyResult<CheckReport> {
        let by_type = PyDict::new(py);
        for (k, v) in &r.blocks_by_type {
            by_type.set_item(k, v)?;
        }
        Ok(CheckReport {
            ok: r.ok(),
            txn: r.txn,
            file_blocks: r.file_blocks,
            blocks_by_type: by_type.unbind(),
            free_blocks: r.free_blocks,
            objects: r.objects,
            nodes: r.nodes,
            interrupted: r.interrupted,
            warnings: r.warnings,
            faults: r.faults,
        })
    }
}

#[pymethods]
impl CheckReport {
    fn __bool__(&self) -> bool {
        self.ok
    }

    fn __repr__(&self) -> String {
        format!(
            "CheckReport(ok={}, objects={}, nodes={}, file_blocks={}, faults={:?})",
            if self.ok { "True" } else { "False" },
            self.objects,
            self.nodes,
            self.file_blocks,
            self.faults
        )
    }
}

/// What `compact` did.
#[pyclass(frozen, get_all, module = "mktree")]
pub struct Compaction {
    pub blocks_before: u32,
    pub blocks_after: u32,
    pub free_after: u32,
    pub rewrites: u32,
}

#[pymethods]
impl Compaction {
    fn __repr__(&self) -> String {
        format!(
            "Compaction(blocks_before={}, blocks_after={}, free_after={}, rewrites={})",
            self.blocks_before, self.blocks_after, self.free_after, self.rewrites
        )
    }
}

/// What a commit wrote.
#[pyclass(frozen, get_all, module = "mktree")]
pub struct ChangeStats {
    /// Objects inserted, updated and removed.
    pub changes: u64,
    pub blocks_written: u64,
    pub blocks_freed: u64,
    pub blocks_read: u64,
    /// The changes were written in place (copy on write); False: the tree was written whole.
    pub in_place: bool,
}

#[pymethods]
impl ChangeStats {
    fn __repr__(&self) -> String {
        format!(
            "ChangeStats(changes={}, blocks_written={}, blocks_freed={}, blocks_read={}, in_place={})",
            self.changes,
            self.blocks_written,
            self.blocks_freed,
            self.blocks_read,
            if self.in_place { "True" } else { "False" }
        )
    }
}
