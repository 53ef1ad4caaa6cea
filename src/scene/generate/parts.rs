//! Mesh primitives: a 2D cross-section swept along a path of frames.
//!
//! One builder, [`Part::sweep`], makes every solid in a generated scene:
//! pipes and equipment shells are n-gon prisms, plates and boxes are
//! rectangle prisms, stiffeners are I/L/T prisms, cable trays are channel
//! prisms, elbows sweep an n-gon around a quarter circle and handwheels
//! around a full one. An open sweep gets a cap at each end, so every solid
//! is closed with outward-facing triangles.
//!
//! Every vertex is snapped to a 1/16 mm grid. Why: grid values and their
//! differences are exact in both f64 and the mesh's f32 offsets, so the
//! stored mesh is exactly the generated one, and the OBJ text stays short
//! ("1234.0625", not "1234.0624999999998"). 1/16 mm is far below any
//! modelled feature, so snapping cannot fold a triangle flat.

use super::trig::cos_sin;
use crate::geom::{Point, Vector};

/// Grid steps per millimetre; a power of two, so snapping is exact.
const GRID_PER_MM: f64 = 16.0;

/// `x` rounded to the generator's 1/16 mm grid.
pub(crate) fn snap(x: f64) -> f64 {
    (x * GRID_PER_MM).round() / GRID_PER_MM
}

/// A closed cross-section: a simple polygon, counter-clockwise in its (u, v)
/// plane, with the triangles that fill it (used for the end caps).
#[derive(Debug, Clone)]
pub(crate) struct Section {
    outline: Vec<[f64; 2]>,
    cap: Vec<[u32; 3]>,
}

impl Section {
    /// A regular polygon of `sides` corners at `radius` around the origin,
    /// rotated half a side so a square has axis-aligned edges.
    pub(crate) fn ngon(sides: u32, radius: f64) -> Section {
        let outline = (0..sides)
            .map(|k| {
                let (c, s) = cos_sin((f64::from(k) + 0.5) / f64::from(sides));
                [radius * c, radius * s]
            })
            .collect();
        Section::from_outline(outline)
    }

    /// A `width` (u) by `height` (v) rectangle centred on the origin.
    pub(crate) fn rect(width: f64, height: f64) -> Section {
        let (w, h) = (width / 2.0, height / 2.0);
        Section::from_outline(vec![[-w, -h], [w, -h], [w, h], [-w, h]])
    }

    /// An I section (rolled beam or pillar): flanges of `width` x `flange`
    /// at v = 0 and v = `depth`, a web of thickness `web` between them,
    /// symmetric about u = 0.
    pub(crate) fn i_beam(depth: f64, width: f64, web: f64, flange: f64) -> Section {
        let (b, w, d, f) = (width / 2.0, web / 2.0, depth, flange);
        Section::from_outline(vec![
            [-b, 0.0],
            [b, 0.0],
            [b, f],
            [w, f],
            [w, d - f],
            [b, d - f],
            [b, d],
            [-b, d],
            [-b, d - f],
            [-w, d - f],
            [-w, f],
            [-b, f],
        ])
    }

    /// An L section (angle stiffener) welded to a plate at v = 0: a web of
    /// thickness `thickness` up to `depth`, and a flange of `width` at its
    /// free end, towards +u.
    pub(crate) fn angle(depth: f64, width: f64, thickness: f64) -> Section {
        let (d, w, t) = (depth, width, thickness);
        Section::from_outline(vec![[0.0, 0.0], [t, 0.0], [t, d - t], [w, d - t], [w, d], [0.0, d]])
    }

    /// A T section (web frame, girder) welded to a plate at v = 0: a web of
    /// thickness `web` up to `depth` and a flange of `width` x `flange` on top.
    pub(crate) fn tee(depth: f64, width: f64, web: f64, flange: f64) -> Section {
        let (b, w, d, f) = (width / 2.0, web / 2.0, depth, flange);
        Section::from_outline(vec![
            [-w, 0.0],
            [w, 0.0],
            [w, d - f],
            [b, d - f],
            [b, d],
            [-b, d],
            [-b, d - f],
            [-w, d - f],
        ])
    }

    /// A U section (cable tray) open towards +v: a floor of `width` at v = 0
    /// and two sides of `depth`, all of `thickness`.
    pub(crate) fn channel(width: f64, depth: f64, thickness: f64) -> Section {
        let (b, d, t) = (width / 2.0, depth, thickness);
        Section::from_outline(vec![
            [-b, 0.0],
            [b, 0.0],
            [b, d],
            [b - t, d],
            [b - t, t],
            [-b + t, t],
            [-b + t, d],
            [-b, d],
        ])
    }

