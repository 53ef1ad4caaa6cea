//! The plant preset: a process plant's pipe racks and the equipment beside
//! them. It is a scene unlike the hull's compartments, kept to report on
//! and not to tune on (issue 38): pipes and longitudinal beams run across
//! many bays, so they straddle any cut the bulk loaders make along the rack,
//! while pipe shoes, flanges, nozzles and instrument boxes are small.
//!
//! The plant is rows of rack bays along x ([`BAYS_PER_ROW`] bays a row,
//! rows side by side in y), each bay [`BAY_MM`] long. A bay has two
//! columns and a cross beam at each of three levels; longitudinal beams at
//! every level start every third bay and span three. Each level has lanes
//! across the rack; a free lane starts a pipe run of 2 to 20 bays, made of
//! spools of at most four bays with a flange between them, a shoe on every
//! cross beam it crosses, sometimes a valve, and at its end an elbow and a
//! drop to grade. Beside each side of the rack, equipment fills the rest of
//! the bay's object budget: vertical vessels with their nozzles, horizontal
//! drums, pumps with their motors, and instrument boxes.
//!
//! As for the hull, objects are streamed bay by bay, each bay gets an equal
//! share of the objects, and a preset and a seed give the same scene
//! everywhere.

use std::io;

use super::emit::Emitter;
use super::parts::{Part, Section, snap};
use crate::geom::{Point, Vector};
use crate::rng::Rng;

/// Objects a bay holds: the plant grows by bays.
pub(crate) const OBJECTS_PER_BAY: u64 = 120;
/// Rack bay length along x, rack width along y.
const BAY_MM: f64 = 6000.0;
const RACK_WIDTH_MM: f64 = 8000.0;
/// Bays in a row; rows stand side by side in y, [`ROW_PITCH_MM`] apart.
const BAYS_PER_ROW: u64 = 50;
const ROW_PITCH_MM: f64 = 40_000.0;
/// The rack's levels (top of steel) and its columns' height.
const LEVELS_MM: [f64; 3] = [4500.0, 6500.0, 8500.0];
const COLUMN_MM: f64 = 9000.0;
/// Column and beam sections: depth, width, web, flange.
const COLUMN: [f64; 4] = [300.0, 300.0, 12.0, 18.0];
const BEAM: [f64; 4] = [250.0, 150.0, 8.0, 12.0];
/// Lanes across the rack at each level, and their pitch.
const LANES: u64 = 11;
const LANE_PITCH_MM: f64 = 650.0;
/// Pipe outside diameters, mm, smallest first; small ones are commoner.
const PIPE_MM: [f64; 9] = [60.0, 90.0, 114.0, 168.0, 219.0, 273.0, 324.0, 406.0, 508.0];
/// The longest spool, in bays.
const SPOOL_BAYS: u64 = 4;
/// Equipment stands in a strip of this width beside each side of the rack.
const YARD_MM: f64 = 12_000.0;

/// Streams a plant of `objects` objects.
pub(crate) fn generate(objects: u64, seed: u64, em: &mut Emitter) -> io::Result<()> {
    let bays = objects.div_ceil(OBJECTS_PER_BAY).max(1);
    // The bay, per level and lane, up to which a pipe run holds the lane.
    let mut busy = vec![0u64; LEVELS_MM.len() * LANES as usize];
    for bay in 0..bays {
        em.start_compartment(objects * (bay + 1) / bays - objects * bay / bays);
        let mut rng = Rng::derive(seed, bay);
        let at = origin(bay);
        rack_bay(bay, at, em)?;
        for (level, &z) in LEVELS_MM.iter().enumerate() {
            for lane in 0..LANES {
                let slot = level * LANES as usize + lane as usize;
                // A run starts where a lane is free, not in the row's last bay.
                if busy[slot] > bay || bay % BAYS_PER_ROW == BAYS_PER_ROW - 1 || !rng.chance(0.45) {
                    continue;
                }
                let left = BAYS_PER_ROW - bay % BAYS_PER_ROW - 1;
                let length = rng.between(2, 20).min(left);
                busy[slot] = bay + length;
                let y = at.y + 400.0 + lane as f64 * LANE_PITCH_MM;
                pipe_run(Point::new(at.x, y, z), length, &mut rng, em)?;
            }
        }
        // Equipment takes the rest of the bay's budget.
        let mut side = 0u64;
        while !em.full() {
            equipment(at, side.is_multiple_of(2), &mut rng, em)?;
            side += 1;
        }
    }
    Ok(())
}

