//! The hull: the grid of compartments, their order, and the structure that
//! bounds each one (Paper §2: the scenes are subsets of oil tankers).
//!
//! Compartments are numbered across the hull (y) first, then up the decks
//! (z), then along it (x), so more objects make a longer hull. Each
//! compartment owns the plating on its low sides (floor deck, aft bulkhead,
//! port-side bulkhead or shell) and, where it has no neighbour, on its high
//! sides too, so the outer boundary is closed and no plate is made twice.
//! Its stiffeners sit on the faces towards its own inside. Everything a
//! compartment makes lies inside its box, so the scene's box is the grid's.

use std::io;

use super::emit::Emitter;
use super::outfit::{self, Room, Through};
use super::parts::{Part, Section, snap};
use super::presets::{Layout, Structure};
use super::spans::{pieces, stations};
use crate::geom::{Aabb, Point, Vector};
use crate::rng::Rng;

/// Hull plating thickness.
const PLATE_MM: f64 = 14.0;
/// Largest plate: strakes are at most this high, plates this long.
const STRAKE_MM: f64 = 2500.0;
const PLATE_LENGTH_MM: f64 = 6000.0;
/// Stiffener spacing and the angle profile used for them.
const STIFFENER_SPACING_MM: f64 = 750.0;
const STIFFENER: [f64; 3] = [150.0, 90.0, 10.0];
/// The deck transverse (web frame) under each deck: depth, flange width, web, flange.
const WEB_FRAME: [f64; 4] = [450.0, 150.0, 10.0, 15.0];
/// Skid members: square tubes of this size, and the base frame's depth.
const SKID_TUBE_MM: f64 = 100.0;
const SKID_BASE_MM: f64 = 200.0;
const SKID_PLATE_MM: f64 = 30.0;
const GRATING_MM: f64 = 1000.0;

/// Streams the scene for `layout` with `objects` objects.
pub(crate) fn generate(layout: &Layout, objects: u64, seed: u64, em: &mut Emitter) -> io::Result<()> {
    let count = layout.compartments_for(objects);
    for index in 0..count {
        em.start_compartment(objects * (index + 1) / count - objects * index / count);
        let cell = Cell::new(layout, index, count);
        let room = match layout.structure {
            Structure::Skid => skid(&cell, em)?,
            Structure::Hull => hull(&cell, seed, em)?,
        };
        // Compartment indices stay below 2^63, so the row streams (top bit
        // set, see `hull`) never collide with them.
        outfit::furnish(room, &mut Rng::derive(seed, index), em)?;
    }
    Ok(())
}

/// One compartment: its box, whether it has a neighbour on the high side
/// of each axis, and its row (position in the slice) for services that
/// run the length of the hull.
struct Cell {
    min: Point,
    max: Point,
    neighbour: [bool; 3],
    row: u64,
}

impl Cell {
    fn new(layout: &Layout, index: u64, count: u64) -> Cell {
        let slice = layout.across * layout.decks;
        let row = index % slice;
        let at = [index / slice, row % layout.across, row / layout.across];
        // Snapped per corner, so neighbours share their faces exactly.
        let corner = |k: u64| -> Point {
            std::array::from_fn(|i| snap((at[i] + k) as f64 * layout.cell_mm[i])).into()
        };
        Cell {
            min: corner(0),
            max: corner(1),
            neighbour: [
                index + slice < count,
                at[1] + 1 < layout.across && index + 1 < count,
                at[2] + 1 < layout.decks && index + layout.across < count,
            ],
            row,
        }
    }
}

/// Axis unit vectors by index.
fn unit(axis: usize) -> Vector {
    Vector::ith(axis, 1.0)
}

/// Emits the box between corners `lo` and `hi` as one object.
fn block(em: &mut Emitter, kind: &str, lo: [f64; 3], hi: [f64; 3]) -> io::Result<()> {
    let mut p = Part::default();
    p.cuboid(lo.into(), hi.into());
    em.emit(kind, p)
}

