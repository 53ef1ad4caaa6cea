//! Scene import from Wavefront OBJ, STL (ASCII and binary), glTF 2.0 and
//! directories of OBJ/STL files, with errors that name the file and the
//! object, line, facet or node at fault. One file per format; `load.rs`
//! dispatches on the path.

mod dir;
mod error;
mod gltf;
mod load;
mod obj;
mod stl;

pub use error::{ImportError, Location, UriRefusal};
pub use load::{ImportOptions, Imported, load, load_each};
pub use obj::read_obj;