    fn from_outline(outline: Vec<[f64; 2]>) -> Section {
        let cap = ear_clip(&outline);
        Section { outline, cap }
    }

    /// Corners of the outline.
    pub(crate) fn corners(&self) -> u32 {
        self.outline.len() as u32
    }
}

/// `(b - a) x (c - a)`: twice the signed area of triangle abc.
fn cross(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
    (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
}

/// Triangulates a simple counter-clockwise polygon by ear clipping. An ear
/// must turn strictly left and hold no other corner, even on its edges, so
/// no triangle is flat. The sections here have at most 12 corners, and the
/// cap is built once per section, so O(n^3) costs nothing.
fn ear_clip(points: &[[f64; 2]]) -> Vec<[u32; 3]> {
    let mut ring: Vec<u32> = (0..points.len() as u32).collect();
    let mut triangles = Vec::with_capacity(points.len() - 2);
    let at = |i: u32| points[i as usize];
    while ring.len() > 3 {
        let n = ring.len();
        let corners = |i: usize| (ring[(i + n - 1) % n], ring[i], ring[(i + 1) % n]);
        let ear = (0..n)
            .find(|&i| {
                let (a, b, c) = corners(i);
                cross(at(a), at(b), at(c)) > 0.0
                    && ring.iter().all(|&q| {
                        let p = at(q);
                        [a, b, c].contains(&q)
                            || cross(at(a), at(b), p) < 0.0
                            || cross(at(b), at(c), p) < 0.0
                            || cross(at(c), at(a), p) < 0.0
                    })
            })
            .expect("a simple counter-clockwise polygon always has an ear");
        let (a, b, c) = corners(ear);
        triangles.push([a, b, c]);
        ring.remove(ear);
    }
    triangles.push([ring[0], ring[1], ring[2]]);
    triangles
}

/// Where a section sits in space: its origin, and the world directions of
/// its u and v axes. The sweep runs along u x v.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Frame {
    origin: Point,
    u: Vector,
    v: Vector,
}

impl Frame {
    /// The frame at `origin` facing along the unit `tangent`, with the
    /// section's v axis along the unit `up` (perpendicular to `tangent`).
    fn new(origin: Point, tangent: Vector, up: Vector) -> Frame {
        Frame { origin, u: up.cross(&tangent), v: up }
    }

    /// The world point of section point `q`, on the grid.
    fn place(&self, q: [f64; 2]) -> Point {
        let p = self.origin + self.u * q[0] + self.v * q[1];
        Point::new(snap(p.x), snap(p.y), snap(p.z))
    }
}

/// A mesh under construction: one or more closed solids that become one
/// object.
#[derive(Debug, Clone, Default)]
pub(crate) struct Part {
    pub(crate) vertices: Vec<Point>,
    pub(crate) triangles: Vec<[u32; 3]>,
}

impl Part {
    /// Sweeps `section` through `frames`: one ring of vertices per frame,
    /// quads between consecutive rings (and from the last back to the first
    /// when `closed`), and end caps when open.
    fn sweep(&mut self, section: &Section, frames: &[Frame], closed: bool) {
        let base = self.vertices.len() as u32;
        let n = section.corners();
        let rings = frames.len() as u32;
        for f in frames {
            self.vertices.extend(section.outline.iter().map(|&q| f.place(q)));
        }
        // With u x v along the sweep and the outline counter-clockwise, the
        // quad (a, b, c, d) faces away from the section's inside.
        let spans = if closed { rings } else { rings - 1 };
        for r in 0..spans {
            let (this, next) = (base + r * n, base + (r + 1) % rings * n);
            for k in 0..n {
                let k2 = (k + 1) % n;
                let (a, b, c, d) = (this + k, this + k2, next + k2, next + k);
                self.triangles.push([a, b, c]);
                self.triangles.push([a, c, d]);
            }
        }
        if !closed {
            // The cap triangles face +tangent: reversed at the start, kept at the end.
            let last = base + (rings - 1) * n;
            for t in &section.cap {
                self.triangles.push([base + t[0], base + t[2], base + t[1]]);
                self.triangles.push([last + t[0], last + t[1], last + t[2]]);
            }
        }
    }

    /// A straight prism: `section` from `start` along the unit `along` for
    /// `length`, its v axis along the unit `up`.
    pub(crate) fn prism(&mut self, section: &Section, start: Point, along: Vector, up: Vector, length: f64) {
        let first = Frame::new(start, along, up);
        let second = Frame::new(start + along * length, along, up);
        self.sweep(section, &[first, second], false);
    }

