//! Which levels of detail a tree stores, and what: the voxel sets of every
//! node and object, computed bottom-up over the hierarchy, and the paper's
//! storage decisions (§1.5) before the writer places the blobs in blocks.
//!
//! Levels for M levels: 1 the AABB, 2 the cuberille (a bitmap, a grid per
//! node within a bit budget), 3 .. M-1 polyhedra (the boundary of a voxel
//! set at a fixed lattice level, stored as boxes), M the exact objects. All
//! grids sit on one lattice, so a level nests in the level below it and a
//! child's set in its parent's (see `lattice.rs`).

use rayon::prelude::*;

use super::{ErrorProbe, Form, Grid, Lattice, LodError, Voxels, encode, encode_objects};
use crate::build::Hierarchy;
use crate::scene::{Mesh, ObjectId, Scene};

/// How a tree's levels of detail are built.
#[derive(Debug, Clone, PartialEq)]
pub struct LodParams {
    /// eps_k of the polyhedral levels k = 3 .. M-1, in mm, coarse to fine
    /// (non-increasing); `None` takes them from the scene's object sizes.
    pub eps: Option<Vec<f64>>,
    /// B(S_n,k) keeps per-object bounds at every node instead of pointing
    /// to b(S_n,k) where that is smaller (the paper's rule).
    pub keep_identity: bool,
    /// Cells of a node's cuberille (level 2).
    pub cuberille_bits: u32,
    /// Cells of an object's cuberille.
    pub cuberille_object_bits: u32,
    /// Cells sampled per bound to measure its error.
    pub error_samples: usize,
}

impl Default for LodParams {
    fn default() -> LodParams {
        LodParams {
            eps: None,
            keep_identity: false,
            cuberille_bits: 4096,
            cuberille_object_bits: 512,
            error_samples: 64,
        }
    }
}

/// The lattice and the lattice level of each level's grids.
#[derive(Debug, Clone, PartialEq)]
pub struct LodPlan {
    /// M.
    pub levels: u8,
    pub lattice: Lattice,
    /// Index k - 1: the lattice level of level k's grids (level 2: the
    /// finest its per-node grids may use); 0 for levels 1 and M.
    pub grid_level: Vec<u8>,
}

/// A root with more triangles than this gets no sampled error (see `errors`).
const MEASURED_TRIANGLES: u64 = 1_000_000;

/// The finest polyhedral cell by default: a quarter of the median object's
/// longest side, so a typical object is a few cells across.
const DEFAULT_CELLS_PER_OBJECT: f64 = 4.0;

impl LodPlan {
    /// The plan for `scene` with M = `levels`.
    pub fn new(scene: &Scene, levels: u8, params: &LodParams) -> Result<LodPlan, LodError> {
        let polyhedral = usize::from(levels.saturating_sub(3));
        let scene_box = scene.aabb();
        let (cell, steps) = match &params.eps {
            Some(eps) => {
                if eps.len() != polyhedral {
                    return Err(LodError::Params(format!(
                        "{} eps values for {polyhedral} polyhedral levels (3 .. M-1 with M = {levels})",
                        eps.len()
                    )));
                }
                if eps.iter().any(|e| !(e.is_finite() && *e > 0.0)) || eps.windows(2).any(|w| w[1] > w[0]) {
                    return Err(LodError::Params(format!(
                        "eps {eps:?} must be positive and not increase with k"
                    )));
                }
                let finest = eps.last().copied().unwrap_or(1.0);
                // A level's error is its cell diagonal: round each cell down to a power-of-two multiple.
                let steps: Vec<u8> =
                    eps.iter().map(|e| (e / finest).log2().floor().clamp(0.0, 60.0) as u8).collect();
                (finest / 3f64.sqrt(), steps)
            }
            None => {
                let mut sides: Vec<f64> =
                    scene.objects().iter().map(|o| longest_side(&o.mesh)).filter(|s| *s > 0.0).collect();
                sides.sort_by(f64::total_cmp);
                let median = sides.get(sides.len() / 2).copied().unwrap_or_else(|| {
                    longest_side_of(&scene_box.extent().into()).max(1.0) // points only
                });
                let steps = (0..polyhedral).map(|i| (polyhedral - 1 - i) as u8).collect();
                (median / DEFAULT_CELLS_PER_OBJECT, steps)
            }
        };
        let mut grid_level = vec![0u8; usize::from(levels)];
        for (i, s) in steps.iter().enumerate() {
            grid_level[3 + i - 1] = *s;
        }
        if levels >= 3 {
            grid_level[1] = if polyhedral > 0 { grid_level[2] } else { 0 };
        }
        Ok(LodPlan { levels, lattice: Lattice { origin: scene_box.min, cell }, grid_level })
    }

