//! Directory import: every `.obj` and `.stl` file directly in a folder (not
//! in subfolders), in file-name order, one object per file named by the
//! file stem. An OBJ file's faces all become that one object, whatever its
//! `o` and `g` lines say. Other files are ignored.

use std::fs;
use std::path::{Path, PathBuf};

use super::load::{Format, open};
use super::{ImportError, Imported, obj, stl};
use crate::scene::Scene;

/// Reads the scene made of the OBJ and STL files in `dir`.
pub(super) fn load(dir: &Path) -> Result<Imported, ImportError> {
    let io_error = |source| ImportError::Io { file: dir.into(), source };
    let mut files: Vec<(PathBuf, Format)> = Vec::new();
    for entry in fs::read_dir(dir).map_err(io_error)? {
        let path = entry.map_err(io_error)?.path();
        let format = match Format::of(&path) {
            Some(format @ (Format::Obj | Format::Stl)) => format,
            _ => continue,
        };
        // `is_file` follows links, so a link to a model counts as the model.
        if path.is_file() {
            files.push((path, format));
        }
    }
    // read_dir's order is the file system's; the scene's order is by name.
    files.sort_by(|a, b| a.0.file_name().cmp(&b.0.file_name()));

    let mut scene = Scene::default();
    let mut degenerate_triangles = 0;
    for (path, format) in files {
        let (object, degenerate) = match format {
            Format::Obj => obj::read_obj_as_one_object(open(&path)?, &path)?,
            _ => stl::load(&path)?,
        };
        scene.push(object);
        degenerate_triangles += degenerate;
    }
    if scene.is_empty() {
        return Err(ImportError::EmptyScene { file: dir.into() });
    }
    Ok(Imported { scene, degenerate_triangles })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn files_are_read_in_name_order_and_others_ignored() {
        let dir = tempfile::tempdir().unwrap();
        let triangle = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
        std::fs::write(dir.path().join("b.obj"), format!("o x\n{triangle}o y\nf 1 2 3\n")).unwrap();
        std::fs::write(dir.path().join("a.OBJ"), triangle).unwrap();
        std::fs::write(dir.path().join("c.txt"), "not a model").unwrap();
        std::fs::create_dir(dir.path().join("d.obj")).unwrap();
        let imported = load(dir.path()).unwrap();
        let names: Vec<&str> = imported.scene.objects().iter().map(|o| o.name.as_str()).collect();
        assert_eq!(names, ["a", "b"]);
        assert_eq!(imported.scene.objects()[1].mesh.triangle_count(), 2);
    }

    #[test]
    fn a_folder_without_models_is_an_empty_scene_naming_it() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("readme.md"), "#").unwrap();
        let err = load(dir.path()).unwrap_err();
        assert!(matches!(err, ImportError::EmptyScene { .. }), "{err}");
        assert!(err.to_string().contains(&*dir.path().to_string_lossy()), "{err}");
    }

    #[test]
    fn an_error_in_one_file_names_that_file() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("good.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
        std::fs::write(dir.path().join("hollow.obj"), "v 0 0 0\n").unwrap();
        let err = load(dir.path()).unwrap_err().to_string();
        assert!(err.ends_with("hollow.obj: object \"hollow\" has no triangles"), "{err}");
    }
}