/// Emits a plate filling `b`, cut into plates at most `STRAKE_MM` along
/// `strake_axis` and `PLATE_LENGTH_MM` along `length_axis`.
fn plating(em: &mut Emitter, b: Aabb, strake_axis: usize, length_axis: usize) -> io::Result<()> {
    for (s0, s1) in pieces(b.min[strake_axis], b.max[strake_axis], STRAKE_MM) {
        for (l0, l1) in pieces(b.min[length_axis], b.max[length_axis], PLATE_LENGTH_MM) {
            let (mut lo, mut hi) = (b.min, b.max);
            (lo[strake_axis], hi[strake_axis], lo[length_axis], hi[length_axis]) = (s0, s1, l0, l1);
            block(em, "plate", lo.into(), hi.into())?;
        }
    }
    Ok(())
}

/// A stretch `[lo, hi]` along one axis.
#[derive(Debug, Clone, Copy)]
struct Span {
    axis: usize,
    lo: f64,
    hi: f64,
}

/// Emits angle stiffeners on a plate face: each runs the length of `run`,
/// one at each stiffener station of `across`, welded to the face at
/// `face` on the `normal` axis and standing towards `towards` (+1 or -1).
fn stiffeners(
    em: &mut Emitter,
    run: Span,
    across: Span,
    normal: usize,
    face: f64,
    towards: f64,
) -> io::Result<()> {
    let section = Section::angle(STIFFENER[0], STIFFENER[1], STIFFENER[2]);
    for at in stations(across.lo, across.hi, STIFFENER_SPACING_MM) {
        let mut start = Point::origin();
        (start[run.axis], start[across.axis], start[normal]) = (run.lo, at, face);
        let mut p = Part::default();
        p.prism(&section, start, unit(run.axis), unit(normal) * towards, run.hi - run.lo);
        em.emit("stiffener", p)?;
    }
    Ok(())
}

/// Hull structure for one compartment; returns the room left inside it.
fn hull(cell: &Cell, seed: u64, em: &mut Emitter) -> io::Result<Room> {
    let (min, max) = (cell.min, cell.max);
    let t = PLATE_MM;
    // The high faces: plated here when there is no neighbour to own them.
    let high = |axis: usize| if cell.neighbour[axis] { max[axis] } else { max[axis] - t };
    let (x1, y1, deck_above) = (high(0), high(1), high(2));
    let floor = min.z + t;
    let b = |lo: [f64; 3], hi: [f64; 3]| Aabb::new(lo.into(), hi.into());

    plating(em, b([min.x, min.y, min.z], [max.x, max.y, floor]), 0, 1)?;
    if !cell.neighbour[2] {
        plating(em, b([min.x, min.y, deck_above], [max.x, max.y, max.z]), 0, 1)?;
    }
    // Transverse bulkheads (x faces) span the full width; the longitudinal
    // ones (y faces) fit between them.
    let height = Span { axis: 2, lo: floor, hi: deck_above };
    let length = Span { axis: 0, lo: min.x + t, hi: x1 };
    let width = Span { axis: 1, lo: min.y + t, hi: y1 };
    plating(em, b([min.x, min.y, floor], [min.x + t, max.y, deck_above]), 2, 1)?;
    stiffeners(em, height, width, 0, min.x + t, 1.0)?;
    if !cell.neighbour[0] {
        plating(em, b([x1, min.y, floor], [max.x, max.y, deck_above]), 2, 1)?;
        stiffeners(em, height, width, 0, x1, -1.0)?;
    }
    plating(em, b([min.x + t, min.y, floor], [x1, min.y + t, deck_above]), 2, 0)?;
    stiffeners(em, height, length, 1, min.y + t, 1.0)?;
    if !cell.neighbour[1] {
        plating(em, b([min.x + t, y1, floor], [x1, max.y, deck_above]), 2, 0)?;
        stiffeners(em, height, length, 1, y1, -1.0)?;
    }
    // Deck longitudinals under the deck above, and one web frame across.
    stiffeners(em, length, width, 2, deck_above, -1.0)?;
    let [depth, width, web, flange] = WEB_FRAME;
    let mut p = Part::default();
    let start = Point::new(snap((min.x + max.x) / 2.0), min.y + t, deck_above);
    p.prism(&Section::tee(depth, width, web, flange), start, Vector::y(), -Vector::z(), y1 - start.y);
    em.emit("web-frame", p)?;

    let margin = t + STIFFENER[0];
    Ok(Room {
        clear: Aabb::new(
            Point::new(min.x + margin, min.y + margin, floor),
            Point::new(max.x - margin, max.y - margin, deck_above - depth),
        ),
        walls: Aabb::new(Point::new(min.x + t, min.y + t, floor), Point::new(x1, y1, deck_above)),
        hang_z: deck_above,
        through: Some(Through { x: [min.x, max.x], row: Rng::derive(seed, 1 << 63 | cell.row) }),
    })
}

