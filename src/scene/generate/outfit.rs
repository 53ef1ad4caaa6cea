//! Outfitting one compartment: equipment on the floor, bundles of parallel
//! pipes between pieces of equipment or out to the walls, and, in the hull,
//! the mains and cable trays that run the length of the ship.
//!
//! A bundle is one route copied sideways per line: up from the equipment
//! (z), along one horizontal axis, along the other, and down to the next
//! piece (or to a wall), so runs are parallel to the three axes as in an
//! engine room. Lines are offset against the direction of the horizontal
//! turn, so their elbows nest instead of crossing. Each line is built of
//! straight spools with flanges between them, swept elbows at the corners,
//! and now and then a valve; horizontal runs get supports (a beam, posts
//! up to the deck above or down to a skid's deck, and a shoe per line).
//!
//! Sizes and counts steer the triangle total (see `emit.rs`): the pipe size
//! class of a bundle follows [`Emitter::wanted_average`], and valves and
//! supports follow [`Emitter::deficit`].

use std::io;

use super::emit::Emitter;
use super::parts::{Part, Section, snap, valve_height, valve_length};
use super::spans::{pieces, stations};
use crate::geom::{Aabb, Point, Vector};
use crate::rng::Rng;

/// The space a compartment leaves for outfitting.
#[derive(Debug, Clone)]
pub(crate) struct Room {
    /// Free space for equipment and pipe routes.
    pub(crate) clear: Aabb,
    /// The structure's inner faces on x and y, where pipes leaving the
    /// compartment end.
    pub(crate) walls: Aabb,
    /// Where support posts end: the deck above, or a skid's deck plate.
    pub(crate) hang_z: f64,
    /// The row's services, in the hull.
    pub(crate) through: Option<Through>,
}

/// Mains and a cable tray that pass through every compartment of a row,
/// from bulkhead to bulkhead.
#[derive(Debug, Clone)]
pub(crate) struct Through {
    /// The compartment's extent in x.
    pub(crate) x: [f64; 2],
    /// The row's own stream: sizes and positions repeat from compartment to
    /// compartment, so the runs line up along the hull.
    pub(crate) row: Rng,
}

/// A nominal pipe size and how finely it is tessellated, as CAD exports
/// of the paper's time did: small bores get hexagons and two-segment bends.
#[derive(Debug, Clone, Copy)]
struct PipeClass {
    diameter: f64,
    sides: u32,
    bend_segments: u32,
}

/// Pipe classes, smallest first; `typical_triangles` grows along the list.
const PIPES: [PipeClass; 8] = [
    PipeClass { diameter: 34.0, sides: 6, bend_segments: 2 },
    PipeClass { diameter: 60.0, sides: 6, bend_segments: 3 },
    PipeClass { diameter: 89.0, sides: 8, bend_segments: 3 },
    PipeClass { diameter: 114.0, sides: 8, bend_segments: 4 },
    PipeClass { diameter: 168.0, sides: 12, bend_segments: 4 },
    PipeClass { diameter: 219.0, sides: 12, bend_segments: 5 },
    PipeClass { diameter: 324.0, sides: 16, bend_segments: 5 },
    PipeClass { diameter: 406.0, sides: 16, bend_segments: 6 },
];

impl PipeClass {
    fn radius(self) -> f64 {
        self.diameter / 2.0
    }

    /// Centreline radius of an elbow (a long-radius bend).
    fn bend_radius(self) -> f64 {
        1.5 * self.diameter
    }

    fn flange_radius(self) -> f64 {
        0.85 * self.diameter
    }

    /// Centre to centre of neighbouring lines: flanges clear each other.
    fn pitch(self) -> f64 {
        snap(2.0 * self.flange_radius() + (0.3 * self.diameter).max(30.0))
    }

    /// Longest straight spool between flanges.
    fn spool(self) -> f64 {
        (40.0 * self.diameter).min(6000.0)
    }

    /// Distance between support stations on horizontal runs.
    fn support_step(self) -> f64 {
        (8.0 * self.diameter).clamp(250.0, 3000.0)
    }

    /// Beam and post size of a support.
    fn support_size(self) -> f64 {
        snap((0.4 * self.diameter).max(40.0))
    }

