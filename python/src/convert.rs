//! Python values to the engine's and back: keys, payloads, vertex and
//! triangle arrays, meshes, objects, poses and points.
//!
//! Arrays are checked here, before any engine call, so that a malformed one
//! raises `ValueError` and nothing is written: vertices must be a real
//! (float or integer) array of shape (n, 3), converted to float64;
//! triangles an integer array of shape (m, 3) whose indices lie in
//! 0 .. n - 1. Non-finite coordinates and an empty triangle list are
//! refused by `Mesh::from_world`, whose message is kept.

use mktree::geom::{Point, Pose, Vector};
use mktree::scene::{Key, Mesh, Object};
use numpy::ndarray::Array2;
use numpy::{
    Element, IntoPyArray, PyArray2, PyArrayDescrMethods, PyArrayMethods, PyUntypedArray,
    PyUntypedArrayMethods,
};
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{PyBool, PyByteArray, PyBytes, PyDict, PyList, PyString, PyTuple, PyType};

use crate::errors::{type_error, value_error};

/// A key from Python: an int in 0 .. 2**64 - 1 (numpy integers too), a str
/// (its UTF-8 bytes) or bytes, at most 255 bytes.
pub fn key_from_py(obj: &Bound<'_, PyAny>) -> PyResult<Key> {
    let bytes = if let Ok(s) = obj.cast::<PyString>() {
        Some(s.to_cow()?.as_bytes().to_vec())
    } else if let Ok(b) = obj.cast::<PyBytes>() {
        Some(b.as_bytes().to_vec())
    } else {
        None
    };
    if let Some(bytes) = bytes {
        return Key::bytes(bytes).map_err(|e| value_error(format!("key {}: {e}", short_repr(obj))));
    }
    if obj.is_instance_of::<PyBool>() || !obj.hasattr(pyo3::intern!(obj.py(), "__index__"))? {
        return Err(type_error(format!(
            "a key is an int, a str or bytes, not {}",
            obj.get_type().name().map(|n| n.to_string()).unwrap_or_default()
        )));
    }
    match obj.extract::<u64>() {
        Ok(x) => Ok(Key::Int(x)),
        Err(_) => Err(value_error(format!("key {}: an integer key lies in 0 .. 2**64 - 1", short_repr(obj)))),
    }
}

/// A key as Python has it: an int, a str (UTF-8 bytes) or bytes.
pub fn key_to_py<'py>(py: Python<'py>, key: &Key) -> PyResult<Bound<'py, PyAny>> {
    Ok(match key {
        Key::Int(x) => x.into_pyobject(py)?.into_any(),
        Key::Bytes(b) => match std::str::from_utf8(b) {
            Ok(s) => PyString::new(py, s).into_any(),
            Err(_) => PyBytes::new(py, b).into_any(),
        },
    })
}

/// `obj`'s repr, cut to 60 characters.
pub fn short_repr(obj: &Bound<'_, PyAny>) -> String {
    let r = obj.repr().map(|r| r.to_string()).unwrap_or_else(|_| "?".into());
    if r.chars().count() > 60 { format!("{}...", r.chars().take(57).collect::<String>()) } else { r }
}

/// The `json` module's `dumps`.
fn json_dumps<'py>(py: Python<'py>) -> PyResult<&'py Bound<'py, PyAny>> {
    static DUMPS: PyOnceLock<Py<PyAny>> = PyOnceLock::new();
    DUMPS
        .get_or_try_init(py, || Ok::<_, PyErr>(py.import("json")?.getattr("dumps")?.unbind()))
        .map(|f| f.bind(py))
}

