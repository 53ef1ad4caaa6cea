//! Scenes: the object model, import from OBJ / STL / glTF, OBJ export, the
//! ship-scene generator and scene statistics.

mod export;
mod mesh;
mod object;

pub use export::{ObjWriter, write_obj};
pub use mesh::{Mesh, MeshError};
pub use object::{Object, ObjectId, Scene};
