//! The engine's errors as Python exceptions, each with the engine's message
//! (and its causes, as `mktree` prints them).
//!
//! The exception classes are defined in Python (`mktree/_errors.py`) so
//! that they can have two bases: `KeyNotFoundError` is a `mktree.Error` and
//! a `KeyError`, `DuplicateKeyError` a `mktree.Error` and a `ValueError`.
//! What the caller gave wrong (a shape, a level, a NaN, a payload too long)
//! is a `ValueError`; what the file or another process did is a
//! `mktree.Error` (or an `OSError` for the operating system's refusals).

use std::io::ErrorKind;

use mktree::StorageError;
use mktree::query::QueryError;
use mktree::scene::KeyError;
use pyo3::exceptions::{
    PyFileExistsError, PyFileNotFoundError, PyOSError, PyPermissionError, PyTypeError, PyValueError,
};
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::PyType;

/// An exception class of `mktree._errors`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// `mktree.Error`: the engine refused (a file, a transaction's state).
    Engine,
    /// `mktree.LockedError`: another process is writing.
    Locked,
    /// `mktree.ReadOnlyError`: the file was opened read-only.
    ReadOnly,
    /// `mktree.CorruptionError`: the file's bytes are damaged.
    Corruption,
    /// `mktree.DuplicateKeyError`: a key given twice, or already stored.
    DuplicateKey,
    /// `mktree.KeyNotFoundError`: no object has the key.
    KeyNotFound,
    /// `mktree.ClosedError`: a transaction or database used after its end.
    Closed,
    /// Built-in `ValueError`: the caller's numbers or arrays.
    Value,
    /// Built-in `OSError` (and its subclasses below).
    Os,
    NotFound,
    Exists,
    Permission,
}

/// An error on its way to Python: built without the interpreter (inside
/// `Python::detach`), raised once it is attached again.
#[derive(Debug)]
pub struct Failure {
    pub kind: Kind,
    pub message: String,
}

impl Failure {
    pub fn new(kind: Kind, message: impl Into<String>) -> Failure {
        Failure { kind, message: message.into() }
    }

    pub fn value(message: impl Into<String>) -> Failure {
        Failure::new(Kind::Value, message)
    }
}

/// `e` and its sources, as one line ("I/O error: No space left on device").
pub fn chain(e: &dyn std::error::Error) -> String {
    let mut text = e.to_string();
    let mut source = e.source();
    while let Some(s) = source {
        let next = s.to_string();
        if !text.ends_with(&next) {
            text.push_str(": ");
            text.push_str(&next);
        }
        source = s.source();
    }
    text
}

impl From<StorageError> for Failure {
    fn from(e: StorageError) -> Failure {
        let kind = match &e {
            StorageError::Open { error, .. } => match error.kind() {
                ErrorKind::NotFound => Kind::NotFound,
                ErrorKind::AlreadyExists => Kind::Exists,
                ErrorKind::PermissionDenied => Kind::Permission,
                _ => Kind::Os,
            },
            StorageError::Io(_) | StorageError::Spill { .. } => Kind::Os,
            StorageError::Locked | StorageError::LockedByCheck => Kind::Locked,
            StorageError::ReadOnly => Kind::ReadOnly,
            e if e.is_corruption() => Kind::Corruption,
            _ => Kind::Engine,
        };
        Failure::new(kind, chain(&e))
    }
}

impl From<QueryError> for Failure {
    fn from(e: QueryError) -> Failure {
        match e {
            QueryError::Storage(s) => s.into(),
            e => {
                let caller = matches!(
                    e,
                    QueryError::Shape(_)
                        | QueryError::Level { .. }
                        | QueryError::Clearance(_)
                        | QueryError::OutOfRange { .. }
                        | QueryError::TooLong { .. }
                );
                Failure::new(if caller { Kind::Value } else { Kind::Engine }, chain(&e))
            }
        }
    }
}

impl From<mktree::Error> for Failure {
    fn from(e: mktree::Error) -> Failure {
        match e {
            mktree::Error::Storage(s) => s.into(),
            mktree::Error::Query(q) => q.into(),
            e => {
                let kind = match &e {
                    mktree::Error::Key(KeyError::Duplicate { .. } | KeyError::Exists { .. }) => {
                        Kind::DuplicateKey
                    }
                    mktree::Error::Key(KeyError::NotFound { .. }) => Kind::KeyNotFound,
                    mktree::Error::Key(_)
                    | mktree::Error::Mesh(_)
                    | mktree::Error::Generate(_)
                    | mktree::Error::Build(_) => Kind::Value,
                    _ => Kind::Engine,
                };
                Failure::new(kind, chain(&e))
            }
        }
    }
}

impl From<mktree::scene::KeyTooLong> for Failure {
    fn from(e: mktree::scene::KeyTooLong) -> Failure {
        Failure::value(e.to_string())
    }
}

/// The class of `mktree._errors` named `name`.
fn class<'py>(
    py: Python<'py>,
    cell: &'static PyOnceLock<Py<PyType>>,
    name: &str,
) -> PyResult<&'py Bound<'py, PyType>> {
    cell.import(py, "mktree._errors", name)
}

impl Failure {
    /// The Python exception.
    pub fn into_py(self, py: Python<'_>) -> PyErr {
        static ENGINE: PyOnceLock<Py<PyType>> = PyOnceLock::new();
        static LOCKED: PyOnceLock<Py<PyType>> = PyOnceLock::new();
        static READ_ONLY: PyOnceLock<Py<PyType>> = PyOnceLock::new();
        static CORRUPTION: PyOnceLock<Py<PyType>> = PyOnceLock::new();
        static DUPLICATE: PyOnceLock<Py<PyType>> = PyOnceLock::new();
        static NOT_FOUND: PyOnceLock<Py<PyType>> = PyOnceLock::new();
        static CLOSED: PyOnceLock<Py<PyType>> = PyOnceLock::new();
        let ours = match self.kind {
            Kind::Engine => Some((&ENGINE, "Error")),
            Kind::Locked => Some((&LOCKED, "LockedError")),
            Kind::ReadOnly => Some((&READ_ONLY, "ReadOnlyError")),
            Kind::Corruption => Some((&CORRUPTION, "CorruptionError")),
            Kind::DuplicateKey => Some((&DUPLICATE, "DuplicateKeyError")),
            Kind::KeyNotFound => Some((&NOT_FOUND, "KeyNotFoundError")),
            Kind::Closed => Some((&CLOSED, "ClosedError")),
            _ => None,
        };
        if let Some((cell, name)) = ours {
            return match class(py, cell, name) {
                Ok(ty) => PyErr::from_type(ty.clone(), self.message),
                Err(e) => e,
            };
        }
        match self.kind {
            Kind::Value => PyValueError::new_err(self.message),
            Kind::NotFound => PyFileNotFoundError::new_err(self.message),
            Kind::Exists => PyFileExistsError::new_err(self.message),
            Kind::Permission => PyPermissionError::new_err(self.message),
            _ => PyOSError::new_err(self.message),
        }
    }
}

/// Raises `e` as its Python exception: `result.map_err(py_err(py))`.
pub fn py_err<E: Into<Failure>>(py: Python<'_>) -> impl Fn(E) -> PyErr + '_ {
    move |e| e.into().into_py(py)
}

/// A `ValueError`.
pub fn value_error(message: impl Into<String>) -> PyErr {
    PyValueError::new_err(message.into())
}

/// A `TypeError`.
pub fn type_error(message: impl Into<String>) -> PyErr {
    PyTypeError::new_err(message.into())
}