/// The low corner of bay `bay`'s rack: rows of bays along x, side by side in y.
fn origin(bay: u64) -> Point {
    let (row, along) = (bay / BAYS_PER_ROW, bay % BAYS_PER_ROW);
    Point::new(snap(along as f64 * BAY_MM), snap(row as f64 * ROW_PITCH_MM), 0.0)
}

/// `section` swept from `start` along `along` for `length`, its v axis along `up`.
fn prism(section: &Section, start: Point, along: Vector, up: Vector, length: f64) -> Part {
    let mut p = Part::default();
    p.prism(section, start, along, up, length);
    p
}

fn i_beam(s: [f64; 4]) -> Section {
    Section::i_beam(s[0], s[1], s[2], s[3])
}

/// A bay's steel: two columns, a cross beam under each level, and every
/// third bay the longitudinal beams of three bays at each level and side.
fn rack_bay(bay: u64, at: Point, em: &mut Emitter) -> io::Result<()> {
    let column = i_beam(COLUMN);
    for y in [0.0, RACK_WIDTH_MM] {
        let foot = Point::new(at.x, at.y + y, 0.0);
        em.emit("column", prism(&column, foot, Vector::z(), Vector::x(), COLUMN_MM))?;
    }
    let beam = i_beam(BEAM);
    for &z in &LEVELS_MM {
        let start = Point::new(at.x, at.y, z - BEAM[0]);
        em.emit("beam", prism(&beam, start, Vector::y(), Vector::z(), RACK_WIDTH_MM))?;
    }
    let left = BAYS_PER_ROW - bay % BAYS_PER_ROW;
    if bay.is_multiple_of(3) {
        let span = left.min(3) as f64 * BAY_MM;
        for &z in &LEVELS_MM {
            for y in [0.0, RACK_WIDTH_MM] {
                let start = Point::new(at.x, at.y + y, z - BEAM[0]);
                em.emit("beam", prism(&beam, start, Vector::x(), Vector::z(), span))?;
            }
        }
    }
    Ok(())
}

/// A pipe run of `bays` bays from `start` (its axis over the level's top of
/// steel) along x: spools with flanges between, a shoe on each cross beam,
/// sometimes a valve, and at its end an elbow and a drop to grade.
fn pipe_run(start: Point, bays: u64, rng: &mut Rng, em: &mut Emitter) -> io::Result<()> {
    // Small pipes are commoner: the square of a uniform draw picks the size.
    let u = rng.unit();
    let d = PIPE_MM[((u * u) * PIPE_MM.len() as f64) as usize % PIPE_MM.len()];
    let sides = if d < 150.0 { 12 } else { 16 };
    let (r, lift) = (d / 2.0, d / 2.0 + 60.0);
    let axis = Point::new(start.x, start.y, start.z + lift);
    let pipe = Section::ngon(sides, r);
    let flange = Section::ngon(sides, r + 0.35 * d.max(60.0));
    let length = bays as f64 * BAY_MM;
    let mut done = 0u64;
    while done < bays {
        let spool = (bays - done).min(rng.between(1, SPOOL_BAYS));
        let from = axis + Vector::x() * (done as f64 * BAY_MM);
        em.emit("pipe", prism(&pipe, from, Vector::x(), Vector::z(), spool as f64 * BAY_MM))?;
        done += spool;
        if done < bays {
            let joint = axis + Vector::x() * (done as f64 * BAY_MM - 30.0);
            em.emit("flange", prism(&flange, joint, Vector::x(), Vector::z(), 60.0))?;
        }
    }
    // A shoe where the pipe crosses each cross beam but the first.
    for k in 1..bays {
        let x = start.x + k as f64 * BAY_MM;
        let min = Point::new(snap(x - 100.0), snap(start.y - r), start.z);
        let max = Point::new(snap(x + 100.0), snap(start.y + r), snap(start.z + 60.0));
        let mut shoe = Part::default();
        shoe.cuboid(min, max);
        em.emit("shoe", shoe)?;
    }
    if rng.chance(0.3) {
        let at = axis + Vector::x() * snap(rng.range(0.2, 0.8) * length);
        let mut valve = Part::default();
        valve.valve(at, Vector::x(), Vector::z(), d, sides);
        em.emit("valve", valve)?;
    }
    // The end turns down to grade, beside the rack's last column.
    let bend_r = 1.5 * d;
    let corner = axis + Vector::x() * (length + bend_r);
    let mut elbow = Part::default();
    elbow.bend(&pipe, corner, Vector::x(), -Vector::z(), bend_r, 4);
    em.emit("elbow", elbow)?;
    let top = corner - Vector::z() * bend_r;
    let drop = (top.z - 300.0).max(100.0);
    em.emit("pipe", prism(&pipe, top, -Vector::z(), Vector::x(), drop))
}