/// A payload from Python: None (none), bytes or bytearray as they are, a
/// dict or list as compact UTF-8 JSON; at most `Object::MAX_PAYLOAD` bytes.
pub fn payload_from_py(obj: Option<&Bound<'_, PyAny>>) -> PyResult<Vec<u8>> {
    let Some(obj) = obj.filter(|o| !o.is_none()) else { return Ok(Vec::new()) };
    let bytes = if let Ok(b) = obj.cast::<PyBytes>() {
        b.as_bytes().to_vec()
    } else if let Ok(b) = obj.cast::<PyByteArray>() {
        b.to_vec()
    } else if obj.is_instance_of::<PyDict>() || obj.is_instance_of::<PyList>() {
        let py = obj.py();
        let kwargs = PyDict::new(py);
        kwargs.set_item("separators", (",", ":"))?;
        kwargs.set_item("ensure_ascii", false)?;
        let text = json_dumps(py)?.call((obj,), Some(&kwargs))?;
        text.cast::<PyString>()?.to_cow()?.as_bytes().to_vec()
    } else {
        return Err(type_error(format!(
            "a payload is bytes or a dict (stored as JSON), not {}",
            obj.get_type().name().map(|n| n.to_string()).unwrap_or_default()
        )));
    };
    if bytes.len() > Object::MAX_PAYLOAD {
        return Err(value_error(format!(
            "a payload of {} bytes (at most {})",
            bytes.len(),
            Object::MAX_PAYLOAD
        )));
    }
    Ok(bytes)
}

/// `numpy.asarray`.
fn asarray<'py>(obj: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
    static ASARRAY: PyOnceLock<Py<PyAny>> = PyOnceLock::new();
    let py = obj.py();
    let f =
        ASARRAY.get_or_try_init(py, || Ok::<_, PyErr>(py.import("numpy")?.getattr("asarray")?.unbind()))?;
    f.bind(py).call1((obj,)).map_err(|e| value_error(format!("not an array: {}", e.value(py))))
}

/// `obj` as a 2-D array of shape (_, `cols`) whose dtype kind is one of
/// `kinds` (numpy's letters: f float, i signed, u unsigned), else a
/// `ValueError` naming `what` and `wanted`.
fn checked_array<'py>(
    obj: &Bound<'py, PyAny>,
    cols: usize,
    kinds: &[u8],
    what: &str,
    wanted: &str,
) -> PyResult<Bound<'py, PyUntypedArray>> {
    let any = match obj.cast::<PyUntypedArray>() {
        Ok(a) => a.clone().into_any(),
        Err(_) => asarray(obj).map_err(|e| value_error(format!("{what}: {}", e.value(obj.py()))))?,
    };
    let a = any.cast_into::<PyUntypedArray>()?;
    let shape = a.shape();
    if shape.len() != 2 || shape[1] != cols {
        let dims: Vec<String> = shape.iter().map(usize::to_string).collect();
        return Err(value_error(format!(
            "{what} must be an array of shape (n, {cols}), not ({})",
            dims.join(", ") + if dims.len() == 1 { "," } else { "" }
        )));
    }
    let kind = a.dtype().kind();
    if !kinds.contains(&kind) {
        return Err(value_error(format!("{what} must be {wanted}, not dtype {}", a.dtype().str()?)));
    }
    Ok(a)
}

/// `a` cast to `T` (a copy unless it is already `T`).
fn as_type<'py, T: Element>(a: &Bound<'py, PyUntypedArray>) -> PyResult<Bound<'py, PyArray2<T>>> {
    if let Ok(t) = a.cast::<PyArray2<T>>() {
        return Ok(t.clone());
    }
    let py = a.py();
    let dtype = numpy::dtype::<T>(py);
    Ok(a.call_method1(pyo3::intern!(py, "astype"), (dtype,))?.cast_into::<PyArray2<T>>()?)
}

/// Vertices: a real array of shape (n, 3), as f64 points.
pub fn vertices_from_py(obj: &Bound<'_, PyAny>) -> PyResult<Vec<Point>> {
    let a = checked_array(obj, 3, b"fiu", "vertices", "a float64 array (or another real dtype)")?;
    let a = as_type::<f64>(&a)?;
    let ro = a.try_readonly().map_err(|e| value_error(format!("vertices: {e}")))?;
    Ok(match ro.as_slice() {
        Ok(flat) => flat.chunks_exact(3).map(|c| Point::new(c[0], c[1], c[2])).collect(),
        Err(_) => ro.as_array().rows().into_iter().map(|r| Point::new(r[0], r[1], r[2])).collect(),
    })
}