    /// Shortest leg between two elbows: both bends and a diameter of straight.
    fn shortest_leg(self) -> f64 {
        2.0 * self.bend_radius() + self.diameter
    }

    /// A rough triangles-per-object figure for a bundle of this class, as
    /// [`Part::sweep`] builds it: two straights or flanges (n-gon prisms,
    /// 4n - 4) to one elbow (2ns sides + 2(n - 2) caps). It only ranks
    /// classes for the steering; the emitter corrects the rest.
    fn typical_triangles(self) -> f64 {
        let (n, s) = (f64::from(self.sides), f64::from(self.bend_segments));
        (2.0 * (4.0 * n - 4.0) + (2.0 * n * s + 2.0 * n - 4.0)) / 3.0
    }
}

/// Outfits `room` until the compartment's object budget is spent.
pub(crate) fn furnish(mut room: Room, rng: &mut Rng, em: &mut Emitter) -> io::Result<()> {
    // Pipes up to a tenth of the headroom: a skid gets small bores only.
    let classes: Vec<PipeClass> =
        PIPES.into_iter().filter(|c| c.diameter <= room.clear.extent().z / 10.0).collect();
    if let Some(through) = room.through.take() {
        room.clear.max.z = services(&room, through, &classes, rng, em)?;
    }
    let equipment = equipment(&room, rng, em)?;
    while !em.full() {
        bundle(&room, &equipment, &classes, rng, em)?;
    }
    Ok(())
}

/// Emits the row's mains and cable tray under the deck head; returns the
/// height below which the room stays free.
fn services(
    room: &Room,
    mut through: Through,
    classes: &[PipeClass],
    rng: &mut Rng,
    em: &mut Emitter,
) -> io::Result<f64> {
    let row = &mut through.row;
    let c = room.clear;
    let mid_y = (c.min.y + c.max.y) / 2.0;
    // Mains: two to four lines of one of the two largest classes, in the
    // port half of the room.
    let class = classes[classes.len() - 1 - row.below(2.min(classes.len() as u64)) as usize];
    let pitch = class.pitch();
    let fit = ((mid_y - c.min.y) / pitch).floor() as u64;
    let lines = row.between(2, 4).min(fit.saturating_sub(1)).max(1);
    let z = snap(c.max.z - class.flange_radius() - 50.0);
    let y0 = snap(row.range(c.min.y + pitch, mid_y - pitch * lines as f64));
    let [x0, x1] = through.x;
    let mains: Vec<Vec<Point>> = (0..lines)
        .map(|j| {
            let y = y0 + pitch * j as f64;
            vec![Point::new(x0, y, z), Point::new(x1, y, z)]
        })
        .collect();
    lay(room, class, &mains, rng, em)?;
    let mains_bottom = z - class.radius() - 1.5 * class.support_size();

    // Cable tray: a channel in the starboard half, supported at every joint.
    let (width, depth) = (snap(row.range(300.0, 600.0)), 100.0);
    let y = snap(row.range(mid_y + width, c.max.y - width / 2.0));
    let tray_bottom = snap(c.max.z - 50.0 - depth);
    let section = Section::channel(width, depth, 3.0);
    let hanger = 50.0;
    for (a, b) in pieces(x0, x1, 2400.0) {
        let mut p = Part::default();
        p.prism(&section, Point::new(a, y, tray_bottom), Vector::x(), Vector::z(), b - a);
        em.emit("tray", p)?;
        let span = (y - width / 2.0 - hanger, y + width / 2.0 + hanger);
        let s =
            Support { axis: 0, station: a + hanger, span, beam_top: tray_bottom, size: hanger, shoes: &[] };
        support(room, s, em)?;
    }
    Ok(snap(mains_bottom.min(tray_bottom - hanger) - 100.0))
}