    /// The axis-aligned box between two corners (12 triangles).
    pub(crate) fn cuboid(&mut self, min: Point, max: Point) {
        let e = max - min;
        let start = Point::new(min.x + e.x / 2.0, min.y + e.y / 2.0, min.z);
        self.prism(&Section::rect(e.x, e.y), start, Vector::z(), Vector::y(), e.z);
    }

    /// A swept bend (pipe elbow): `section` turned through a quarter circle
    /// of centreline `radius` in `segments` steps, for a run that meets
    /// `corner` along the unit axis `d_in` and leaves along `d_out`.
    pub(crate) fn bend(
        &mut self,
        section: &Section,
        corner: Point,
        d_in: Vector,
        d_out: Vector,
        radius: f64,
        segments: u32,
    ) {
        let centre = corner + (d_out - d_in) * radius;
        let binormal = d_in.cross(&d_out);
        let frames: Vec<Frame> = (0..=segments)
            .map(|k| {
                let (c, s) = cos_sin(f64::from(k) / f64::from(4 * segments));
                let position = centre + (d_in * s - d_out * c) * radius;
                Frame::new(position, d_in * c + d_out * s, binormal)
            })
            .collect();
        self.sweep(section, &frames, false);
    }

    /// A closed ring (handwheel): `section` swept around a full circle of
    /// `radius` about `centre`, in the plane normal to the unit axis
    /// `normal`; `across` is any unit axis perpendicular to `normal`.
    pub(crate) fn ring(
        &mut self,
        section: &Section,
        centre: Point,
        normal: Vector,
        across: Vector,
        radius: f64,
        segments: u32,
    ) {
        let other = normal.cross(&across);
        let frames: Vec<Frame> = (0..segments)
            .map(|k| {
                let (c, s) = cos_sin(f64::from(k) / f64::from(segments));
                Frame::new(centre + (across * c + other * s) * radius, other * c - across * s, normal)
            })
            .collect();
        self.sweep(section, &frames, true);
    }

    /// A flanged valve on a pipe of `diameter` running along the unit `axis`,
    /// centred at `centre`, its bonnet, stem and handwheel towards the unit
    /// `up`. It is [`valve_length`] long and reaches [`valve_height`] above
    /// the pipe axis.
    pub(crate) fn valve(&mut self, centre: Point, axis: Vector, up: Vector, diameter: f64, sides: u32) {
        let d = diameter;
        let half = valve_length(d) / 2.0;
        let flange = Section::ngon(sides, 0.85 * d);
        let flange_thickness = 0.2 * d;
        self.prism(&flange, centre - axis * half, axis, up, flange_thickness);
        self.prism(
            &Section::ngon(sides, 0.65 * d),
            centre - axis * (half - flange_thickness),
            axis,
            up,
            1.2 * d,
        );
        self.prism(&flange, centre + axis * (half - flange_thickness), axis, up, flange_thickness);
        self.prism(&Section::ngon(sides, 0.35 * d), centre + up * 0.4 * d, up, axis, 0.8 * d);
        let stem = (0.06 * d).max(5.0);
        self.prism(&Section::ngon(6, stem), centre + up * 1.2 * d, up, axis, 0.6 * d);
        let rim = (0.04 * d).max(4.0);
        self.ring(&Section::ngon(4, rim), centre + up * (1.8 * d - rim), up, axis, 0.55 * d + stem, sides);
    }

    /// Triangles so far.
    pub(crate) fn triangle_count(&self) -> usize {
        self.triangles.len()
    }
}

/// Flange face to flange face of a valve on a pipe of `diameter`.
pub(crate) fn valve_length(diameter: f64) -> f64 {
    1.6 * diameter
}

