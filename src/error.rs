//! The crate's umbrella error: each family converts into it.

use crate::bulk::BuildError;
use crate::scene::generate::GenError;
use crate::scene::import::ImportError;
use crate::store::StorageError;

/// Any error of the library.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    #[error(transparent)]
    Storage(#[from] StorageError),
    #[error(transparent)]
    Build(#[from] BuildError),
    #[error(transparent)]
    Import(#[from] ImportError),
    #[error(transparent)]
    Generate(#[from] GenError),
    #[error(transparent)]
    Lod(#[from] crate::lod::LodError),
    #[error(transparent)]
    Query(#[from] crate::query::QueryError),
    #[error(transparent)]
    Key(#[from] crate::scene::KeyError),
}