    /// Level k's guaranteed error for a grid at its lattice level (k >= 3).
    pub fn eps(&self, k: u8) -> f64 {
        self.lattice.cell_at(self.grid_level[usize::from(k) - 1]) * 3f64.sqrt()
    }
}

fn longest_side(mesh: &Mesh) -> f64 {
    longest_side_of(&mesh.aabb().extent().into())
}

fn longest_side_of(e: &[f64; 3]) -> f64 {
    e[0].max(e[1]).max(e[2])
}

/// One entry (b or B at one level) of a node, before placement.
#[derive(Debug, Clone, PartialEq)]
pub enum Entry {
    /// b(S_n,1): the record's box.
    InRecord,
    /// Bytes to store.
    Blob { bytes: Vec<u8> },
    /// The union of the children's entries at this level.
    Spread,
    /// The same as another entry of the node (resolved: never names a `Same`).
    Same { level: u8, objects: bool },
}

/// A node's entries for k = 1 .. M-1, [b, B] each.
pub type NodeEntries = Vec<[Entry; 2]>;

/// Everything the writer needs: the entries of every node (preorder), and
/// per level k = 1 .. M the guaranteed and the measured error.
#[derive(Debug, Clone)]
pub struct Computed {
    pub plan: LodPlan,
    pub nodes: Vec<NodeEntries>,
    pub eps: Vec<f64>,
    pub measured: Vec<f64>,
}

/// A node's voxel sets for k = 2 .. M-1 (index k - 2); `None` where the
/// grid would be too large to build.
type Sets = Vec<Option<Voxels>>;

/// Before resolution: where an entry points when it is not stored itself.
#[derive(Debug, Clone)]
enum Draft {
    Final(Entry),
    /// Stored no more accurately than the exact objects would be: the next level up.
    Up,
}

/// Computes the levels of detail of `tree` over `scene`; blobs larger than
/// `max_blob` bytes are spread over the children (internal nodes) or stored
/// as runs (leaves).
pub fn compute(
    scene: &Scene,
    tree: &Hierarchy,
    plan: &LodPlan,
    params: &LodParams,
    max_blob: usize,
) -> Result<Computed, LodError> {
    let m = plan.levels;
    let n = tree.nodes.len();
    let levels = usize::from(m.saturating_sub(2)); // voxel levels 2 .. M-1
    let mut sets: Vec<Option<Sets>> = vec![None; n];
    let mut nodes: Vec<NodeEntries> = vec![Vec::new(); n];
    let mut errors = vec![[0f64; 2]; usize::from(m)];
    let triangles = subtree_triangles(scene, tree);
    // Level-synchronous bottom-up: children (one level deeper) are done
    // before their parents, and a depth's nodes are independent.
    let depth = tree.nodes.iter().map(|x| x.level).max().unwrap_or(0);
    for d in (0..=depth).rev() {
        let ids: Vec<usize> = (0..n).filter(|&i| tree.nodes[i].level == d).collect();
        let inputs: Vec<(usize, Option<[Sets; 2]>)> = ids
            .iter()
            .map(|&i| {
                let kids = tree.nodes[i]
                    .children()
                    .map(|c| c.map(|c| sets[c.index()].take().unwrap_or_else(|| vec![None; levels])));
                (i, kids)
            })
            .collect();
        let done: Vec<(usize, Sets, NodeEntries, Vec<[f64; 2]>)> = inputs
            .into_par_iter()
            .map(|(i, kids)| {
                let ctx = NodeCtx { scene, tree, plan, params, max_blob, i, triangles: triangles[i] };
                let (s, e, err) = match kids {
                    None => ctx.leaf()?,
                    Some(kids) => ctx.internal(kids)?,
                };
                Ok((i, s, e, err))
            })
            .collect::<Result<_, LodError>>()?;
        for (i, s, e, err) in done {
            sets[i] = Some(s);
            nodes[i] = e;
            for (acc, x) in errors.iter_mut().zip(err) {
                acc[0] = acc[0].max(x[0]);
                acc[1] = acc[1].max(x[1]);
            }
        }
    }
    // Levels 1 and 2: the largest cell diagonal stored; polyhedral levels:
    // the lattice level's (cells grow by the voxelization's rounding
    // allowance, which the stored diagonals include).
    let mut eps: Vec<f64> = errors.iter().map(|e| e[0]).collect();
    for k in 3..m {
        let e = &mut eps[usize::from(k) - 1];
        *e = e.max(plan.eps(k));
    }
    let measured = errors.iter().map(|e| e[1]).collect();
    Ok(Computed { plan: plan.clone(), nodes, eps, measured })
}

