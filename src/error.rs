//! The crate's umbrella error: each family converts into it.

use crate::bulk::BuildError;
use crate::scene::generate::GenError;
use crate::scene::import::ImportError;
use crate::store::StorageError;

/// Any error of the library.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// Reading or writing the file.
    #[error(transparent)]
    Storage(#[from] StorageError),
    /// A bulk load's scene or parameters.
    #[error(transparent)]
    Build(#[from] BuildError),
    /// A tree given to write that is not a valid tree of its scene.
    #[error("the tree does not fit the scene: {0}")]
    Hierarchy(#[from] crate::bulk::HierarchyError),
    /// Reading a scene from OBJ, STL or glTF.
    #[error(transparent)]
    Import(#[from] ImportError),
    /// Generating a scene.
    #[error(transparent)]
    Generate(#[from] GenError),
    /// Building the levels of detail.
    #[error(transparent)]
    Lod(#[from] crate::lod::LodError),
    /// A query.
    #[error(transparent)]
    Query(#[from] crate::query::QueryError),
    /// A transaction asked to write two trees: a bulk load, and changes to
    /// objects (or a second bulk load). One transaction writes one tree.
    #[error("a transaction writes one tree: a bulk load, or changes to objects")]
    OneTree,
    /// An object's key or payload.
    #[error(transparent)]
    Key(#[from] crate::scene::KeyError),
    /// A mesh an operation was given or made (a change's object, a moved
    /// object) that is not one.
    #[error("the object's mesh: {0}")]
    Mesh(#[from] crate::scene::MeshError),
}