/// Places equipment on the floor, at most one piece per cell of a coarse
/// grid, the first always a pump unit; returns the pieces' boxes.
fn equipment(room: &Room, rng: &mut Rng, em: &mut Emitter) -> io::Result<Vec<Aabb>> {
    let c = room.clear;
    let e = c.extent();
    // At least two slots along the longer side, at most 2.2 m each.
    let slot = (e.x.max(e.y) / 2.0).min(2200.0);
    let (nx, ny) = ((e.x / slot).floor().max(1.0) as u64, (e.y / slot).floor().max(1.0) as u64);
    let mut slots: Vec<u64> = (0..nx * ny).collect();
    for i in (1..slots.len()).rev() {
        slots.swap(i, rng.below(i as u64 + 1) as usize);
    }
    // About one piece per 45 objects of budget, at least two so bundles
    // have somewhere to go.
    slots.truncate((em.room_left() / 45).clamp(2, nx * ny) as usize);
    let (w, d) = (e.x / nx as f64, e.y / ny as f64);
    let mut boxes = Vec::with_capacity(slots.len());
    for (k, s) in slots.into_iter().enumerate() {
        let (i, j) = ((s % nx) as f64, (s / nx) as f64);
        let (fx, fy) = (rng.range(0.45, 0.8) * w, rng.range(0.45, 0.8) * d);
        let x0 = c.min.x + i * w + rng.range(0.0, w - fx);
        let y0 = c.min.y + j * d + rng.range(0.0, d - fy);
        let height = rng.range(0.25, 0.45) * e.z;
        let b = Aabb::new(
            Point::new(snap(x0), snap(y0), c.min.z),
            Point::new(snap(x0 + fx), snap(y0 + fy), snap(c.min.z + height)),
        );
        match if k == 0 { 0 } else { rng.below(4) } {
            0 => pump(b, em)?,
            1 => vertical_tank(b, em)?,
            2 => vessel(b, em)?,
            _ => cabinets(b, rng, em)?,
        }
        boxes.push(b);
    }
    Ok(boxes)
}

/// The long horizontal axis of a footprint, and the other one.
fn long_axis(b: &Aabb) -> (usize, usize) {
    let e = b.extent();
    if e.x >= e.y { (0, 1) } else { (1, 0) }
}

/// A point of `b` given as fractions along its long axis, its short axis and z.
fn at(b: &Aabb, along: f64, across: f64, up: f64) -> Point {
    let (a, c) = long_axis(b);
    let mut p = b.min;
    p[a] += along * b.extent()[a];
    p[c] += across * b.extent()[c];
    p.z += up * b.extent().z;
    Point::new(snap(p.x), snap(p.y), snap(p.z))
}

/// Sides of an equipment shell of `radius`: a multiple of 4 from 12 to 48,
/// about one per 20 mm of radius, so large tanks are smoother than small
/// pumps, as a CAD export's chord tolerance makes them.
fn sides_for(radius: f64) -> u32 {
    4 * ((radius / 80.0).round() as u32).clamp(3, 12)
}

fn cuboid(min: Point, max: Point) -> Part {
    let mut p = Part::default();
    p.cuboid(min, max);
    p
}

/// A pump unit filling `b`: baseplate, pump casing with its suction and
/// discharge nozzles, coupling guard, and motor with its terminal box.
fn pump(b: Aabb, em: &mut Emitter) -> io::Result<()> {
    let (a, c) = long_axis(&b);
    let (along, e) = (Vector::ith(a, 1.0), b.extent());
    let (length, height) = (e[a], e.z);
    let base = snap(b.min.z + 0.12 * height);
    em.emit("baseplate", cuboid(b.min, Point::new(b.max.x, b.max.y, base)))?;

    let rc = snap((0.3 * e[c]).min(0.3 * height));
    let zc = base + rc;
    let axis = |frac: f64| {
        let mut p = at(&b, frac, 0.5, 0.0);
        p.z = zc;
        p
    };
    let mut casing = Part::default();
    casing.prism(&Section::ngon(sides_for(rc), rc), axis(0.12), along, Vector::z(), 0.33 * length);
    casing.prism(&Section::ngon(8, 0.35 * rc), axis(0.0), along, Vector::z(), 0.12 * length);
    casing.prism(&Section::ngon(8, 0.3 * rc), axis(0.28), Vector::z(), along, b.max.z - zc);
    em.emit("pump", casing)?;

    let mut guard_lo = axis(0.45);
    guard_lo[c] -= 0.6 * rc;
    guard_lo.z = base;
    let mut guard_hi = axis(0.55);
    guard_hi[c] += 0.6 * rc;
    guard_hi.z = zc + 0.6 * rc;
    em.emit("coupling-guard", cuboid(guard_lo.inf(&guard_hi), guard_lo.sup(&guard_hi)))?;

    let rm = snap(0.9 * rc);
    let mut motor = Part::default();
    motor.prism(&Section::ngon(sides_for(rm), rm), axis(0.55), along, Vector::z(), 0.4 * length);
    let (mut box_lo, mut box_hi) = (axis(0.65), axis(0.8));
    box_lo[c] -= 0.4 * rm;
    box_hi[c] += 0.4 * rm;
    box_lo.z = zc + 0.8 * rm;
    box_hi.z = zc + 1.3 * rm;
    motor.cuboid(box_lo.inf(&box_hi), box_lo.sup(&box_hi));
    em.emit("motor", motor)
}

