//! The object stream: every generated part passes through [`Emitter`],
//! which names it, counts it, keeps each compartment to its object budget,
//! and tells the layout how far the triangle count has drifted from the
//! preset's target.
//!
//! Why a running target instead of a fixed mix: Table 1's triangle counts
//! must land within 5% for every seed, and one valve more or less in a
//! 222-object scene moves the total by 4%. The layout asks
//! [`Emitter::wanted_average`] when it picks a pipe size and
//! [`Emitter::deficit`] when it decides on a valve or a support, so the
//! drift is corrected as the scene is built, deterministically, whatever
//! the seed drew before.

use std::io;

use super::parts::Part;
use crate::geom::Aabb;

/// Objects over which a drift in triangles is worked off: short enough that
/// a small scene ends on target, long enough that one valve does not
/// swing the pipe sizes of the next bundle.
const HORIZON: f64 = 60.0;

/// Receives each finished part with its name.
pub(crate) type PartSink<'s> = dyn FnMut(String, Part) -> io::Result<()> + 's;

/// Counts, names and budgets the stream of generated parts.
pub(crate) struct Emitter<'s> {
    sink: &'s mut PartSink<'s>,
    total_objects: u64,
    triangles_per_object: f64,
    /// Object count at which the current compartment is full.
    limit: u64,
    pub(crate) objects: u64,
    pub(crate) triangles: u64,
    pub(crate) vertices: u64,
    pub(crate) aabb: Aabb,
}

impl<'s> Emitter<'s> {
    /// A stream of `total_objects` objects averaging `triangles_per_object`.
    pub(crate) fn new(sink: &'s mut PartSink<'s>, total_objects: u64, triangles_per_object: f64) -> Self {
        Emitter {
            sink,
            total_objects,
            triangles_per_object,
            limit: 0,
            objects: 0,
            triangles: 0,
            vertices: 0,
            aabb: Aabb::EMPTY,
        }
    }

    /// Opens the next compartment, which may hold `budget` objects.
    pub(crate) fn start_compartment(&mut self, budget: u64) {
        self.limit = self.objects + budget;
    }

    /// Objects the current compartment may still take.
    pub(crate) fn room_left(&self) -> u64 {
        self.limit.saturating_sub(self.objects)
    }

    /// True when the current compartment has its budget; further parts are
    /// dropped, so a layout step may finish its loop without checking.
    pub(crate) fn full(&self) -> bool {
        self.objects >= self.limit
    }

    /// Sends `part` on as the next object, named `{kind}.{id}`.
    pub(crate) fn emit(&mut self, kind: &str, part: Part) -> io::Result<()> {
        if self.full() {
            return Ok(());
        }
        self.triangles += part.triangles.len() as u64;
        self.vertices += part.vertices.len() as u64;
        self.aabb = self.aabb.union(&Aabb::from_points(&part.vertices));
        let name = format!("{kind}.{}", self.objects);
        self.objects += 1;
        (self.sink)(name, part)
    }

    /// Triangles the scene is short of its target so far (negative: over).
    pub(crate) fn deficit(&self) -> f64 {
        self.triangles_per_object * self.objects as f64 - self.triangles as f64
    }

    /// Triangles per object the next objects should average to cancel the
    /// deficit within [`HORIZON`] objects (or by the scene's end).
    pub(crate) fn wanted_average(&self) -> f64 {
        let left = (self.total_objects - self.objects).clamp(1, HORIZON as u64) as f64;
        self.triangles_per_object + self.deficit() / left
    }
}
