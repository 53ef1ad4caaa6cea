//! `mktree.WriteTransaction`: a bulk load, or inserts, updates, removals
//! and moves by key, committed atomically. As a context manager it commits
//! when the block ends normally and aborts when it raises.
//!
//! The engine's `WriteTransaction<'db>` borrows its `Database`. Python has
//! no lifetimes, so this object owns an `Arc` of the database beside the
//! transaction and hands the transaction out as `'static` (the one
//! `unsafe` of the crate, argued at `begin`). Each step locks the
//! transaction inside `Python::detach`, never while attached, so a thread
//! waiting for another thread's step does not hold the interpreter that
//! step needs to return.

use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::ThreadId;

use mktree::BuildParams;
use mktree::db::WriterWait;
use mktree::scene::{Object, Scene};
use pyo3::prelude::*;
use pyo3::types::PyTuple;
use rayon::prelude::*;

use crate::answers::ChangeStats;
use crate::convert::{RawObject, key_from_py, key_to_py, object_from_py, object_to_py, vector_from_py};
use crate::errors::{Failure, Kind, py_err};

type Txn = mktree::WriteTransaction<'static>;

/// Which thread began a database's open write transaction. The engine
/// makes a second writer of the process wait for the first; begun on the
/// thread that holds the first, it would wait for ever, so that is refused.
pub type Writer = Arc<Mutex<Option<ThreadId>>>;

/// The write transaction. Use it as a context manager (`with db.write() as
/// w:`), or end it with `commit` or `abort`; dropped unended, it aborts.
#[pyclass(frozen, module = "mktree")]
pub struct WriteTransaction {
    // Declared (so dropped) before `db`, which it borrows.
    txn: Mutex<Option<Txn>>,
    db: Arc<mktree::Database>,
    writer: Writer,
}

impl Drop for WriteTransaction {
    fn drop(&mut self) {
        // Dropped unended: the engine's transaction aborts as it drops.
        if self.txn.get_mut().unwrap_or_else(|e| e.into_inner()).take().is_some() {
            seat(&self.writer).take();
        }
    }
}

fn seat(writer: &Writer) -> MutexGuard<'_, Option<ThreadId>> {
    writer.lock().unwrap_or_else(|e| e.into_inner())
}

impl WriteTransaction {
    pub fn begin(
        py: Python<'_>,
        db: Arc<mktree::Database>,
        writer: Writer,
        wait: WriterWait,
    ) -> PyResult<WriteTransaction> {
        let me = std::thread::current().id();
        if *seat(&writer) == Some(me) {
            return Err(Failure::new(
                Kind::Engine,
                "this thread's write transaction is still open: commit or abort it before beginning another",
            )
            .into_py(py));
        }
        let txn = py.detach(|| db.begin_write_with(wait)).map_err(py_err(py))?;
        *seat(&writer) = Some(me);
        // SAFETY: `txn` borrows the `Database` inside the `Arc` allocation
        // of `db`, which never moves and lives as long as this object holds
        // `db`. The transaction is stored in `self.txn`, declared before
        // `self.db`, so it is dropped first; it is never moved out of this
        // object but to be committed, aborted or dropped within a method of
        // it, while `self.db` lives.
        let txn: Txn = unsafe { std::mem::transmute::<mktree::WriteTransaction<'_>, Txn>(txn) };
        Ok(WriteTransaction { txn: Mutex::new(Some(txn)), db, writer })
    }

    fn lock(&self) -> MutexGuard<'_, Option<Txn>> {
        self.txn.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Runs `f` on the open transaction, detached from the interpreter.
    fn with<T: Send>(
        &self,
        py: Python<'_>,
        f: impl FnOnce(&mut Txn) -> Result<T, Failure> + Send,
    ) -> PyResult<T> {
        py.detach(|| match self.lock().as_mut() {
            Some(txn) => f(txn),
            None => Err(closed()),
        })
        .map_err(|e| e.into_py(py))
    }

    /// Ends the transaction: commits it or aborts it.
    fn end(&self, py: Python<'_>, commit: bool) -> PyResult<Option<ChangeStats>> {
        py.detach(|| {
            let txn = self.lock().take().ok_or_else(closed)?;
            seat(&self.writer).take();
            if commit {
                let s = txn.commit_with_stats()?;
                Ok(Some(ChangeStats {
                    changes: s.changes,
                    blocks_written: s.blocks_written,
                    blocks_freed: s.blocks_freed,
                    blocks_read: s.blocks_read,
                    in_place: s.in_place,
                }))
            } else {
                txn.abort()?;
                Ok(None)
            }
        })
        .map_err(|e: Failure| e.into_py(py))
    }
}

fn closed() -> Failure {
    Failure::new(Kind::Closed, "the write transaction has ended (committed or aborted)")
}

/// `e` with "`what`: " before its message, of the same exception type.
fn prefixed(py: Python<'_>, e: PyErr, what: &str) -> PyErr {
    let message = format!("{what}: {}", e.value(py));
    PyErr::from_type(e.get_type(py), message)
}

/// Makes the engine's objects of checked parts, on every core; the first
/// refusal names the object.
fn objects_of(raw: Vec<RawObject>) -> Result<Vec<Object>, Failure> {
    raw.into_par_iter()
        .enumerate()
        .map(|(i, r)| {
            let key = r.key.as_ref().map_or_else(|| format!("{i} (its id)"), ToString::to_string);
            r.into_object().map_err(|e| Failure::value(format!("object {i} (key {key}): {e}")))
        })
        .collect()
}

#[pymethods]
impl WriteTransaction {
    /// Replaces the tree with one bulk-loaded from `objects`, an iterable of
    /// `mktree.Object` (or tuples `(key, vertices, triangles[, payload[,
    /// name]])`). Every object is checked before anything is written.
    /// Returns the number of objects loaded.
    fn bulk_load(&self, py: Python<'_>, objects: &Bound<'_, PyAny>) -> PyResult<usize> {
        let mut raw = Vec::with_capacity(objects.len().unwrap_or(0));
        for (i, item) in objects.try_iter()?.enumerate() {
            let item = item?;
            raw.push(object_from_py(&item).map_err(|e| prefixed(py, e, &format!("object {i}")))?);
        }
        let n = raw.len();
        let params = BuildParams::for_blocks(self.db.block_size());
        self.with(py, move |txn| {
            let scene = Scene::new(objects_of(raw)?);
            txn.bulk_load(&scene, &params, &|_| {})?;
            Ok(n)
        })
    }