/// A vertical cylindrical tank filling `b`, with a manway neck on top.
fn vertical_tank(b: Aabb, em: &mut Emitter) -> io::Result<()> {
    let e = b.extent();
    let r = snap(0.5 * e.x.min(e.y));
    let neck = snap(0.1 * e.z);
    let centre = at(&b, 0.5, 0.5, 0.0);
    let mut shell = Part::default();
    shell.prism(&Section::ngon(sides_for(r), r), centre, Vector::z(), Vector::x(), e.z - neck);
    em.emit("tank", shell)?;
    let mut manway = Part::default();
    manway.prism(
        &Section::ngon(12, 0.25 * r),
        at(&b, 0.5, 0.5, 1.0) - Vector::z() * neck,
        Vector::z(),
        Vector::x(),
        neck,
    );
    em.emit("manway", manway)
}

/// A horizontal pressure vessel (heat exchanger, receiver) on two saddles.
fn vessel(b: Aabb, em: &mut Emitter) -> io::Result<()> {
    let (a, c) = long_axis(&b);
    let e = b.extent();
    let saddle = snap(0.2 * e.z);
    let r = snap((0.5 * e[c]).min(0.4 * e.z));
    for frac in [0.2, 0.8] {
        let (mut lo, mut hi) = (at(&b, frac - 0.04, 0.1, 0.0), at(&b, frac + 0.04, 0.9, 0.0));
        hi.z += saddle;
        lo[c] = lo[c].max(at(&b, 0.0, 0.5, 0.0)[c] - r);
        hi[c] = hi[c].min(at(&b, 0.0, 0.5, 0.0)[c] + r);
        em.emit("saddle", cuboid(lo, hi))?;
    }
    let mut start = at(&b, 0.0, 0.5, 0.0);
    start.z += saddle + r;
    let mut shell = Part::default();
    shell.prism(&Section::ngon(sides_for(r), r), start, Vector::ith(a, 1.0), Vector::z(), e[a]);
    em.emit("vessel", shell)
}

/// One to three cabinets (switchboard sections) side by side in `b`.
fn cabinets(b: Aabb, rng: &mut Rng, em: &mut Emitter) -> io::Result<()> {
    let count = rng.between(1, 3);
    for k in 0..count {
        let (lo, mut hi) =
            (at(&b, k as f64 / count as f64, 0.0, 0.0), at(&b, (k as f64 + 0.95) / count as f64, 1.0, 1.0));
        hi.z = b.max.z;
        em.emit("cabinet", cuboid(lo, hi))?;
    }
    Ok(())
}

/// Where a bundle ends.
#[derive(Debug, Clone, Copy)]
enum End {
    /// On top of a piece of equipment.
    Equipment(Aabb),
    /// At a wall, normal to `axis`.
    Wall { axis: usize, at: f64 },
}

