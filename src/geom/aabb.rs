//! Axis-aligned bounding boxes, R(S) in the paper (Definition 1.2.2).

use super::{Axis, Point, Vector, round_down_f32, round_up_f32};

/// An axis-aligned box in world millimetres. `Aabb::EMPTY` (min = +inf,
/// max = -inf) is the identity of [`Aabb::union`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aabb {
    /// The lower corner, mm.
    pub min: Point,
    /// The upper corner, mm.
    pub max: Point,
}

/// The lesser of `a` and `b` on each axis, `a`'s on ties (a signed zero
/// keeps `a`'s sign, as nalgebra's `inf` does) and where `b` is NaN. The
/// comparison is written `b < a` so that it compiles to one `minsd`
/// (x86's takes its second operand on ties and NaN): the build unions
/// boxes per object per tree level. Meshes hold no NaN (`MeshError`).
fn lower(a: &Point, b: &Point) -> Point {
    let min = |a: f64, b: f64| if b < a { b } else { a };
    Point::new(min(a.x, b.x), min(a.y, b.y), min(a.z, b.z))
}

/// The greater of `a` and `b` on each axis, as [`lower`] the lesser.
fn upper(a: &Point, b: &Point) -> Point {
    let max = |a: f64, b: f64| if b > a { b } else { a };
    Point::new(max(a.x, b.x), max(a.y, b.y), max(a.z, b.z))
}

impl Aabb {
    /// The empty box: contains nothing, unions to the other operand.
    pub const EMPTY: Aabb = Aabb {
        min: Point::new(f64::INFINITY, f64::INFINITY, f64::INFINITY),
        max: Point::new(f64::NEG_INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY),
    };

    /// The box with corners `min` and `max` (not checked: `min <= max` is the caller's to keep).
    pub fn new(min: Point, max: Point) -> Aabb {
        Aabb { min, max }
    }

    /// The box from six numbers `[x0, y0, z0, x1, y1, z1]`.
    pub fn from_array(a: [f64; 6]) -> Aabb {
        Aabb::new(Point::new(a[0], a[1], a[2]), Point::new(a[3], a[4], a[5]))
    }

    /// `[x0, y0, z0, x1, y1, z1]`.
    pub fn to_array(&self) -> [f64; 6] {
        [self.min.x, self.min.y, self.min.z, self.max.x, self.max.y, self.max.z]
    }

