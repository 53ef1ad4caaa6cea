//! `mktree._mktree`, the extension module of the Python package: the
//! engine's database, transactions and queries as Python classes, over the
//! public API of the `mktree` crate alone. The package `mktree/` re-exports
//! it and adds what is plain Python (trimesh and IfcOpenShell interop);
//! `mktree/_mktree.pyi` types and documents every name.
//!
//! Layers: `database` opens files and starts `read` and `write`
//! transactions; `lazy` wraps the engine's iterators; `convert` checks
//! what Python passes in (arrays before any write) and builds what it gets
//! back; `answers` holds the result classes; `errors` maps the engine's
//! errors to exceptions. Long calls run in `Python::detach`, so threads
//! query one file in parallel.

use pyo3::prelude::*;

mod answers;
mod convert;
mod database;
mod errors;
mod lazy;
mod read;
mod write;

use mktree::scene::Key;
use mktree::scene::generate::{GenOptions, generate_scene};
use mktree::scene::import::{ImportOptions, load};

use crate::errors::{Failure, py_err};

/// A generated ship-outfitting scene (`mktree gen`'s presets: tanker1,
/// tanker2, tanker3, ship), as a list of `mktree.Object`, keyed by id.
#[pyfunction]
#[pyo3(signature = (preset, objects = None, seed = 0))]
fn generate<'py>(
    py: Python<'py>,
    preset: &str,
    objects: Option<u64>,
    seed: u64,
) -> PyResult<Vec<Bound<'py, PyAny>>> {
    let preset = preset
        .parse()
        .map_err(|e: mktree::scene::generate::GenError| Failure::value(e.to_string()).into_py(py))?;
    let scene = py
        .detach(|| generate_scene(&GenOptions { preset, objects, seed }))
        .map_err(|e| Failure::from(mktree::Error::from(e)).into_py(py))?;
    scene_objects(py, scene)
}

/// The objects of a scene file (OBJ, STL, glTF, or a folder of OBJ and
/// STL files) as `mktree.Object`s keyed by id; glTF is scaled by
/// `gltf_scale` (metres to millimetres by default).
#[pyfunction]
#[pyo3(signature = (path, gltf_scale = 1000.0))]
fn read_scene<'py>(
    py: Python<'py>,
    path: std::path::PathBuf,
    gltf_scale: f64,
) -> PyResult<Vec<Bound<'py, PyAny>>> {
    let imported = py
        .detach(|| load(&path, &ImportOptions { gltf_scale }).map_err(mktree::Error::from))
        .map_err(py_err(py))?;
    scene_objects(py, imported.scene)
}

/// The binding's cost, measured: runs each box of `boxes` (q, 6: min x, y,
/// z, max x, y, z) `repeats` times through the Rust API on `r`'s snapshot
/// and the database's cache, as `r.box` does but with no Python between
/// queries; returns the seconds per query (`python/benchmarks/`).
#[pyfunction]
fn _rust_box_seconds(
    py: Python<'_>,
    r: PyRef<'_, read::ReadTransaction>,
    boxes: Vec<[f64; 6]>,
    repeats: usize,
) -> PyResult<f64> {
    use mktree::query::{QueryOptions, Region, query_region};
    let txn = r.snapshot(py)?;
    let regions: Vec<Region> = boxes.iter().map(|b| Region::Box(mktree::Aabb::from_array(*b))).collect();
    py.detach(|| {
        let started = std::time::Instant::now();
        let mut found = 0usize;
        for _ in 0..repeats {
            for region in &regions {
                found +=
                    query_region(&txn, region, &QueryOptions::default(), Some(txn.cache()))?.objects.len();
            }
        }
        std::hint::black_box(found);
        Ok::<_, mktree::query::QueryError>(
            started.elapsed().as_secs_f64() / (repeats * regions.len()).max(1) as f64,
        )
    })
    .map_err(py_err(py))
}

fn scene_objects<'py>(py: Python<'py>, scene: mktree::Scene) -> PyResult<Vec<Bound<'py, PyAny>>> {
    scene
        .objects()
        .iter()
        .enumerate()
        .map(|(i, o)| convert::object_to_py(py, o, &Key::Int(i as u64)))
        .collect()
}

#[pymodule]
fn _mktree(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<database::Database>()?;
    m.add_class::<read::ReadTransaction>()?;
    m.add_class::<write::WriteTransaction>()?;
    m.add_class::<answers::Answer>()?;
    m.add_class::<answers::Clashes>()?;
    m.add_class::<answers::Stats>()?;
    m.add_class::<answers::Hit>()?;
    m.add_class::<answers::Near>()?;
    m.add_class::<answers::RayHit>()?;
    m.add_class::<answers::Record>()?;
    m.add_class::<answers::Info>()?;
    m.add_class::<answers::CheckReport>()?;
    m.add_class::<answers::Compaction>()?;
    m.add_class::<answers::ChangeStats>()?;
    m.add_class::<lazy::HitIterator>()?;
    m.add_class::<lazy::NearIterator>()?;
    m.add_class::<lazy::RayIterator>()?;
    m.add_function(wrap_pyfunction!(generate, m)?)?;
    m.add_function(wrap_pyfunction!(read_scene, m)?)?;
    m.add_function(wrap_pyfunction!(_rust_box_seconds, m)?)?;
    Ok(())
}