/// One bundle from a random piece of equipment to another (or to a wall).
fn bundle(
    room: &Room,
    equipment: &[Aabb],
    classes: &[PipeClass],
    rng: &mut Rng,
    em: &mut Emitter,
) -> io::Result<()> {
    let n = equipment.len() as u64;
    let from = rng.below(n);
    let to = if rng.chance(0.75) {
        End::Equipment(equipment[((from + 1 + rng.below(n - 1)) % n) as usize])
    } else {
        let axis = rng.below(2) as usize;
        let start = equipment[from as usize].center()[axis];
        // The farther wall, so the last leg has room for its bend.
        let (lo, hi) = (room.walls.min[axis], room.walls.max[axis]);
        End::Wall { axis, at: if start - lo > hi - start { lo } else { hi } }
    };
    let from = equipment[from as usize];
    let want = em.wanted_average();
    // Below what even the smallest bore averages, single and paired lines
    // get more supports per pipe.
    let lines = rng.between(1, if want < classes[0].typical_triangles() { 2 } else { 4 });
    let first = rng.below(2) as usize;
    let chosen = choose_class(classes, want, rng);
    // A bundle too big for the headroom falls back to smaller bores; the
    // smallest fits every room (equipment stays under half the headroom).
    let (class, route) = classes[..=chosen]
        .iter()
        .rev()
        .find_map(|&class| Some((class, route(room, &from, to, class, lines, first, rng)?)))
        .expect("the smallest pipe class fits every room");
    lay(room, class, &route, rng, em)
}

/// The class for a bundle when the emitter wants `want` triangles per
/// object: the largest class typically under `want`, or with the right odds
/// the next one up, so that on average the bundle matches `want`.
fn choose_class(classes: &[PipeClass], want: f64, rng: &mut Rng) -> usize {
    let below = classes.iter().rposition(|c| c.typical_triangles() <= want).unwrap_or(0);
    match classes.get(below + 1) {
        Some(up) => {
            let low = classes[below].typical_triangles();
            let odds = (want - low) / (up.typical_triangles() - low);
            if rng.chance(odds) { below + 1 } else { below }
        }
        None => below,
    }
}

/// The corner points of each line of a bundle of `lines` pipes from the
/// top of `from` to `to`, first along horizontal axis `first` (equipment
/// to equipment) or along the wall (to a wall); `None` if the class does
/// not fit.
fn route(
    room: &Room,
    from: &Aabb,
    to: End,
    class: PipeClass,
    lines: u64,
    first: usize,
    rng: &mut Rng,
) -> Option<Vec<Vec<Point>>> {
    let (d, r, pitch) = (class.diameter, class.bend_radius(), class.pitch());
    // Lines must start (and end) on the equipment's top.
    let fits = |b: &Aabb| 1 + (b.extent().x.min(b.extent().y) / pitch).floor() as u64;
    let mut lines = lines.min(fits(from));
    let start = from.center();
    let (dest, axes, top) = match to {
        End::Equipment(b) => {
            lines = lines.min(fits(&b));
            (b.center(), [first, 1 - first], from.max.z.max(b.max.z))
        }
        End::Wall { axis, at } => {
            let spread = pitch * (lines - 1) as f64;
            let along = 1 - axis;
            let (lo, hi) =
                (room.clear.min[along] + spread / 2.0 + d, room.clear.max[along] - spread / 2.0 - d);
            if lo > hi {
                return None;
            }
            let mut dest = start;
            dest[along] = snap(rng.range(lo, hi));
            dest[axis] = at;
            (dest, [along, axis], from.max.z)
        }
    };
    let low = top + r + d;
    let high = room.clear.max.z - valve_height(d).max(class.flange_radius());
    if low > high {
        return None;
    }
    let h = snap(rng.range(low, high));

    // Offset lines against the turn so elbows nest: sign +1 along the first
    // leg's direction, -1 along the second's.
    let heading = |axis: usize| if dest[axis] >= start[axis] { 1.0 } else { -1.0 };
    let mut shift = Vector::zeros();
    shift[axes[0]] = heading(axes[0]) * pitch;
    shift[axes[1]] = -heading(axes[1]) * pitch;
    let centre = (lines - 1) as f64 / 2.0;
    // A leg too short for two bends is dropped (the bundle lands a little
    // off centre instead); the leg to a wall is always kept.
    let keep = |axis: usize| (dest[axis] - start[axis]).abs() >= class.shortest_leg();
    let keep = [keep(axes[0]), keep(axes[1]) || matches!(to, End::Wall { .. })];
    if !keep[0] && !keep[1] {
        return None;
    }
    let mut routes = Vec::with_capacity(lines as usize);
    for j in 0..lines {
        let offset = shift * (j as f64 - centre);
        let mut p = Point::new(snap(start.x + offset.x), snap(start.y + offset.y), from.max.z);
        let mut points = vec![p];
        p.z = h;
        points.push(p);
        for (k, &axis) in axes.iter().enumerate() {
            if keep[k] {
                p[axis] = snap(dest[axis] + offset[axis]);
                points.push(p);
            }
        }
        match to {
            End::Equipment(b) => {
                p.z = b.max.z;
                points.push(p);
            }
            End::Wall { axis, at } => {
                // Every line ends on the wall: the last leg absorbs the offset,
                // and must still have room for its bend.
                p[axis] = at;
                *points.last_mut()? = p;
                let before = points[points.len() - 2];
                if (p[axis] - before[axis]).abs() < r + d {
                    return None;
                }
            }
        }
        routes.push(points);
    }
    Some(routes)
}