/// Triangles of a mesh of `vertices` vertices: an integer array of shape
/// (m, 3) whose entries lie in 0 .. vertices - 1.
pub fn triangles_from_py(obj: &Bound<'_, PyAny>, vertices: usize) -> PyResult<Vec<[u32; 3]>> {
    let a = checked_array(obj, 3, b"iu", "triangles", "an integer array")?;
    if let Ok(t) = a.cast::<PyArray2<u32>>() {
        return collect_triangles(t, vertices);
    }
    if let Ok(t) = a.cast::<PyArray2<i32>>() {
        return collect_triangles(t, vertices);
    }
    if let Ok(t) = a.cast::<PyArray2<u64>>() {
        return collect_triangles(t, vertices);
    }
    collect_triangles(&as_type::<i64>(&a)?, vertices)
}

/// The triangles of `a`, each index checked against `vertices`.
fn collect_triangles<T>(a: &Bound<'_, PyArray2<T>>, vertices: usize) -> PyResult<Vec<[u32; 3]>>
where
    T: Element + Copy + TryInto<u32> + std::fmt::Display,
{
    let ro = a.try_readonly().map_err(|e| value_error(format!("triangles: {e}")))?;
    let index = |t: usize, x: T| -> PyResult<u32> {
        match x.try_into() {
            Ok(i) if (i as usize) < vertices => Ok(i),
            _ => Err(value_error(format!(
                "triangle {t} uses vertex index {x}, but the object has {vertices} vertices"
            ))),
        }
    };
    let mut out = Vec::with_capacity(ro.len() / 3);
    match ro.as_slice() {
        Ok(flat) => {
            for (t, c) in flat.chunks_exact(3).enumerate() {
                out.push([index(t, c[0])?, index(t, c[1])?, index(t, c[2])?]);
            }
        }
        Err(_) => {
            for (t, r) in ro.as_array().rows().into_iter().enumerate() {
                out.push([index(t, r[0])?, index(t, r[1])?, index(t, r[2])?]);
            }
        }
    }
    Ok(out)
}

/// A mesh's arrays, checked, not yet made a `Mesh`.
pub struct RawMesh {
    pub vertices: Vec<Point>,
    pub triangles: Vec<[u32; 3]>,
}

impl RawMesh {
    /// The engine's mesh (finite coordinates, at least one triangle).
    pub fn into_mesh(self) -> Result<Mesh, String> {
        Mesh::from_world(&self.vertices, self.triangles).map_err(|e| e.to_string())
    }

    /// Applies the affine 4x4 matrix `m` to every vertex.
    fn transform(&mut self, m: &[[f64; 4]; 4]) {
        for p in &mut self.vertices {
            let (x, y, z) = (p.x, p.y, p.z);
            *p = Point::new(
                m[0][0] * x + m[0][1] * y + m[0][2] * z + m[0][3],
                m[1][0] * x + m[1][1] * y + m[1][2] * z + m[1][3],
                m[2][0] * x + m[2][1] * y + m[2][2] * z + m[2][3],
            );
        }
    }
}

fn raw_mesh(vertices: &Bound<'_, PyAny>, triangles: &Bound<'_, PyAny>) -> PyResult<RawMesh> {
    let vertices = vertices_from_py(vertices)?;
    let triangles = triangles_from_py(triangles, vertices.len())?;
    Ok(RawMesh { vertices, triangles })
}

/// A mesh from Python: a `(vertices, triangles)` pair (`mktree.Mesh`), or
/// anything with `vertices` and `faces` (a trimesh) or `triangles`.
pub fn mesh_from_py(obj: &Bound<'_, PyAny>) -> PyResult<RawMesh> {
    if let Ok(t) = obj.cast::<PyTuple>() {
        if t.len() != 2 {
            return Err(value_error(format!(
                "a mesh is a pair (vertices, triangles), not {} items",
                t.len()
            )));
        }
        return raw_mesh(&t.get_item(0)?, &t.get_item(1)?);
    }
    let py = obj.py();
    if obj.hasattr(pyo3::intern!(py, "vertices"))? {
        // `faces` first: a trimesh's `triangles` are its corners' coordinates.
        let triangles = if obj.hasattr(pyo3::intern!(py, "faces"))? {
            obj.getattr(pyo3::intern!(py, "faces"))?
        } else if obj.hasattr(pyo3::intern!(py, "triangles"))? {
            obj.getattr(pyo3::intern!(py, "triangles"))?
        } else {
            return Err(type_error("a mesh has triangles (or faces)"));
        };
        return raw_mesh(&obj.getattr(pyo3::intern!(py, "vertices"))?, &triangles);
    }
    Err(type_error(format!(
        "a mesh is a (vertices, triangles) pair, an mktree.Mesh or a trimesh.Trimesh, not {}",
        obj.get_type().name().map(|n| n.to_string()).unwrap_or_default()
    )))
}

/// An object's parts, checked, not yet made an `Object`.
pub struct RawObject {
    pub key: Option<Key>,
    pub name: String,
    pub payload: Vec<u8>,
    pub mesh: RawMesh,
}

impl RawObject {
    /// The engine's object; `Err` is the mesh's refusal.
    pub fn into_object(self) -> Result<Object, String> {
        let mesh = self.mesh.into_mesh()?;
        let mut o = Object::new(self.name, mesh).with_payload(self.payload);
        o.key = self.key;
        Ok(o)
    }
}

/// An object from Python: a tuple `(key, vertices, triangles[, payload[,
/// name]])` (an `mktree.Object` is one), or anything with those attributes.
/// A key of None is the object's id (bulk loads) or the next integer key
/// (inserts).
pub fn object_from_py<'py>(obj: &Bound<'py, PyAny>) -> PyResult<RawObject> {
    let py = obj.py();
    let (key, vertices, triangles, payload, name) = if let Ok(t) = obj.cast::<PyTuple>() {
        if !(3..=5).contains(&t.len()) {
            return Err(value_error(format!(
                "an object is a tuple (key, vertices, triangles[, payload[, name]]), not {} items",
                t.len()
            )));
        }
        let opt = |i: usize| if i < t.len() { t.get_item(i).map(Some) } else { Ok(None) };
        (t.get_item(0)?, t.get_item(1)?, t.get_item(2)?, opt(3)?, opt(4)?)
    } else if obj.hasattr(pyo3::intern!(py, "vertices"))? {
        let opt = |name: &Bound<'py, PyString>| -> PyResult<Option<Bound<'py, PyAny>>> {
            if obj.hasattr(name)? { obj.getattr(name).map(Some) } else { Ok(None) }
        };
        let triangles = opt(pyo3::intern!(py, "faces"))?
            .or(opt(pyo3::intern!(py, "triangles"))?)
            .ok_or_else(|| type_error("an object has triangles"))?;
        let key = opt(pyo3::intern!(py, "key"))?.unwrap_or_else(|| py.None().into_bound(py));
        (
            key,
            obj.getattr(pyo3::intern!(py, "vertices"))?,
            triangles,
            opt(pyo3::intern!(py, "payload"))?,
            opt(pyo3::intern!(py, "name"))?,
        )
    } else {
        return Err(type_error(format!(
            "an object is a tuple (key, vertices, triangles[, payload[, name]]) or an mktree.Object, not {}",
            obj.get_type().name().map(|n| n.to_string()).unwrap_or_default()
        )));
    };
    let key = if key.is_none() { None } else { Some(key_from_py(&key)?) };
    let name = match name.filter(|n| !n.is_none()) {
        Some(n) => n.extract::<String>().map_err(|_| type_error("an object's name is a str"))?,
        None => String::new(),
    };
    let payload = payload_from_py(payload.as_ref())?;
    Ok(RawObject { key, name, payload, mesh: raw_mesh(&vertices, &triangles)? })
}

