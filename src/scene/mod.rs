//! Scenes: the object model, import from OBJ / STL / glTF, OBJ export, the
//! ship-scene generator and scene statistics.

mod export;
pub mod generate;
pub mod import;
mod key;
mod mesh;
mod object;
mod stats;

pub(crate) use object::unique_keys;

pub use export::{ObjWriter, write_obj};
pub(crate) use key::KeyRef;
pub use key::{Key, KeyTooLong};
pub use mesh::{Mesh, MeshError};
pub use object::{KeyError, Object, ObjectId, Scene};
pub use stats::{Distribution, SceneInfo};