/// Lays a bundle: for each leg, its supports if it is horizontal, then each
/// line's spools, flanges, valve and the elbow that ends the leg.
fn lay(
    room: &Room,
    class: PipeClass,
    lines: &[Vec<Point>],
    rng: &mut Rng,
    em: &mut Emitter,
) -> io::Result<()> {
    let legs = lines[0].len() - 1;
    let r = class.bend_radius();
    let bore = Bore {
        class,
        pipe: Section::ngon(class.sides, class.radius()),
        flange: Section::ngon(class.sides, class.flange_radius()),
    };
    let direction = |line: &[Point], leg: usize| (line[leg + 1] - line[leg]).normalize();
    for leg in 0..legs {
        let dir = direction(&lines[0], leg);
        let axis = dir.iamax();
        let horizontal = axis != 2;
        // Each line's straight stretch: the leg less the bends at its ends.
        let stretches: Vec<(Point, Point)> = lines
            .iter()
            .map(|line| {
                let a = line[leg] + dir * if leg > 0 { r } else { 0.0 };
                (a, line[leg + 1] - dir * if leg + 1 < legs { r } else { 0.0 })
            })
            .collect();
        // Supports go first, so a compartment whose budget runs out inside
        // this leg ends on the lines, not on supports the lines never get.
        if horizontal {
            let other = 1 - axis;
            let across: Vec<f64> = lines.iter().map(|l| l[leg][other]).collect();
            let (lo, hi) =
                across.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &c| (lo.min(c), hi.max(c)));
            let (from, to) =
                stretches.iter().fold((f64::NEG_INFINITY, f64::INFINITY), |(from, to), (a, b)| {
                    (from.max(a[axis].min(b[axis])), to.min(a[axis].max(b[axis])))
                });
            // The beam reaches past the outer flanges, so the posts clear them.
            let reach = 1.2 * class.diameter;
            let size = class.support_size();
            let beam_top = snap(lines[0][leg].z - class.radius() - size / 2.0);
            for station in stations(from, to, class.support_step()) {
                // Supports bring the average down: placed when over target,
                // and now and then anyway so no long run hangs free.
                if em.deficit() < 0.0 || rng.chance(0.15) {
                    let span = (lo - reach, hi + reach);
                    let s = Support { axis, station: snap(station), span, beam_top, size, shoes: &across };
                    support(room, s, em)?;
                }
            }
        }
        for (line, &(a, b)) in lines.iter().zip(&stretches) {
            spools(&bore, a, dir, (b - a).dot(&dir), horizontal, rng, em)?;
            if leg + 1 < legs {
                let mut elbow = Part::default();
                elbow.bend(&bore.pipe, line[leg + 1], dir, direction(line, leg + 1), r, class.bend_segments);
                em.emit("elbow", elbow)?;
            }
        }
    }
    Ok(())
}

/// A pipe class with its two cross-sections, built once per bundle.
struct Bore {
    class: PipeClass,
    pipe: Section,
    flange: Section,
}

