//! The ship-scene generator: synthetic ship-outfitting scenes in
//! millimetres, after the paper's oil tankers (Paper §2, Table 1).
//!
//! A scene is a grid of compartments (`ship.rs`) bounded by hull structure
//! or a skid frame, each outfitted (`outfit.rs`) with equipment, bundles of
//! parallel pipes with flanges, elbows, valves and supports, and in the hull
//! mains and cable trays. Every object is a closed mesh built by one sweep
//! (`parts.rs`). The presets (`presets.rs`) reproduce Table 1's object
//! counts and extents exactly and its triangle counts within a few percent,
//! by steering the mix of parts as the scene is built (`emit.rs`).
//!
//! Output is a stream: objects are made one at a time, compartment after
//! compartment, so memory does not grow with the object count. A preset and
//! a seed give the same objects in the same order on every platform: the
//! random stream (`rng.rs`) and the trigonometry (`trig.rs`) are our own,
//! everything runs on one thread, and vertices sit on a 1/16 mm grid.
//!
//! ```
//! use mktree::scene::generate::{generate_scene, GenOptions, Preset};
//!
//! let scene = generate_scene(&GenOptions { preset: Preset::Tanker1, objects: None, seed: 0 })?;
//! assert_eq!(scene.len(), 222);
//! # Ok::<(), mktree::scene::generate::GenError>(())
//! ```

mod emit;
mod outfit;
mod parts;
mod plant;
mod presets;
mod ship;
mod spans;
mod trig;

use std::io::{self, Write};

pub use presets::Preset;

use super::{Mesh, ObjWriter, Object, Scene};
use crate::geom::Aabb;
use emit::Emitter;
use parts::Part;

/// What to generate.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GenOptions {
    /// The kind of scene.
    pub preset: Preset,
    /// Objects to make; `None` for the preset's own count
    /// ([`Preset::default_objects`]). Must lie in [`Preset::object_range`].
    pub objects: Option<u64>,
    /// Seed of the random stream; each seed gives a different scene.
    pub seed: u64,
}

/// Totals of a generated scene.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GenSummary {
    /// Objects made.
    pub objects: u64,
    /// Triangles over all objects.
    pub triangles: u64,
    /// Vertices over all objects.
    pub vertices: u64,
    /// The box of all vertices, R(S).
    pub aabb: Aabb,
}

/// Why a scene could not be generated.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum GenError {
    /// An object count outside the preset's range.
    #[error("preset {preset} takes {} to {} objects, not {objects}", range.start(), range.end())]
    InvalidObjectCount {
        /// The preset.
        preset: Preset,
        /// The count asked for.
        objects: u64,
        /// The counts it takes ([`Preset::object_range`]).
        range: std::ops::RangeInclusive<u64>,
    },
    /// A preset name that is not one of the presets.
    #[error("unknown preset {name:?}: expected tanker1, tanker2, tanker3, ship or plant")]
    UnknownPreset {
        /// The name given.
        name: String,
    },
    /// The sink failed (for [`write_scene_obj`], writing the OBJ text).
    #[error("could not write the generated scene")]
    Io(#[from] io::Error),
}

/// Generates the scene and hands each object to `sink` as it is made, in a
/// deterministic order; ids are positions in that order. An error from the
/// sink stops generation and is returned as [`GenError::Io`].
pub fn generate(
    options: &GenOptions,
    sink: &mut dyn FnMut(Object) -> io::Result<()>,
) -> Result<GenSummary, GenError> {
    run(options, &mut |name, part: Part| {
        // Sweeps make finite vertices and at least one triangle, so a refusal is a bug here.
        let mesh = Mesh::from_world(&part.vertices, part.triangles).expect("generated meshes are valid");
        sink(Object::new(name, mesh))
    })
}

/// Generates the whole scene in memory.
pub fn generate_scene(options: &GenOptions) -> Result<Scene, GenError> {
    let mut scene = Scene::default();
    generate(options, &mut |o| {
        scene.push(o);
        Ok(())
    })?;
    Ok(scene)
}

/// Generates the scene as Wavefront OBJ on `out` (wrap files in a
/// `BufWriter`), after a `#` header naming the preset, seed, objects and
/// triangles. The header needs the totals before the first object, so the
/// scene is generated twice: once to count (no meshes are built), once to write.
pub fn write_scene_obj(options: &GenOptions, out: impl Write) -> Result<GenSummary, GenError> {
    let totals = run(options, &mut |_, _| Ok(()))?;
    let mut writer = ObjWriter::new(out);
    writer.comment(&format!(
        "mktree generated scene\npreset {}, seed {}\nobjects {}, triangles {}, vertices {}",
        options.preset, options.seed, totals.objects, totals.triangles, totals.vertices
    ))?;
    let summary = generate(options, &mut |o| writer.write_object(&o))?;
    writer.finish()?;
    Ok(summary)
}

/// Checks the options and streams the parts with their names.
fn run(options: &GenOptions, sink: &mut emit::PartSink<'_>) -> Result<GenSummary, GenError> {
    let preset = options.preset;
    let objects = options.objects.unwrap_or(preset.default_objects());
    let range = preset.object_range();
    if !range.contains(&objects) {
        return Err(GenError::InvalidObjectCount { preset, objects, range });
    }
    // The emitter steers towards the preset's triangles per object; the
    // plant has no target of the paper's to meet.
    let per_object = preset.layout().map_or(60.0, |l| l.triangles_per_object);
    let mut em = Emitter::new(sink, objects, per_object);
    match preset.layout() {
        Some(layout) => ship::generate(&layout, objects, options.seed, &mut em)?,
        None => plant::generate(objects, options.seed, &mut em)?,
    }
    Ok(GenSummary { objects: em.objects, triangles: em.triangles, vertices: em.vertices, aabb: em.aabb })
}
