//! What a cut method implements, and what it builds with: the
//! [`Splitter`] that divides a node's objects in two (MOA1's and LAA1's
//! `wDivideList`, §3.1-3.2, and the reference methods), and the build's
//! [`Ctx`]. `driver.rs` grows the tree with them.

use super::leaf::Leaf;
use super::progress::Meter;
use super::{Order, Split, TieBreak, signed_intersection};
use crate::geom::{Aabb, Axis};

/// What every method needs while it builds. Objects are numbered
/// locally (0..N in Hilbert order): local object j is input object
/// `ids[j]`, has box `boxes[j]`, and every tie between objects is broken
/// by input id, so the tree does not depend on the numbering.
pub(crate) struct Ctx<'a> {
    pub(crate) boxes: &'a [Aabb],
    pub(crate) ids: &'a [u32],
    pub(crate) leaf: Leaf<'a>,
    /// `rate` (R).
    pub(crate) rate: f64,
    pub(crate) tie: TieBreak,
    pub(crate) meter: Meter<'a>,
}

impl Ctx<'_> {
    /// R(S) of the objects: the union of their boxes.
    pub(crate) fn aabb_of(&self, objects: &[u32]) -> Aabb {
        objects.iter().fold(Aabb::EMPTY, |b, &j| b.union(&self.boxes[j as usize]))
    }

    /// The split record of a reference method that divided a node into
    /// `left` and `right`: the signed intersection of the children's boxes
    /// on `axis`, or, without an axis, on the axis where it is least (the
    /// first on ties).
    pub(crate) fn split_between(&self, left: &[u32], right: &[u32], axis: Option<Axis>) -> Split {
        self.split_of(&self.aabb_of(left), &self.aabb_of(right), axis)
    }

    /// [`Ctx::split_between`] of children with boxes `l` and `r`.
    pub(crate) fn split_of(&self, l: &Aabb, r: &Aabb, axis: Option<Axis>) -> Split {
        let axes = axis.as_ref().map_or(&Axis::ALL[..], std::slice::from_ref);
        let (axis, gap) = axes
            .iter()
            .map(|&a| (a, signed_intersection(l, r, a)))
            .fold((Axis::X, f64::INFINITY), |best, c| if c.1 < best.1 { c } else { best });
        Split { axis, order: Order::Center, overlap: if gap > 0.0 { gap } else { 0.0 }, gap }
    }
}

/// How a method divides a node that does not fit a page.
pub(crate) trait Splitter: Sync {
    /// The method's view of a node's objects.
    type Set: Send;
    /// The objects of `set`, in any order.
    fn objects<'s>(&self, set: &'s Self::Set) -> &'s [u32];
    /// R(S_n) of `set`: the union of its objects' boxes.
    fn aabb(&self, ctx: &Ctx<'_>, set: &Self::Set) -> Aabb {
        ctx.aabb_of(self.objects(set))
    }
    /// Divides `set` (at least two objects) into two non-empty parts,
    /// first the left; `aabb` is the node's box.
    fn split(&self, set: Self::Set, aabb: &Aabb) -> (Self::Set, Self::Set, Split);
}
