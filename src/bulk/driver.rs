//! `build`: checks the input, then grows the tree top-down with the chosen
//! method — `generate_tree` and `wDivideList` of MOA1 (§3.1) and LAA1
//! (§3.2), shared by every method: a node that fits a page is a leaf,
//! any other is divided in two by the method's [`Splitter`].
//!
//! Inside a build, objects are renumbered along the Hilbert curve of their
//! centres so that a node's objects are close in memory (about a third
//! less time on random scenes); every tie is still broken by input id, so
//! the numbering never shows in the tree.

use super::cost::CostModel;
use super::cut::Keys;
use super::estimate_work;
use super::hierarchy::node_id;
use super::hilbert::{self, Hilbert};
use super::laa::Laa;
use super::leaf::Leaf;
use super::median::Median;
use super::moa::Moa;
use super::progress::Meter;
use super::refine::{Refine, Scoped};
use super::sah::{Heuristic, Sah};
use super::splitter::{Ctx, Splitter};
use super::walk::{Walk, walk};
use super::{BuildError, BuildParams, BuildProgress, Hierarchy, Method, Node, NodeId, NodeKind};
use crate::geom::Aabb;
use crate::scene::ObjectId;

/// The most objects a build takes: its fewer than 2 N nodes keep u32 ids.
const MAX_OBJECTS: usize = 1 << 31;

/// Builds the hierarchy of the objects with boxes `boxes` (object j has id
/// j), with per-object byte sizes `sizes` for [`LeafRule::Bytes`]
/// (see [`object_bytes`]).
///
/// `progress` is called at the start, then periodically (as leaves are
/// emitted and as work is done, possibly from several threads at once:
/// hence `Sync`), and once at the end with every object placed. The tree is the same for
/// any number of rayon threads; run it in a `ThreadPool::install` to choose
/// them.
///
/// ```
/// use mktree::bulk::{BuildParams, LeafRule, Method, build};
/// use mktree::geom::Aabb;
///
/// let boxes: Vec<Aabb> = (0..50)
///     .map(|i| Aabb::from_array([i as f64, 0.0, 0.0, i as f64 + 0.5, 1.0, 1.0]))
///     .collect();
/// let params = BuildParams { method: Method::Moa, leaf: LeafRule::Objects(10), ..BuildParams::paper() };
/// let tree = build(&boxes, None, &params, &|_| {})?;
/// tree.validate(&boxes, None, &params)?;
/// assert!(tree.leaves().all(|(_, objects)| objects.len() <= 10));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// [`LeafRule::Bytes`]: super::LeafRule::Bytes
/// [`object_bytes`]: super::object_bytes
pub fn build(
    boxes: &[Aabb],
    sizes: Option<&[u64]>,
    params: &BuildParams,
    progress: &(dyn Fn(BuildProgress) + Sync),
) -> Result<Hierarchy, BuildError> {
    check_input(boxes, sizes, params)?;
    let ids = hilbert::curve_order(boxes);
    let local = Local::new(boxes, sizes, &ids, params);
    grow_all(local, ids, params, progress)
}

/// [`build`] of boxes and sizes the caller gives up: they are freed once
/// renumbered, before the tree grows (a bulk load of 10^7 objects keeps
/// 560 MB less).
pub(crate) fn build_owned(
    boxes: Vec<Aabb>,
    sizes: Option<Vec<u64>>,
    params: &BuildParams,
    progress: &(dyn Fn(BuildProgress) + Sync),
) -> Result<Hierarchy, BuildError> {
    check_input(&boxes, sizes.as_deref(), params)?;
    let ids = hilbert::curve_order(&boxes);
    let local = Local::new(&boxes, sizes.as_deref(), &ids, params);
    drop((boxes, sizes));
    grow_all(local, ids, params, progress)
}

/// What a build needs of its input once objects are renumbered along the
/// Hilbert curve of their centres, so that a node's objects sit close
/// together in memory: local object j is input object `ids[j]`.
struct Local {
    boxes: Vec<Aabb>,
    sizes: Option<Vec<u64>>,
    /// Refine's cost model, of the input's boxes.
    model: Option<CostModel>,
    /// The estimated object visits.
    work: f64,
}

impl Local {
    fn new(boxes: &[Aabb], sizes: Option<&[u64]>, ids: &[u32], params: &BuildParams) -> Local {
        Local {
            boxes: ids.iter().map(|&j| boxes[j as usize]).collect(),
            sizes: sizes.map(|s| ids.iter().map(|&j| s[j as usize]).collect()),
            model: (params.method == Method::Refine).then(|| CostModel::of_boxes(boxes, params.query_extent)),
            work: estimate_work(boxes.len(), sizes, params),
        }
    }
}