/// One piece of equipment at a random place in the yard beside the rack at
/// `at` (the low side when `low`): a vessel, a drum, a pump or an instrument box.
fn equipment(at: Point, low: bool, rng: &mut Rng, em: &mut Emitter) -> io::Result<()> {
    let y0 = if low { at.y - YARD_MM - 1000.0 } else { at.y + RACK_WIDTH_MM + 1000.0 };
    let x = snap(at.x + rng.range(1500.0, BAY_MM - 1500.0));
    let y = snap(y0 + rng.range(1500.0, YARD_MM - 1500.0));
    match rng.below(10) {
        0 | 1 => {
            // A vertical vessel on a skirt, with nozzles around its shell.
            let radius = snap(rng.range(600.0, 1400.0));
            let height = snap(rng.range(3000.0, 12_000.0));
            let skirt = 1000.0;
            em.emit(
                "skirt",
                prism(&Section::ngon(24, radius), Point::new(x, y, 0.0), Vector::z(), Vector::x(), skirt),
            )?;
            let shell = Point::new(x, y, skirt);
            em.emit("vessel", prism(&Section::ngon(24, radius), shell, Vector::z(), Vector::x(), height))?;
            for k in 0..rng.between(2, 4) {
                let z = skirt + height * (0.2 + 0.2 * k as f64);
                let d = PIPE_MM[rng.below(5) as usize];
                let (dir, up) =
                    if k % 2 == 0 { (Vector::x(), Vector::z()) } else { (Vector::y(), Vector::z()) };
                let from = Point::new(x, y, snap(z)) + dir * (radius - 50.0);
                em.emit("nozzle", prism(&Section::ngon(12, d / 2.0), from, dir, up, 400.0))?;
            }
        }
        2 | 3 => {
            // A horizontal drum on two saddles.
            let radius = snap(rng.range(500.0, 1200.0));
            let length = snap(rng.range(2500.0, BAY_MM - 1000.0).min(2.0 * (BAY_MM - 1500.0)));
            let x0 = snap(at.x + 500.0);
            let axis = Point::new(x0, y, 600.0 + radius);
            em.emit("drum", prism(&Section::ngon(20, radius), axis, Vector::x(), Vector::z(), length))?;
            for t in [0.2, 0.8] {
                let sx = snap(x0 + t * length);
                let mut saddle = Part::default();
                saddle.cuboid(
                    Point::new(sx - 150.0, y - radius, 0.0),
                    Point::new(sx + 150.0, y + radius, 600.0 + radius / 2.0),
                );
                em.emit("saddle", saddle)?;
            }
        }
        4..=6 => {
            // A pump: baseplate, casing and motor along x.
            let size = snap(rng.range(300.0, 700.0));
            let mut base = Part::default();
            base.cuboid(
                Point::new(x - 2.0 * size, y - size, 0.0),
                Point::new(x + 2.0 * size, y + size, 150.0),
            );
            em.emit("pump-base", base)?;
            let centre = Point::new(x - 2.0 * size + 50.0, y, 150.0 + size);
            em.emit(
                "pump",
                prism(&Section::ngon(16, 0.8 * size), centre, Vector::x(), Vector::z(), 1.5 * size),
            )?;
            let motor = centre + Vector::x() * (1.7 * size);
            em.emit(
                "motor",
                prism(&Section::ngon(16, 0.7 * size), motor, Vector::x(), Vector::z(), 2.0 * size),
            )?;
        }
        _ => {
            // An instrument or junction box on a stand.
            let w = snap(rng.range(200.0, 600.0));
            let h = snap(rng.range(800.0, 1500.0));
            let mut stand = Part::default();
            stand.cuboid(Point::new(x - 40.0, y - 40.0, 0.0), Point::new(x + 40.0, y + 40.0, h));
            em.emit("stand", stand)?;
            let mut b = Part::default();
            b.cuboid(Point::new(x - w, y - w / 2.0, h), Point::new(x + w, y + w / 2.0, h + w));
            em.emit("box", b)?;
        }
    }
    Ok(())
}
