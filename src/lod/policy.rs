//! Which levels of detail a file stores: only those that pay (format-spec/
//! lod.md, "What pays"). Paper §1.5 stores every level of every node; here a
//! bound is stored inline in its leaf's record, where a query meets it with
//! no read of its own, and only when, under the query model, the geometry
//! reads it is expected to save exceed the node-block reads its bytes cost.
//!
//! The query model is refine's (`build/cost.rs`): a box query of extents q
//! placed uniformly; it meets a box W with probability ∏ (W_i + q_i) /
//! (S_i + q_i). For an object o with geometry over g blocks and a candidate
//! voxel bound V at level k (surface cells only: each holds a piece of the
//! surface, so it can witness contact as well as rule it out):
//!
//! - saving = P(meets box(o)) x P(V decides | meets box(o)) x g, where V
//!   decides when the query misses every cell of V (reject), or holds a
//!   whole cell without holding a face of the box (confirm: the box alone
//!   would have confirmed it). The conditional probability is sampled at
//!   `model_samples` query positions that meet the box.
//! - cost = P(meets the leaf's box) x bytes(V) / (bytes a node block holds):
//!   every query that reads the leaf's block reads that share of a block more.
//!
//! The level with the largest saving - cost > 0 is stored; none otherwise
//! (`LodParams::store_all` stores every level, to measure them).

use rayon::prelude::*;

use super::compact::{aligned_grid, encode};
use super::{ErrorProbe, Grid, Lattice, LodError, LodParams, LodPlan, Voxels};
use crate::build::{CostModel, Hierarchy};
use crate::geom::{Aabb, Vector};
use crate::scene::{Mesh, Scene};
use crate::store::format::geometry::{payload, record_len};
use crate::store::format::node::{BoundEntry, capacity};
use crate::store::format::quant::{QuantBox, quantize};

/// The bounds a tree stores, and what the meta block records of them.
#[derive(Debug, Clone, Default)]
pub struct StoredBounds {
    /// Per node (preorder): a leaf's per-object bounds B(o,k).
    pub bounds: Vec<Vec<BoundEntry>>,
    /// Per level k = 1 .. M: (eps_k, the largest sampled error) of what is stored.
    pub errors: Vec<[f64; 2]>,
    /// Per level k = 1 .. M: (bytes, bounds) stored.
    pub usage: Vec<[u64; 2]>,
    /// Per level k = 1 .. M: the lattice level of its grids (0 for 1 and M).
    pub grid_level: Vec<u8>,
    pub lattice: Option<Lattice>,
    /// The query model's extents q, mm.
    pub query_extent: [f64; 3],
    /// Per level k = 1 .. M: the model's expected saving and cost, in block
    /// reads per query, summed over the bounds stored (what `mktree lods` shows).
    pub predicted: Vec<[f64; 2]>,
}

/// One candidate: an object's bound at a level, with its model value.
struct Candidate {
    level: u8,
    blob: Vec<u8>,
    voxels: Voxels,
    saving: f64,
    cost: f64,
}

/// Decides and encodes the bounds of `tree` over `scene` for M = `m`
/// levels and blocks of `block_size` bytes, judged on `model`.
pub fn plan_bounds(
    scene: &Scene,
    tree: &Hierarchy,
    m: u8,
    block_size: u32,
    params: &LodParams,
    model: &CostModel,
) -> Result<StoredBounds, LodError> {
    let levels = usize::from(m);
    let mut out = StoredBounds {
        bounds: vec![Vec::new(); tree.nodes.len()],
        errors: vec![[0.0; 2]; levels],
        usage: vec![[0; 2]; levels],
        grid_level: vec![0; levels],
        lattice: None,
        query_extent: model.query_extent(),
        predicted: vec![[0.0; 2]; levels],
    };
    if m < 3 {
        return Ok(out);
    }
    let plan = LodPlan::new(scene, m, params)?;
    out.grid_level = plan.grid_level.clone();
    out.lattice = Some(plan.lattice);
    let node_capacity = capacity(block_size) as f64;
    let geometry_payload = payload(block_size) as f64;
    // Leaves in parallel; each object's frame is its leaf's box as stored.
    let frames = leaf_frames(tree);
    let chosen: Vec<(usize, Vec<(u16, Candidate)>)> = tree
        .nodes
        .par_iter()
        .enumerate()
        .filter_map(|(i, node)| node.objects().map(|objs| (i, objs)))
        .map(|(i, objs)| {
            let leaf_p = model.access_probability(&frames[i]);
            let mut picked = Vec::new();
            for (j, id) in objs.iter().enumerate() {
                let Some(o) = scene.object(*id) else { continue };
                let g = (record_len(&o.mesh) as f64 / geometry_payload).ceil().max(1.0);
                let qb = QuantBox::decode(&frames[i], quantize(&frames[i], &o.mesh.aabb()));
                let all = (2..m)
                    .filter_map(|k| {
                        candidate(&plan, params, k, &o.mesh, qb.as_ref(), model, g, leaf_p, node_capacity)
                            .transpose()
                    })
                    .collect::<Result<Vec<_>, LodError>>()?;
                if params.store_all {
                    picked.extend(all.into_iter().map(|c| (j as u16, c)));
                } else if let Some(c) = all
                    .into_iter()
                    .filter(|c| c.saving > c.cost)
                    .max_by(|a, b| (a.saving - a.cost).total_cmp(&(b.saving - b.cost)))
                {
                    picked.push((j as u16, c));
                }
            }
            Ok((i, picked))
        })
        .collect::<Result<_, LodError>>()?;
    for (i, picked) in chosen {
        let objs = tree.nodes[i].objects().unwrap_or_default();
        for (j, c) in picked {
            let k = usize::from(c.level) - 1;
            out.usage[k][0] += c.blob.len() as u64;
            out.usage[k][1] += 1;
            out.predicted[k][0] += c.saving;
            out.predicted[k][1] += c.cost;
            out.errors[k][0] = out.errors[k][0].max(c.voxels.grid().max_cell_diagonal());
            if let Some(o) = objs.get(usize::from(j)).and_then(|id| scene.object(*id)) {
                let probe = ErrorProbe::new([&o.mesh]);
                out.errors[k][1] = out.errors[k][1].max(probe.measure(&c.voxels, params.error_samples));
            }
            out.bounds[i].push(BoundEntry { target: j, level: c.level, blob: c.blob });
        }
    }
    Ok(out)
}

