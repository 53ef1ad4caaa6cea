//! `mktree.Database`: one .mkt file, opened or created, with its
//! transactions, `stats`, `check` and `compact`.

use std::path::PathBuf;
use std::sync::{Arc, Mutex};

use mktree::db::WriterWait;
use mktree::{CreateOptions, StorageError};
use pyo3::prelude::*;
use pyo3::types::PyType;

use crate::answers::{CheckReport, Compaction, Info};
use crate::errors::{Failure, Kind, py_err};
use crate::read::ReadTransaction;
use crate::write::WriteTransaction;

const _: () = assert!(mktree::db::DEFAULT_BLOCK_SIZE == 16384 && mktree::db::DEFAULT_LOD_LEVELS == 4);

/// An MKtree file. Any number of processes and threads may read it; one
/// write transaction runs at a time.
#[pyclass(frozen, module = "mktree")]
pub struct Database {
    db: Mutex<Option<Arc<mktree::Database>>>,
    /// The thread that began the open write transaction, if one is open.
    writer: crate::write::Writer,
    path: PathBuf,
    read_only: bool,
}

impl Database {
    /// The open database, or `ClosedError`.
    pub fn get(&self, py: Python<'_>) -> PyResult<Arc<mktree::Database>> {
        let db = self.db.lock().unwrap_or_else(|e| e.into_inner());
        db.clone().ok_or_else(|| Failure::new(Kind::Closed, "the database is closed").into_py(py))
    }

    fn new(db: mktree::Database, path: PathBuf, read_only: bool) -> Database {
        Database { db: Mutex::new(Some(Arc::new(db))), writer: Default::default(), path, read_only }
    }
}

#[pymethods]
impl Database {
    /// Creates a new file at `path` (it must not exist) with an empty tree.
    #[classmethod]
    // The defaults are the engine's, written as numbers so that `help()` and
    // the stub show them (checked below).
    #[pyo3(signature = (path, block_size = 16384, lod_levels = 4))]
    fn create(
        _cls: &Bound<'_, PyType>,
        py: Python<'_>,
        path: PathBuf,
        block_size: u32,
        lod_levels: u8,
    ) -> PyResult<Database> {
        let options = CreateOptions { block_size, lod_levels };
        let db = py.detach(|| mktree::Database::create(&path, options)).map_err(|e| match e {
            // Settings the caller chose: a ValueError, not a damaged file.
            StorageError::InvalidBlockSize(_) | StorageError::InvalidLodLevels(_) => {
                Failure::value(e.to_string()).into_py(py)
            }
            e => Failure::from(e).into_py(py),
        })?;
        Ok(Database::new(db, path, false))
    }

    /// Opens an existing file; `read_only=True` opens it to read only (a
    /// read-only file or mount will do, and `write` raises `ReadOnlyError`).
    #[classmethod]
    #[pyo3(signature = (path, read_only = false))]
    fn open(_cls: &Bound<'_, PyType>, py: Python<'_>, path: PathBuf, read_only: bool) -> PyResult<Database> {
        let db = py
            .detach(|| {
                if read_only {
                    mktree::Database::open_read_only(&path)
                } else {
                    mktree::Database::open(&path)
                }
            })
            .map_err(py_err(py))?;
        Ok(Database::new(db, path, read_only))
    }

    /// A read transaction: a snapshot of the newest commit, which later commits do not change.
    fn read(&self, py: Python<'_>) -> PyResult<ReadTransaction> {
        let db = self.get(py)?;
        let txn = py.detach(|| db.begin_read()).map_err(py_err(py))?;
        Ok(ReadTransaction::new(txn))
    }

    /// The write transaction. One runs at a time: another thread's waits
    /// for it; another process's makes this raise `LockedError`, unless
    /// `wait=True` waits for it to end. The thread whose transaction is
    /// open gets `mktree.Error`: it would wait for itself.
    #[pyo3(signature = (wait = false))]
    fn write(&self, py: Python<'_>, wait: bool) -> PyResult<WriteTransaction> {
        let db = self.get(py)?;
        WriteTransaction::begin(
            py,
            db,
            self.writer.clone(),
            if wait { WriterWait::Wait } else { WriterWait::Fail },
        )
    }

    /// The committed tree's counts, blocks and fill; None for a file with no tree yet.
    fn stats(&self, py: Python<'_>) -> PyResult<Option<Info>> {
        let db = self.get(py)?;
        let txn = py.detach(|| db.begin_read()).map_err(py_err(py))?;
        Ok(txn.info().as_ref().map(Info::of))
    }

    /// Verifies every checksum and structural rule of the newest commit.
    fn check(&self, py: Python<'_>) -> PyResult<CheckReport> {
        let db = self.get(py)?;
        let report = py.detach(|| mktree::check(&db)).map_err(py_err(py))?;
        CheckReport::of(py, report)
    }

    /// Gives the file's free blocks back to the file system.
    #[pyo3(signature = (wait = false))]
    fn compact(&self, py: Python<'_>, wait: bool) -> PyResult<Compaction> {
        let db = self.get(py)?;
        let wait = if wait { WriterWait::Wait } else { WriterWait::Fail };
        let c = py.detach(|| db.compact_with(wait)).map_err(py_err(py))?;
        Ok(Compaction {
            blocks_before: c.blocks_before,
            blocks_after: c.blocks_after,
            free_after: c.free_after,
            rewrites: c.rewrites,
        })
    }

    /// The file's path.
    #[getter]
    fn path(&self) -> PathBuf {
        self.path.clone()
    }

    /// Bytes per block.
    #[getter]
    fn block_size(&self, py: Python<'_>) -> PyResult<u32> {
        Ok(self.get(py)?.block_size())
    }

    /// M, the levels of detail per node.
    #[getter]
    fn lod_levels(&self, py: Python<'_>) -> PyResult<u8> {
        Ok(self.get(py)?.lod_levels())
    }

    /// Opened with `read_only=True`.
    #[getter]
    fn read_only(&self) -> bool {
        self.read_only
    }

    /// True once `close` ran.
    #[getter]
    fn closed(&self) -> bool {
        self.db.lock().unwrap_or_else(|e| e.into_inner()).is_none()
    }

    /// Closes the database: the file is closed once its transactions have ended too.
    fn close(&self) {
        self.db.lock().unwrap_or_else(|e| e.into_inner()).take();
    }

    fn __enter__(slf: Py<Self>) -> Py<Self> {
        slf
    }

    #[pyo3(signature = (*_args))]
    fn __exit__(&self, _args: &Bound<'_, pyo3::types::PyTuple>) -> bool {
        self.close();
        false
    }

    fn __repr__(&self) -> String {
        let state = if self.closed() {
            ", closed"
        } else if self.read_only {
            ", read-only"
        } else {
            ""
        };
        format!("Database({:?}{state})", self.path.display().to_string())
    }
}