/// How far a valve reaches above its pipe's axis (the handwheel's top).
pub(crate) fn valve_height(diameter: f64) -> f64 {
    1.8 * diameter
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeMap;

    fn area(points: &[[f64; 2]]) -> f64 {
        (0..points.len()).map(|i| cross([0.0, 0.0], points[i], points[(i + 1) % points.len()])).sum::<f64>()
            / 2.0
    }

    fn sections() -> Vec<Section> {
        vec![
            Section::ngon(3, 100.0),
            Section::ngon(6, 25.0),
            Section::ngon(24, 900.0),
            Section::rect(100.0, 12.0),
            Section::i_beam(300.0, 150.0, 8.0, 12.0),
            Section::angle(150.0, 90.0, 10.0),
            Section::tee(450.0, 150.0, 10.0, 15.0),
            Section::channel(400.0, 100.0, 3.0),
        ]
    }

    #[test]
    fn caps_tile_every_section_with_no_flat_triangle() {
        for s in sections() {
            let o = &s.outline;
            assert!(area(o) > 0.0, "outlines are counter-clockwise");
            assert_eq!(s.cap.len(), o.len() - 2);
            let mut sum = 0.0;
            for t in &s.cap {
                let a = cross(o[t[0] as usize], o[t[1] as usize], o[t[2] as usize]);
                assert!(a > 0.0, "cap triangle {t:?} is flat or flipped");
                sum += a / 2.0;
            }
            assert!((sum - area(o)).abs() < 1e-9 * area(o));
        }
    }

    /// Every edge of a closed, consistently oriented mesh is used once in
    /// each direction.
    fn assert_closed_and_oriented(part: &Part) {
        let mut edges: BTreeMap<(u32, u32), i32> = BTreeMap::new();
        for t in &part.triangles {
            for i in 0..3 {
                *edges.entry((t[i], t[(i + 1) % 3])).or_default() += 1;
            }
        }
        for (&(a, b), &n) in &edges {
            assert_eq!(n, 1, "edge {a}-{b} used {n} times");
            assert_eq!(edges.get(&(b, a)), Some(&1), "edge {a}-{b} has no twin");
        }
    }

    /// The signed volume (divergence theorem): positive when triangles face outwards.
    fn volume(part: &Part) -> f64 {
        part.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| part.vertices[i as usize].coords);
                a.dot(&b.cross(&c)) / 6.0
            })
            .sum()
    }

    #[test]
    fn every_primitive_is_closed_and_faces_outwards() {
        let o = Point::new(1000.0, 2000.0, 3000.0);
        let mut parts = Vec::new();
        let mut p = Part::default();
        p.cuboid(o, Point::new(1100.0, 2050.0, 3010.0));
        parts.push((p, 12, 100.0 * 50.0 * 10.0));
        for s in sections() {
            let mut p = Part::default();
            p.prism(&s, o, -Vector::y(), Vector::x(), 500.0);
            let expected = 500.0 * area(&s.outline);
            parts.push((p, 2 * s.outline.len() + 2 * s.cap.len(), expected));
        }
        for (part, triangles, expected) in &parts {
            assert_eq!(part.triangle_count(), *triangles);
            assert_closed_and_oriented(part);
            // Snapping moves each corner by at most half a grid step.
            assert!((volume(part) - expected).abs() < 1e-2 * expected, "{} vs {expected}", volume(part));
        }
        let mut elbow = Part::default();
        elbow.bend(&Section::ngon(8, 50.0), o, Vector::x(), -Vector::z(), 150.0, 4);
        assert_eq!(elbow.triangle_count(), 2 * 8 * 4 + 2 * 6);
        let mut valve = Part::default();
        valve.valve(o, Vector::y(), Vector::z(), 100.0, 12);
        for part in [&elbow, &valve] {
            assert_closed_and_oriented(part);
            assert!(volume(part) > 0.0);
        }
    }

    #[test]
    fn a_bend_joins_the_runs_it_connects() {
        let corner = Point::new(0.0, 0.0, 0.0);
        let mut p = Part::default();
        p.bend(&Section::ngon(4, 10.0), corner, Vector::x(), Vector::y(), 100.0, 3);
        // First ring centred 100 mm before the corner on x, last 100 mm after it on y.
        let centre = |ring: usize| {
            p.vertices[ring * 4..ring * 4 + 4].iter().fold(Vector::zeros(), |s, v| s + v.coords) / 4.0
        };
        assert!((centre(0) - Vector::new(-100.0, 0.0, 0.0)).norm() < 0.1);
        assert!((centre(3) - Vector::new(0.0, 100.0, 0.0)).norm() < 0.1);
    }

    #[test]
    fn valve_stays_within_its_documented_size() {
        let mut p = Part::default();
        let d = 200.0;
        p.valve(Point::origin(), Vector::x(), Vector::z(), d, 16);
        let b = crate::geom::Aabb::from_points(&p.vertices);
        assert!((b.max.x - valve_length(d) / 2.0).abs() < 0.1);
        assert!(b.max.z <= valve_height(d) + 0.1 && b.max.z > 0.9 * valve_height(d));
    }

    #[test]
    fn snapping_is_exact_on_the_grid() {
        assert_eq!(snap(1234.0625), 1234.0625);
        assert_eq!(snap(0.03), 0.0);
        assert_eq!(snap(-7.97), -8.0);
    }
}
