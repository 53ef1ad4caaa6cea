//! `mktree collide`: a posed query object (a mesh file, or one of the
//! file's own objects) against the scene, with a clearance.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use mktree::geom::Pose;
use mktree::query::{CollideOptions, QueryOptions, collide, object_mesh};
use mktree::scene::import::ImportOptions;
use mktree::scene::{Mesh, ObjectId};

use crate::output::print_answer;

/// The query object and its pose, as the flags give them.
pub struct Query {
    pub mesh: Option<PathBuf>,
    pub object: Option<u32>,
    pub translate: [f64; 3],
    pub rotate_deg: [f64; 3],
    pub clearance: f64,
}

/// All of a scene file's objects as one mesh.
fn merged(path: &Path, import: &ImportOptions) -> Result<Mesh> {
    let scene = crate::input::read_scene(path, import)?;
    let mut vertices = Vec::new();
    let mut triangles = Vec::new();
    for o in scene.objects() {
        let base = u32::try_from(vertices.len()).context("too many vertices")?;
        vertices.extend(o.mesh.vertices());
        triangles.extend(o.mesh.triangles().iter().map(|t| t.map(|i| i + base)));
    }
    Mesh::from_world(&vertices, triangles).with_context(|| format!("{}", path.display()))
}

pub fn run(
    file: &Path,
    q: &Query,
    level: &QueryOptions,
    import: &ImportOptions,
    as_json: bool,
) -> Result<()> {
    let db = crate::input::open_to_read(file)?;
    let r = db.begin_read()?;
    let (mesh, exclude) = match (&q.mesh, q.object) {
        (Some(path), _) => (merged(path, import)?, None),
        (None, Some(id)) => (object_mesh(&r, ObjectId(id))?, Some(ObjectId(id))),
        (None, None) => anyhow::bail!("one of --mesh, --object is needed"),
    };
    let pose = Pose::from_degrees(q.translate, q.rotate_deg)?;
    let opts = CollideOptions { query: *level, clearance: q.clearance, exclude };
    print_answer(&collide(&r, &mesh, &pose, &opts, None)?, as_json)
}