/// One line's straight stretch of `length` from `start` along `dir`: spools
/// of at most [`PipeClass::spool`] with a flange at each joint, and on a
/// horizontal stretch perhaps a valve, when the triangle count is short.
fn spools(
    bore: &Bore,
    start: Point,
    dir: Vector,
    length: f64,
    horizontal: bool,
    rng: &mut Rng,
    em: &mut Emitter,
) -> io::Result<()> {
    let class = bore.class;
    let d = class.diameter;
    let lv = valve_length(d);
    let mut stretches = vec![(0.0, length)];
    let mut valve = None;
    if horizontal && length >= lv + 2.0 * d {
        let t = snap(rng.range(d + lv / 2.0, length - d - lv / 2.0));
        let mut v = Part::default();
        v.valve(start + dir * t, dir, Vector::z(), d, class.sides);
        // The odds grow with the shortfall from nothing at half a valve's
        // triangles to certain at a whole valve's, so a valve never leaves
        // the scene further off its target than it found it; and none while
        // plain pipe of this class already runs above the wanted average,
        // as the rest of the bundle will.
        let valve_triangles = v.triangle_count() as f64;
        let short = em.deficit() > (0.5 + 0.5 * rng.unit()) * valve_triangles;
        if short && em.wanted_average() >= class.typical_triangles() {
            stretches = vec![(0.0, t - lv / 2.0), (t + lv / 2.0, length)];
            valve = Some(v);
        }
    }
    let up = if horizontal { Vector::z() } else { Vector::x() };
    for (k, &(s, e)) in stretches.iter().enumerate() {
        if k == 1 {
            em.emit("valve", valve.take().expect("a valve splits the stretch in two"))?;
        }
        for (a, b) in pieces(s, e, class.spool()) {
            let mut p = Part::default();
            p.prism(&bore.pipe, start + dir * a, dir, up, b - a);
            em.emit("pipe", p)?;
            if b < e {
                let mut f = Part::default();
                f.prism(&bore.flange, start + dir * (b - 0.1 * d), dir, up, 0.2 * d);
                em.emit("flange", f)?;
            }
        }
    }
    Ok(())
}

/// A support across lines (or a tray) running along horizontal `axis`:
/// a beam at `station` whose top is at `beam_top`, spanning `span` on the
/// other horizontal axis, a post from each end of the beam to the room's
/// hang height (a trapeze hanger, or a goal post on a skid), and a shoe
/// from the beam up to each line centred at `shoes`.
struct Support<'a> {
    axis: usize,
    station: f64,
    span: (f64, f64),
    beam_top: f64,
    size: f64,
    shoes: &'a [f64],
}

fn support(room: &Room, s: Support, em: &mut Emitter) -> io::Result<()> {
    let other = 1 - s.axis;
    let along = (s.station - s.size / 2.0, s.station + s.size / 2.0);
    let block = |across: (f64, f64), z: (f64, f64)| {
        let (mut lo, mut hi) = (Point::new(0.0, 0.0, z.0), Point::new(0.0, 0.0, z.1));
        (lo[s.axis], hi[s.axis], lo[other], hi[other]) = (along.0, along.1, across.0, across.1);
        cuboid(lo, hi)
    };
    let beam_bottom = s.beam_top - s.size;
    em.emit("support", block(s.span, (beam_bottom, s.beam_top)))?;
    let post = if room.hang_z > s.beam_top { (s.beam_top, room.hang_z) } else { (room.hang_z, beam_bottom) };
    em.emit("support", block((s.span.0, s.span.0 + s.size), post))?;
    em.emit("support", block((s.span.1 - s.size, s.span.1), post))?;
    for &c in s.shoes {
        em.emit(
            "shoe",
            block((c - s.size / 2.0, c + s.size / 2.0), (s.beam_top, s.beam_top + s.size / 2.0)),
        )?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pipe_classes_grow_in_size_and_triangles() {
        for w in PIPES.windows(2) {
            assert!(w[0].diameter < w[1].diameter);
            assert!(w[0].typical_triangles() < w[1].typical_triangles());
        }
    }

    #[test]
    fn class_choice_brackets_the_wanted_average() {
        let mut rng = Rng::new(3);
        let want = (PIPES[2].typical_triangles() + PIPES[3].typical_triangles()) / 2.0;
        let picks: Vec<usize> = (0..1000).map(|_| choose_class(&PIPES, want, &mut rng)).collect();
        assert!(picks.iter().all(|&c| c == 2 || c == 3));
        let ups = picks.iter().filter(|&&c| c == 3).count();
        assert!((400..600).contains(&ups), "{ups} of 1000 picked the larger class");
        assert_eq!(choose_class(&PIPES, 1.0, &mut rng), 0);
        assert_eq!(choose_class(&PIPES, 1e9, &mut rng), PIPES.len() - 1);
    }
}