fn subtree_triangles(scene: &Scene, tree: &Hierarchy) -> Vec<u64> {
    let mut t = vec![0u64; tree.nodes.len()];
    for i in (0..tree.nodes.len()).rev() {
        t[i] = match (tree.nodes[i].objects(), tree.nodes[i].children()) {
            (Some(objs), _) => {
                objs.iter().map(|o| scene.objects()[o.index()].mesh.triangle_count() as u64).sum()
            }
            (None, Some(c)) => t[c[0].index()] + t[c[1].index()],
            (None, None) => 0,
        };
    }
    t
}

struct NodeCtx<'a> {
    scene: &'a Scene,
    tree: &'a Hierarchy,
    plan: &'a LodPlan,
    params: &'a LodParams,
    max_blob: usize,
    i: usize,
    triangles: u64,
}

/// (the node's sets, its entries, per level k = 1 .. M: (guaranteed, measured) error).
type NodeOut = (Sets, NodeEntries, Vec<[f64; 2]>);

impl NodeCtx<'_> {
    fn m(&self) -> u8 {
        self.plan.levels
    }

    /// The grid of level `k` over `bounds`; `budget` cells for the cuberille.
    fn grid(&self, k: u8, bounds: &crate::geom::Aabb, budget: u32) -> Result<Option<Grid>, LodError> {
        let level = self.plan.grid_level[usize::from(k) - 1];
        let g = if k == 2 {
            Grid::coarsest_within(&self.plan.lattice, bounds, u64::from(budget), level)
        } else {
            Grid::new(&self.plan.lattice, level, bounds)
        };
        match g {
            Ok(g) => Ok(Some(g)),
            Err(LodError::TooLarge { .. }) => Ok(None),
            Err(e) => Err(e),
        }
    }

    /// A node's group sets from finer sets (its objects' or children's):
    /// level k >= 3 lifts level k of each part, the cuberille lifts the
    /// parts' finest set it can.
    fn lift_group(&self, parts: &[&Sets], mut direct: impl FnMut(Grid) -> Voxels) -> Result<Sets, LodError> {
        let bounds = self.tree.nodes[self.i].aabb;
        let mut out = Vec::new();
        for k in 2..self.m() {
            let Some(grid) = self.grid(k, &bounds, self.params.cuberille_bits)? else {
                out.push(None);
                continue;
            };
            let idx = usize::from(k) - 2;
            let mut v = Voxels::empty(grid.clone());
            let mut complete = true;
            for p in parts {
                // The finest set of this part that the grid can take (k, or for the cuberille any level).
                let src = if k == 2 { p.iter().flatten().last() } else { p[idx].as_ref() };
                match src {
                    Some(s) if s.grid().level() <= grid.level() => s.lift_into(&mut v)?,
                    _ => complete = false,
                }
            }
            if !complete {
                if k == 2 {
                    // The cuberille always exists: voxelize the objects on it directly.
                    v = direct(grid);
                } else {
                    out.push(None);
                    continue;
                }
            }
            out.push(Some(v));
        }
        Ok(out)
    }

    fn objects(&self) -> Vec<(ObjectId, &Mesh)> {
        let tree = self.tree;
        let mut stack = vec![self.i];
        let mut out = Vec::new();
        while let Some(j) = stack.pop() {
            match (tree.nodes[j].objects(), tree.nodes[j].children()) {
                (Some(objs), _) => {
                    out.extend(objs.iter().map(|o| (*o, &self.scene.objects()[o.index()].mesh)))
                }
                (None, Some(c)) => stack.extend(c.iter().map(|c| c.index())),
                (None, None) => {}
            }
        }
        out
    }

    /// An object's sets: the finest level voxelized, coarser ones lifted
    /// from it (so they nest), a level voxelized directly where the finer
    /// grid would be too large.
    fn object_sets(&self, mesh: &Mesh) -> Result<Sets, LodError> {
        let bounds = mesh.aabb();
        let m = self.m();
        let mut out: Vec<Option<Voxels>> = vec![None; usize::from(m.saturating_sub(2))];
        for k in (2..m).rev() {
            let Some(grid) = self.grid(k, &bounds, self.params.cuberille_object_bits)? else { continue };
            let finer = out.get(usize::from(k) - 1).and_then(|v| v.as_ref());
            let v = match finer {
                Some(f) if f.grid().level() <= grid.level() => {
                    let mut v = Voxels::empty(grid);
                    f.lift_into(&mut v)?;
                    v
                }
                _ => Voxels::of_meshes(grid, [mesh]),
            };
            out[usize::from(k) - 2] = Some(v);
        }
        Ok(out)
    }

    fn leaf(&self) -> Result<NodeOut, LodError> {
        let objs = self.objects();
        let per: Vec<Sets> = objs.iter().map(|(_, mesh)| self.object_sets(mesh)).collect::<Result<_, _>>()?;
        let group = self.lift_group(&per.iter().collect::<Vec<_>>(), |g| {
            Voxels::of_meshes(g, objs.iter().map(|(_, mesh)| *mesh))
        })?;
        let mut err = self.errors(&group, &objs);
        // Objects' sets: their grids bound eps (sampled errors are measured on
        // the leaf's sets, which hold them, to keep builds linear).
        for p in &per {
            for (k, v) in p.iter().enumerate() {
                if let Some(v) = v {
                    err[k + 1][0] = err[k + 1][0].max(v.grid().max_cell_diagonal());
                }
            }
        }
        let boxes: Vec<(u32, crate::geom::Aabb)> =
            objs.iter().map(|(id, mesh)| (id.0, mesh.aabb())).collect();
        let mut level1 = Vec::new();
        crate::store::format::objboxes::encode(&boxes, &mut level1);
        let mut b = vec![Draft::Final(Entry::InRecord)];
        let mut bb = vec![Draft::Final(Entry::Blob { bytes: level1 })];
        for k in 2..self.m() {
            let idx = usize::from(k) - 2;
            let form = if k == 2 { Form::Bitmap } else { Form::Boxes };
            // B(S_n,k): every object's bound, or the level up when one is missing or as costly as exact.
            let items: Option<Vec<(u32, &Voxels)>> =
                objs.iter().zip(&per).map(|((id, _), p)| p[idx].as_ref().map(|v| (id.0, v))).collect();
            let objects = match items {
                Some(items) => {
                    let mut faces = 0u64;
                    for (_, v) in &items {
                        let left = self.triangles.saturating_sub(faces);
                        faces += v.faces_up_to(usize::try_from(left).unwrap_or(usize::MAX)) as u64;
                        if faces >= self.triangles {
                            break;
                        }
                    }
                    if faces >= self.triangles {
                        Draft::Up
                    } else {
                        let mut bytes = Vec::new();
                        encode_objects(&items, form, &mut bytes);
                        Draft::Final(Entry::Blob { bytes })
                    }
                }
                None => Draft::Up,
            };
            let group = match &group[idx] {
                Some(v) => self.group_draft(v, form, k, &group),
                None => Draft::Final(Entry::Same { level: k, objects: true }),
            };
            // The paper's rule: B(S_n,k) points to b(S_n,k) when that is smaller.
            let objects = match (&group, objects) {
                (Draft::Final(Entry::Blob { bytes: g, .. }), Draft::Final(Entry::Blob { bytes: o, .. }))
                    if !self.params.keep_identity && g.len() < o.len() =>
                {
                    Draft::Final(Entry::Same { level: k, objects: false })
                }
                (_, o) => o,
            };
            b.push(group);
            bb.push(objects);
        }
        let entries = self.resolve(b, bb);
        Ok((self.keep_for_parent(group, &entries), entries, err))
    }

    fn internal(&self, kids: [Sets; 2]) -> Result<NodeOut, LodError> {
        let objs = self.objects();
        let group = self.lift_group(&[&kids[0], &kids[1]], |g| {
            Voxels::of_meshes(g, objs.iter().map(|(_, mesh)| *mesh))
        })?;
        let err = self.errors(&group, &objs);
        let mut b = vec![Draft::Final(Entry::InRecord)];
        let spread_or_group = |k: u8| {
            if self.params.keep_identity {
                Draft::Final(Entry::Spread)
            } else {
                Draft::Final(Entry::Same { level: k, objects: false })
            }
        };
        let mut bb = vec![spread_or_group(1)];
        let mut spread = false;
        for k in 2..self.m() {
            let idx = usize::from(k) - 2;
            let form = if k == 2 { Form::Bitmap } else { Form::Boxes };
            let d = match &group[idx] {
                Some(v) if !spread => self.group_draft(v, form, k, &group),
                _ => Draft::Final(Entry::Spread),
            };
            // Once a level is the union of the children's, every finer one is too, so levels nest.
            spread |= matches!(d, Draft::Final(Entry::Spread));
            b.push(d);
            bb.push(match &b[usize::from(k) - 1] {
                Draft::Final(Entry::Blob { .. }) => spread_or_group(k),
                _ => Draft::Final(Entry::Spread),
            });
        }
        let entries = self.resolve(b, bb);
        Ok((self.keep_for_parent(group, &entries), entries, err))
    }

    /// b(S_n,k) from its voxel set: spread when it does not fit a block (an
    /// internal node), else the level up when it has as many faces as the
    /// exact objects, the level below when it is the same set, or stored.
    fn group_draft(&self, v: &Voxels, form: Form, k: u8, group: &Sets) -> Draft {
        // Size first: a set spread over the children is stored nowhere here,
        // and counting a large set's faces costs more than encoding it.
        let mut bytes = Vec::new();
        encode(v, form, &mut bytes);
        if bytes.len() > self.max_blob && self.tree.nodes[self.i].children().is_some() {
            return Draft::Final(Entry::Spread);
        }
        let faces = v.faces_up_to(usize::try_from(self.triangles).unwrap_or(usize::MAX)) as u64;
        if faces >= self.triangles {
            return Draft::Up;
        }
        if k > 2 && group[usize::from(k) - 3].as_ref() == Some(v) {
            return Draft::Final(Entry::Same { level: k - 1, objects: false });
        }
        Draft::Final(Entry::Blob { bytes })
    }

    /// The sets the parent builds on: a polyhedral level that is spread here
    /// (or too big for a block) is spread in every ancestor too, so its set is
    /// dropped instead of lifted into ever larger grids.
    fn keep_for_parent(&self, mut group: Sets, entries: &NodeEntries) -> Sets {
        for k in 3..self.m() {
            let big = match &entries[usize::from(k) - 1][0] {
                Entry::Spread => true,
                Entry::Blob { bytes, .. } => bytes.len() > self.max_blob,
                _ => false,
            };
            if big {
                group[usize::from(k) - 2] = None;
            }
        }
        group
    }

    /// Per level k = 1 .. M: (guaranteed, measured) error of the group sets.
    fn errors(&self, group: &Sets, objs: &[(ObjectId, &Mesh)]) -> Vec<[f64; 2]> {
        let mut err = vec![[0f64; 2]; usize::from(self.m())];
        // Level 1, the box: one cell of a lattice level coarse enough to hold it.
        let bounds = self.tree.nodes[self.i].aabb;
        let mut boxed = None;
        if self.m() > 1
            && let Ok(g) = Grid::coarsest_within(&self.plan.lattice, &bounds, 1, 0)
        {
            let mut v = Voxels::empty(g);
            v.set_cell([0, 0, 0]);
            err[0][0] = v.grid().max_cell_diagonal();
            boxed = Some(v);
        }
        for (k, v) in group.iter().enumerate() {
            if let Some(v) = v {
                err[k + 1][0] = v.grid().max_cell_diagonal();
            }
        }
        // The sampled error needs a BVH over the node's triangles: measured at
        // every leaf (the finest sets) and at the root (the coarsest cuberille)
        // when it has at most MEASURED_TRIANGLES; a BVH per internal node would
        // cost O(triangles x depth). eps bounds every node's error.
        let leaf = self.tree.nodes[self.i].children().is_none();
        if leaf || (self.i == 0 && self.triangles <= MEASURED_TRIANGLES) {
            let probe = ErrorProbe::new(objs.iter().map(|(_, mesh)| *mesh));
            let sets = boxed
                .iter()
                .map(|v| (0, v))
                .chain(group.iter().enumerate().filter_map(|(k, v)| Some((k + 1, v.as_ref()?))));
            for (k, v) in sets {
                err[k][1] = probe.measure(v, self.params.error_samples);
            }
        }
        err
    }

    /// Turns drafts into entries: `Up` names the next level that is stored
    /// (M at worst), and every `Same` names a stored entry.
    fn resolve(&self, b: Vec<Draft>, bb: Vec<Draft>) -> NodeEntries {
        let m = self.m();
        let drafts = [b, bb];
        let entry = |k: u8, objects: bool| -> Entry {
            let (mut at, mut obj) = (k, objects);
            // Each step moves up a level or across to the other kind: 2M steps reach M.
            for _ in 0..2 * usize::from(m) {
                if at >= m {
                    break;
                }
                match &drafts[usize::from(obj)][usize::from(at) - 1] {
                    Draft::Up => at += 1,
                    Draft::Final(Entry::Same { level, objects }) => (at, obj) = (*level, *objects),
                    Draft::Final(e) if (at, obj) == (k, objects) => return e.clone(),
                    Draft::Final(_) => return Entry::Same { level: at, objects: obj },
                }
            }
            Entry::Same { level: m, objects: obj }
        };
        (1..m).map(|k| [entry(k, false), entry(k, true)]).collect()
    }
}