    /// Adds `object` (its key None: the next integer key); returns its key.
    fn insert<'py>(&self, py: Python<'py>, object: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
        let raw = object_from_py(object)?;
        let key = self.with(py, move |txn| {
            let object = objects_of(vec![raw])?.pop().ok_or_else(|| Failure::value("no object"))?;
            Ok(txn.insert(object)?)
        })?;
        key_to_py(py, &key)
    }

    /// Replaces the object with `object`'s key by `object`.
    fn update(&self, py: Python<'_>, object: &Bound<'_, PyAny>) -> PyResult<()> {
        let raw = object_from_py(object)?;
        if raw.key.is_none() {
            return Err(crate::errors::value_error("update needs the object's key"));
        }
        self.with(py, move |txn| {
            let object = objects_of(vec![raw])?.pop().ok_or_else(|| Failure::value("no object"))?;
            txn.update(object)?;
            Ok(())
        })
    }

    /// Removes the object with `key`; returns whether there was one. A
    /// missing key raises `KeyNotFoundError` unless `missing_ok`.
    #[pyo3(signature = (key, missing_ok = false))]
    fn remove(&self, py: Python<'_>, key: &Bound<'_, PyAny>, missing_ok: bool) -> PyResult<bool> {
        let key = key_from_py(key)?;
        self.with(py, move |txn| match txn.remove(&key)? {
            Some(_) => Ok(true),
            None if missing_ok => Ok(false),
            None => Err(Failure::new(Kind::KeyNotFound, format!("no object has key {key}"))),
        })
    }

    /// Moves the object with `key` by `offset` (dx, dy, dz), mm.
    fn move_by(&self, py: Python<'_>, key: &Bound<'_, PyAny>, offset: &Bound<'_, PyAny>) -> PyResult<()> {
        let key = key_from_py(key)?;
        let by = vector_from_py(offset, "an offset")?;
        self.with(py, move |txn| match txn.move_by(&key, by)? {
            true => Ok(()),
            false => Err(Failure::new(Kind::KeyNotFound, format!("no object has key {key}"))),
        })
    }

    /// The object with `key` as this transaction has it (its changes
    /// included), or None.
    fn get<'py>(&self, py: Python<'py>, key: &Bound<'py, PyAny>) -> PyResult<Option<Bound<'py, PyAny>>> {
        let key = key_from_py(key)?;
        let k = key.clone();
        match self.with(py, move |txn| Ok(txn.object(&k)?))? {
            Some(o) => object_to_py(py, &o, &key).map(Some),
            None => Ok(None),
        }
    }

    /// Commits: the new tree replaces the old one atomically. Returns what it wrote.
    fn commit(&self, py: Python<'_>) -> PyResult<ChangeStats> {
        self.end(py, true)?.ok_or_else(|| closed().into_py(py))
    }

    /// Aborts: the committed state stays as it was.
    fn abort(&self, py: Python<'_>) -> PyResult<()> {
        self.end(py, false).map(|_| ())
    }

    /// True once committed or aborted.
    #[getter]
    fn closed(&self) -> bool {
        self.lock().is_none()
    }

    fn __enter__(slf: Py<Self>) -> Py<Self> {
        slf
    }

    /// Commits when the block ended normally, aborts when it raised; an
    /// exception goes on.
    #[pyo3(signature = (*args))]
    fn __exit__(&self, py: Python<'_>, args: &Bound<'_, PyTuple>) -> PyResult<bool> {
        let raised = args.get_item(0).is_ok_and(|t| !t.is_none());
        if self.closed() {
            return Ok(false);
        }
        if raised {
            // The block's exception is the one to see; an abort that fails leaves the file as committed.
            let _ = self.end(py, false);
        } else {
            self.end(py, true)?;
        }
        Ok(false)
    }

    fn __repr__(&self) -> String {
        format!("WriteTransaction({})", if self.closed() { "ended" } else { "open" })
    }
}