/// Grows the tree of checked, renumbered objects with the method of `params`.
fn grow_all(
    local: Local,
    ids: Vec<u32>,
    params: &BuildParams,
    progress: &(dyn Fn(BuildProgress) + Sync),
) -> Result<Hierarchy, BuildError> {
    let n = local.boxes.len();
    let ctx = Ctx {
        boxes: &local.boxes,
        ids: &ids,
        leaf: Leaf::new(params.leaf, local.sizes.as_deref())?,
        rate: params.rate,
        tie: params.tie_break,
        meter: Meter::new(progress, n, local.work),
    };
    let nodes = match params.method {
        Method::Moa | Method::Laa | Method::Refine => {
            let keys = Keys::new(&local.boxes, &ids);
            let lists = keys.sorted_lists();
            match (params.method, local.model) {
                (Method::Laa, _) => grow(&ctx, &Laa::new(&ctx, &keys, params.look_ahead), lists),
                (Method::Refine, Some(model)) => {
                    grow(&ctx, &Refine::new(&ctx, &keys, model), Scoped::root(lists))
                }
                _ => grow(&ctx, &Moa::new(&ctx, &keys), lists),
            }
        }
        Method::Median => grow(&ctx, &Median::new(&ctx), (0..n as u32).collect()),
        // Local numbering is already the curve's order.
        Method::Hilbert => grow(&ctx, &Hilbert::new(&ctx), (0..n as u32).collect()),
        Method::Sah => grow(&ctx, &Sah::new(&ctx, Heuristic::Area), (0..n as u32).collect()),
        Method::Vsah => grow(&ctx, &Sah::new(&ctx, Heuristic::Volume), (0..n as u32).collect()),
    };
    ctx.meter.finish();
    Ok(Hierarchy { nodes })
}

/// Checks options and input together; returns the leaf test.
pub(crate) fn check_input<'a>(
    boxes: &[Aabb],
    sizes: Option<&'a [u64]>,
    params: &BuildParams,
) -> Result<Leaf<'a>, BuildError> {
    params.validate()?;
    if boxes.is_empty() {
        return Err(BuildError::EmptyInput);
    }
    if boxes.len() > MAX_OBJECTS {
        return Err(BuildError::TooManyObjects { objects: boxes.len(), max: MAX_OBJECTS });
    }
    for (j, b) in boxes.iter().enumerate() {
        let object = ObjectId(j as u32);
        if !b.min.iter().chain(b.max.iter()).all(|c| c.is_finite()) {
            return Err(BuildError::NonFiniteBox { object });
        }
        if b.is_empty() {
            return Err(BuildError::InvertedBox { object });
        }
    }
    if let Some(s) = sizes.filter(|s| s.len() != boxes.len()) {
        return Err(BuildError::SizesMismatch { boxes: boxes.len(), sizes: s.len() });
    }
    Leaf::new(params.leaf, sizes)
}

/// The tree grown by `splitter` from `set`, in preorder.
pub(super) fn grow<S: Splitter>(ctx: &Ctx<'_>, splitter: &S, set: S::Set) -> Vec<Node> {
    walk(&Grower { ctx, splitter }, set, 0)
}

/// A [`Walk`] that emits the nodes of the real tree.
struct Grower<'a, S> {
    ctx: &'a Ctx<'a>,
    splitter: &'a S,
}

impl<S: Splitter> Walk for Grower<'_, S> {
    type Set = S::Set;
    type Out = Vec<Node>;
    /// The index of the internal node whose right child is pending.
    type Mark = usize;

    fn len(&self, set: &S::Set) -> usize {
        self.splitter.objects(set).len()
    }

    fn start(&self) -> Vec<Node> {
        Vec::new()
    }

    fn visit(&self, set: S::Set, level: u32, out: &mut Vec<Node>) -> Option<(S::Set, S::Set, usize)> {
        let aabb = self.splitter.aabb(self.ctx, &set);
        let objects = self.splitter.objects(&set);
        if self.ctx.leaf.fits(objects) {
            let mut ids: Vec<ObjectId> =
                objects.iter().map(|&j| ObjectId(self.ctx.ids[j as usize])).collect();
            ids.sort_unstable();
            self.ctx.meter.placed(ids.len());
            out.push(Node { aabb, level, kind: NodeKind::Leaf { objects: ids } });
            return None;
        }
        self.ctx.meter.worked(objects.len());
        let (left, right, split) = self.splitter.split(set, &aabb);
        let me = out.len();
        // The right child's id is known once the left subtree is out.
        let children = [node_id(me + 1), NodeId(u32::MAX)];
        out.push(Node { aabb, level, kind: NodeKind::Internal { children, split } });
        Some((left, right, me))
    }

    fn right_begins(&self, out: &mut Vec<Node>, parent: usize) {
        let right = node_id(out.len());
        if let NodeKind::Internal { children, .. } = &mut out[parent].kind {
            children[1] = right;
        }
    }

    fn splice(&self, out: &mut Vec<Node>, parent: usize, left: Vec<Node>, right: Vec<Node>) {
        let base = out.len();
        let right_base = base + left.len();
        if let NodeKind::Internal { children, .. } = &mut out[parent].kind {
            *children = [node_id(base), node_id(right_base)];
        }
        for (shift, nodes) in [(base, left), (right_base, right)] {
            out.extend(nodes.into_iter().map(|mut n| {
                if let NodeKind::Internal { children, .. } = &mut n.kind {
                    *children = children.map(|c| node_id(c.index() + shift));
                }
                n
            }));
        }
    }
}