    /// The smallest box holding every point (EMPTY for none).
    pub fn from_points<'a>(points: impl IntoIterator<Item = &'a Point>) -> Aabb {
        points.into_iter().fold(Aabb::EMPTY, |b, p| b.including(p))
    }

    /// True when the box holds no point.
    pub fn is_empty(&self) -> bool {
        (0..3).any(|i| self.min[i] > self.max[i])
    }

    /// This box grown to hold `p`.
    pub fn including(&self, p: &Point) -> Aabb {
        Aabb::new(lower(&self.min, p), upper(&self.max, p))
    }

    /// The smallest box holding both.
    pub fn union(&self, other: &Aabb) -> Aabb {
        Aabb::new(lower(&self.min, &other.min), upper(&self.max, &other.max))
    }

    /// The eight corners.
    pub fn corners(&self) -> [Point; 8] {
        std::array::from_fn(|i| {
            Point::new(
                if i & 1 == 0 { self.min.x } else { self.max.x },
                if i & 2 == 0 { self.min.y } else { self.max.y },
                if i & 4 == 0 { self.min.z } else { self.max.z },
            )
        })
    }

    /// The box grown by `d` on every side.
    pub fn grown(&self, d: f64) -> Aabb {
        let v = Vector::repeat(d);
        Aabb::new(self.min - v, self.max + v)
    }

    /// Side lengths (zero for an empty box).
    pub fn extent(&self) -> Vector {
        if self.is_empty() { Vector::zeros() } else { self.max - self.min }
    }

    /// Side length along one axis.
    pub fn extent_on(&self, axis: Axis) -> f64 {
        self.extent()[axis.index()]
    }

    /// The centre point.
    pub fn center(&self) -> Point {
        nalgebra::center(&self.min, &self.max)
    }

    /// Volume in mm^3 (zero for an empty or flat box).
    pub fn volume(&self) -> f64 {
        let e = self.extent();
        e.x * e.y * e.z
    }

    /// Surface area in mm^2.
    pub fn surface_area(&self) -> f64 {
        let e = self.extent();
        2.0 * (e.x * e.y + e.y * e.z + e.z * e.x)
    }

    /// The axis with the longest side (x on ties).
    pub fn longest_axis(&self) -> Axis {
        let e = self.extent();
        let mut best = Axis::X;
        for a in [Axis::Y, Axis::Z] {
            if e[a.index()] > e[best.index()] {
                best = a;
            }
        }
        best
    }

    /// True when the closed boxes share a point (touching boxes do).
    pub fn intersects(&self, other: &Aabb) -> bool {
        (0..3).all(|i| self.min[i] <= other.max[i] && other.min[i] <= self.max[i])
    }

    /// True when the gap between the boxes is at most `d` on every axis (with
    /// `d` = 0, exactly [`Aabb::intersects`]). The same for `a.within(b)` and
    /// `b.within(a)`, bit for bit, unlike growing one of them by `d`; and a
    /// larger box is within whenever a box it holds is.
    pub fn within(&self, other: &Aabb, d: f64) -> bool {
        (0..3).all(|i| (self.min[i] - other.max[i]).max(other.min[i] - self.max[i]) <= d)
    }

    /// True when `other` lies inside this closed box.
    pub fn contains(&self, other: &Aabb) -> bool {
        other.is_empty() || (0..3).all(|i| self.min[i] <= other.min[i] && other.max[i] <= self.max[i])
    }

    /// True when the point lies in the closed box.
    pub fn contains_point(&self, p: &Point) -> bool {
        (0..3).all(|i| self.min[i] <= p[i] && p[i] <= self.max[i])
    }

    /// xOverlap / yOverlap / zOverlap (Definition 1.2.3): the length of the
    /// intersection of the two projections on `axis`, zero when they are apart.
    pub fn overlap_on(&self, other: &Aabb, axis: Axis) -> f64 {
        let i = axis.index();
        (self.max[i].min(other.max[i]) - self.min[i].max(other.min[i])).max(0.0)
    }

    /// The f32 box that contains this one: lower corner rounded down, upper
    /// corner rounded up, so storing it never loses containment.
    pub fn to_f32_outward(&self) -> ([f32; 3], [f32; 3]) {
        (
            [round_down_f32(self.min.x), round_down_f32(self.min.y), round_down_f32(self.min.z)],
            [round_up_f32(self.max.x), round_up_f32(self.max.y), round_up_f32(self.max.z)],
        )
    }

    /// The box back from its f32 corners (exact: every f32 is an f64).
    pub fn from_f32(min: [f32; 3], max: [f32; 3]) -> Aabb {
        let p = |a: [f32; 3]| Point::new(a[0].into(), a[1].into(), a[2].into());
        Aabb::new(p(min), p(max))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn b(a: [f64; 6]) -> Aabb {
        Aabb::from_array(a)
    }

    #[test]
    fn empty_is_the_identity_of_union() {
        let x = b([0.0, 1.0, 2.0, 3.0, 4.0, 5.0]);
        assert_eq!(Aabb::EMPTY.union(&x), x);
        assert!(Aabb::EMPTY.is_empty());
        assert_eq!(Aabb::EMPTY.volume(), 0.0);
    }

    #[test]
    fn overlap_is_the_length_of_the_intersection() {
        let a = b([0.0, 0.0, 0.0, 10.0, 1.0, 1.0]);
        let c = b([7.0, 0.0, 0.0, 20.0, 1.0, 1.0]);
        assert_eq!(a.overlap_on(&c, Axis::X), 3.0);
        let d = b([12.0, 0.0, 0.0, 20.0, 1.0, 1.0]);
        assert_eq!(a.overlap_on(&d, Axis::X), 0.0);
    }

    #[test]
    fn within_is_symmetric_and_closed() {
        let a = b([0.1, 0.2, 0.3, 0.4, 0.5, 0.6]);
        let touching = b([0.4, 0.5, 0.6, 1.0, 1.0, 1.0]);
        assert!(a.intersects(&touching) && a.within(&touching, 0.0) && touching.within(&a, 0.0));
        let apart = b([0.4f64.next_up(), 0.5, 0.6, 1.0, 1.0, 1.0]);
        assert!(!a.intersects(&apart) && !a.within(&apart, 0.0) && !apart.within(&a, 0.0));
        assert!(a.within(&apart, 1e-15) && apart.within(&a, 1e-15));
        let far = b([0.7, 0.2, 0.3, 0.9, 0.5, 0.6]);
        assert!(!a.within(&far, 0.2) && a.within(&far, 0.3) && far.within(&a, 0.3));
        assert!(!Aabb::EMPTY.within(&a, 1e9) && !a.within(&Aabb::EMPTY, 1e9));
    }

    #[test]
    fn longest_axis_prefers_x_on_ties() {
        assert_eq!(b([0.0; 6]).longest_axis(), Axis::X);
        assert_eq!(b([0.0, 0.0, 0.0, 1.0, 3.0, 2.0]).longest_axis(), Axis::Y);
    }

    proptest! {
        #[test]
        fn f32_outward_box_contains_the_f64_box(
            x0 in -1e7f64..1e7, y0 in -1e7f64..1e7, z0 in -1e7f64..1e7,
            dx in 0f64..1e5, dy in 0f64..1e5, dz in 0f64..1e5,
        ) {
            let a = b([x0, y0, z0, x0 + dx, y0 + dy, z0 + dz]);
            let (lo, hi) = a.to_f32_outward();
            prop_assert!(Aabb::from_f32(lo, hi).contains(&a));
        }

        #[test]
        fn within_is_symmetric_and_intersects_at_zero(
            p in prop::array::uniform6(-10i32..10), q in prop::array::uniform6(-10i32..10), d in 0i32..4,
        ) {
            let sorted = |v: [i32; 6]| {
                let v = v.map(|x| f64::from(x) * 0.1);
                Aabb::from_points(&[Point::new(v[0], v[1], v[2]), Point::new(v[3], v[4], v[5])])
            };
            let (x, y, d) = (sorted(p), sorted(q), f64::from(d) * 0.1);
            prop_assert_eq!(x.within(&y, d), y.within(&x, d));
            prop_assert_eq!(x.within(&y, 0.0), x.intersects(&y));
        }

        #[test]
        fn union_and_including_are_nalgebras_inf_and_sup_bit_for_bit(
            p in prop::array::uniform6(prop::sample::select(vec![-1.5, -0.0, 0.0, 2.0, f64::INFINITY, f64::NEG_INFINITY])),
            q in prop::array::uniform6(prop::sample::select(vec![-1.5, -0.0, 0.0, 2.0, f64::INFINITY, f64::NEG_INFINITY])),
        ) {
            // The build's trees and files depend on these to the bit, signed
            // zeros included, as nalgebra gave them before (NaN aside: meshes
            // hold none, and a NaN of `other` is passed over).
            let (x, y) = (b(p), b(q));
            let bits = |a: Aabb| a.to_array().map(f64::to_bits);
            let reference = Aabb::new(x.min.inf(&y.min), x.max.sup(&y.max));
            prop_assert_eq!(bits(x.union(&y)), bits(reference));
            prop_assert_eq!(bits(x.union(&b([f64::NAN; 6]))), bits(x));
            let reference = Aabb::new(x.min.inf(&y.max), x.max.sup(&y.max));
            prop_assert_eq!(bits(x.including(&y.max)), bits(reference));
        }
    }
}