/// How a query mesh is placed.
pub enum Placement {
    /// The engine's pose: rotated about the mesh's box centre, then moved.
    Pose(Pose),
    /// An affine 4x4 matrix applied to the vertices (trimesh's transforms).
    Matrix([[f64; 4]; 4]),
}

impl Placement {
    /// Places `mesh`: a matrix moves its vertices; a pose is returned for the engine.
    pub fn apply(&self, mesh: &mut RawMesh) -> Pose {
        match self {
            Placement::Pose(p) => *p,
            Placement::Matrix(m) => {
                mesh.transform(m);
                Pose::default()
            }
        }
    }
}

/// A pose from Python: None (as it is), an `mktree.Pose` (translate,
/// rotate_deg), a translation (3 numbers), or an affine 4x4 matrix.
pub fn placement_from_py(obj: Option<&Bound<'_, PyAny>>) -> PyResult<Placement> {
    let Some(obj) = obj.filter(|o| !o.is_none()) else { return Ok(Placement::Pose(Pose::default())) };
    if let Ok(t) = obj.cast::<PyTuple>()
        && t.len() == 2
    {
        let translate: [f64; 3] =
            t.get_item(0)?.extract().map_err(|_| value_error("a pose's translate is 3 numbers"))?;
        let rotate: [f64; 3] =
            t.get_item(1)?.extract().map_err(|_| value_error("a pose's rotate_deg is 3 numbers"))?;
        return Pose::from_degrees(translate, rotate)
            .map(Placement::Pose)
            .map_err(|e| value_error(e.to_string()));
    }
    if let Ok(t) = obj.extract::<[f64; 3]>() {
        return Pose::from_degrees(t, [0.0; 3]).map(Placement::Pose).map_err(|e| value_error(e.to_string()));
    }
    let m: [[f64; 4]; 4] = obj
        .extract()
        .map_err(|_| value_error("a pose is an mktree.Pose, a translation (3 numbers) or a 4x4 matrix"))?;
    if !m.iter().flatten().all(|x| x.is_finite()) {
        return Err(value_error("a pose matrix must be finite"));
    }
    if m[3] != [0.0, 0.0, 0.0, 1.0] {
        return Err(value_error("a pose matrix must be affine: its last row 0, 0, 0, 1"));
    }
    Ok(Placement::Matrix(m))
}