/// Every node's box as its parent's entry stores it (the root's exact).
fn leaf_frames(tree: &Hierarchy) -> Vec<Aabb> {
    let mut frame = vec![Aabb::EMPTY; tree.nodes.len()];
    if let Some(root) = tree.nodes.first() {
        frame[0] = root.aabb;
    }
    for i in 0..tree.nodes.len() {
        if let Some(kids) = tree.nodes[i].children() {
            for c in kids {
                let q = quantize(&frame[i], &tree.nodes[c.index()].aabb);
                frame[c.index()] = QuantBox::decode(&frame[i], q).map_or(frame[i], |b| b.outer);
            }
        }
    }
    frame
}

/// The grid of level k over `b`: the cuberille's within its cell budget,
/// a polyhedral level's at its lattice level; `None` when too large.
fn grid(plan: &LodPlan, params: &LodParams, k: u8, b: &Aabb) -> Result<Option<(Grid, [i64; 3])>, LodError> {
    let finest = plan.grid_level[usize::from(k) - 1];
    if k == 2 {
        for level in finest..=u8::MAX {
            match aligned_grid(&plan.lattice, level, b) {
                Ok((g, first)) if g.cells() <= u64::from(params.cuberille_object_bits) => {
                    return Ok(Some((g, first)));
                }
                Ok(_) | Err(LodError::TooLarge { .. }) => {}
                Err(e) => return Err(e),
            }
        }
        return Ok(None);
    }
    match aligned_grid(&plan.lattice, finest, b) {
        Ok(g) => Ok(Some(g)),
        Err(LodError::TooLarge { .. }) => Ok(None),
        Err(e) => Err(e),
    }
}

#[allow(clippy::too_many_arguments)]
fn candidate(
    plan: &LodPlan,
    params: &LodParams,
    k: u8,
    mesh: &Mesh,
    qb: Option<&QuantBox>,
    model: &CostModel,
    g: f64,
    leaf_p: f64,
    node_capacity: f64,
) -> Result<Option<Candidate>, LodError> {
    let b = mesh.aabb();
    let Some((grid, first)) = grid(plan, params, k, &b)? else { return Ok(None) };
    if grid.cells() > u64::from(u16::MAX) {
        return Ok(None);
    }
    let voxels = Voxels::of_surfaces(grid, [mesh]);
    let blob = encode(&voxels, first);
    let cost = leaf_p * blob.len() as f64 / node_capacity;
    let p_box = model.access_probability(&b);
    let decides = sampled_decisions(&voxels, &b, qb, model.query_extent(), params.model_samples);
    Ok(Some(Candidate { level: k, blob, voxels, saving: p_box * decides * g, cost }))
}

/// The share of queries meeting box `b` that `v` decides (misses every
/// cell, or holds a whole cell without holding a face of the box),
/// sampled at `n` query positions from a fixed stream.
fn sampled_decisions(v: &Voxels, b: &Aabb, qb: Option<&QuantBox>, q: [f64; 3], n: usize) -> f64 {
    if n == 0 {
        return 0.0;
    }
    let half = Vector::new(q[0], q[1], q[2]) / 2.0;
    let zone = b.grown(0.0);
    let e = zone.extent() + 2.0 * half;
    let tol = v.grid().tolerance();
    let cells: Vec<Aabb> = v.world_boxes();
    let slabs = qb.map(|q| q.face_slabs());
    let mut decided = 0usize;
    // Halton points (bases 2, 3, 5): deterministic and evenly spread.
    for s in 1..=n {
        let u = [halton(s, 2), halton(s, 3), halton(s, 5)];
        let c = zone.min - half + Vector::new(u[0] * e.x, u[1] * e.y, u[2] * e.z);
        let query = Aabb::new(c - half, c + half);
        let meets = cells.iter().any(|cb| cb.grown(tol).intersects(&query));
        if !meets {
            decided += 1;
            continue;
        }
        let box_confirms = slabs.is_some_and(|s| s.iter().any(|f| query.contains(f)));
        if !box_confirms && v.holds_a_cell_in(&query) {
            decided += 1;
        }
    }
    decided as f64 / n as f64
}

fn halton(mut i: usize, base: usize) -> f64 {
    let (mut f, mut r) = (1.0, 0.0);
    while i > 0 {
        f /= base as f64;
        r += f * (i % base) as f64;
        i /= base;
    }
    r
}