/// An equipment skid: base frame, grating deck, corner posts, top rails.
/// Members are square tubes, except the I-beams under the long sides.
fn skid(cell: &Cell, em: &mut Emitter) -> io::Result<Room> {
    let (min, max) = (cell.min, cell.max);
    let s = SKID_TUBE_MM;
    let base_top = min.z + SKID_BASE_MM;
    let deck = base_top + SKID_PLATE_MM;
    // Rolled I-beams under the long sides, tubes across.
    let beam = Section::i_beam(SKID_BASE_MM, s, 8.0, 12.0);
    for y in [min.y + s / 2.0, max.y - s / 2.0] {
        let mut p = Part::default();
        p.prism(&beam, Point::new(min.x, y, min.z), Vector::x(), Vector::z(), max.x - min.x);
        em.emit("beam", p)?;
    }
    for x in [min.x, (min.x + max.x - s) / 2.0, max.x - s] {
        let x = snap(x);
        block(em, "beam", [x, min.y + s, min.z], [x + s, max.y - s, base_top])?;
    }
    // The deck is grating panels of at most a metre square.
    for (x0, x1) in pieces(min.x, max.x, GRATING_MM) {
        for (y0, y1) in pieces(min.y, max.y, GRATING_MM) {
            block(em, "grating", [snap(x0), snap(y0), base_top], [snap(x1), snap(y1), deck])?;
        }
    }
    for x in [min.x, max.x - s] {
        for y in [min.y, max.y - s] {
            block(em, "post", [x, y, deck], [x + s, y + s, max.z - s])?;
        }
    }
    for y in [min.y, max.y - s] {
        block(em, "rail", [min.x, y, max.z - s], [max.x, y + s, max.z])?;
    }
    Ok(Room {
        clear: Aabb::new(Point::new(min.x + s, min.y + s, deck), Point::new(max.x - s, max.y - s, max.z - s)),
        walls: Aabb::new(Point::new(min.x, min.y, deck), Point::new(max.x, max.y, max.z)),
        hang_z: deck,
        through: None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn neighbours_are_found_in_a_partial_slice() {
        let layout = super::super::Preset::Tanker2.layout().unwrap(); // 2 across, 5 decks
        let last = Cell::new(&layout, 4, 5); // (x 0, y 0, z 2), the fifth of five
        assert_eq!(last.neighbour, [false, false, false]);
        let first = Cell::new(&layout, 0, 5);
        assert_eq!(first.neighbour, [false, true, true]);
        let full = Cell::new(&layout, 0, 40);
        assert_eq!(full.neighbour, [true, true, true]);
        assert_eq!(full.max, Point::new(8647.0, 6462.0, snap(27351.0 / 5.0)));
    }
}