/// A point (3 numbers).
pub fn point_from_py(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Point> {
    let [x, y, z]: [f64; 3] = obj.extract().map_err(|_| value_error(format!("{what} is 3 numbers")))?;
    Ok(Point::new(x, y, z))
}

/// A vector (3 numbers).
pub fn vector_from_py(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Vector> {
    let [x, y, z]: [f64; 3] = obj.extract().map_err(|_| value_error(format!("{what} is 3 numbers")))?;
    Ok(Vector::new(x, y, z))
}

/// A class of `mktree._types`.
fn types_class<'py>(
    py: Python<'py>,
    cell: &'static PyOnceLock<Py<PyType>>,
    name: &str,
) -> PyResult<&'py Bound<'py, PyType>> {
    cell.import(py, "mktree._types", name)
}

/// `mesh` as an `mktree.Mesh`: vertices (n, 3) float64, triangles (m, 3) uint32.
pub fn mesh_to_py<'py>(py: Python<'py>, mesh: &Mesh) -> PyResult<Bound<'py, PyAny>> {
    static MESH: PyOnceLock<Py<PyType>> = PyOnceLock::new();
    let (vertices, triangles) = mesh_arrays(py, mesh)?;
    types_class(py, &MESH, "Mesh")?.call1((vertices, triangles))
}

/// A mesh's two arrays.
pub fn mesh_arrays<'py>(py: Python<'py>, mesh: &Mesh) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    let flat: Vec<f64> = mesh.vertices().flat_map(|p| [p.x, p.y, p.z]).collect();
    let v = Array2::from_shape_vec((mesh.vertex_count(), 3), flat).map_err(|e| value_error(e.to_string()))?;
    let tri: Vec<u32> = mesh.triangles().as_flattened().to_vec();
    let t =
        Array2::from_shape_vec((mesh.triangle_count(), 3), tri).map_err(|e| value_error(e.to_string()))?;
    Ok((v.into_pyarray(py).into_any(), t.into_pyarray(py).into_any()))
}

/// `object` as an `mktree.Object`; `key` stands for a missing key.
pub fn object_to_py<'py>(py: Python<'py>, object: &Object, key: &Key) -> PyResult<Bound<'py, PyAny>> {
    static OBJECT: PyOnceLock<Py<PyType>> = PyOnceLock::new();
    let (vertices, triangles) = mesh_arrays(py, &object.mesh)?;
    let key = key_to_py(py, object.key.as_ref().unwrap_or(key))?;
    let payload = PyBytes::new(py, &object.payload);
    types_class(py, &OBJECT, "Object")?.call1((key, vertices, triangles, payload, object.name.as_str()))
}

/// A box as 6 floats: min x, y, z, max x, y, z.
pub fn bounds(b: &mktree::Aabb) -> (f64, f64, f64, f64, f64, f64) {
    let a = b.to_array();
    (a[0], a[1], a[2], a[3], a[4], a[5])
}
