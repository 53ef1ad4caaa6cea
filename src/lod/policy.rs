//! Which levels of detail a file stores: only those that pay (format-spec/
//! lod.md, "What pays"). Paper §1.5 stores every level of every node; here a
//! bound is stored inline in its leaf's record, where a query meets it with
//! no read of its own, and only when, under the read model ([`QueryMix`]),
//! the geometry reads it is expected to save exceed the node-block reads
//! its bytes cost.
//!
//! For an object o and a candidate voxel bound V at level k (surface cells
//! only: each holds a piece of the surface, so it can witness contact as
//! well as rule it out), the model's queries that meet o's box are sampled
//! (`model_samples`, spread over the scales). In each sample where o's box
//! alone leaves o undecided (no face of it held) and V decides it (the query
//! misses every cell, or holds one), V saves the reads of o's geometry
//! blocks that no other object's box leaves undecided in that query (a
//! block another undecided object needs is read anyway). So:
//!
//! - saving = Σ over scales of P(meets box(o)) x mean saved blocks, / scales;
//! - cost = bytes(V) / (bytes a node block holds) x the share of the model's
//!   queries that read o's leaf's node block (in the layout without bounds).
//!
//! The level with the largest saving - cost > 0 is stored; none otherwise
//! (`LodParams::store_all` stores every level, to measure them).

use std::collections::HashMap;
use std::ops::RangeInclusive;

use rayon::prelude::*;

use super::compact::{aligned_grid, encode};
use super::{ErrorProbe, Grid, Lattice, LodError, LodParams, LodPlan, Voxels};
use crate::build::{Hierarchy, QueryMix};
use crate::geom::Aabb;
use crate::scene::{Mesh, ObjectId, Scene};
use crate::store::format::node::{BoundEntry, capacity};
use crate::store::format::quant::{QuantBox, quantize};

/// An entry of a leaf: an object, or a part of one (format-spec/
/// geometry.md, "Parts"), with the geometry blocks its record lies in.
#[derive(Debug, Clone)]
pub struct LeafEntry<'a> {
    pub id: ObjectId,
    pub mesh: &'a Mesh,
    pub blocks: RangeInclusive<u64>,
}

/// What the bounds' cost and saving depend on of the tree's layout.
pub struct Layout<'a> {
    /// Per node: its box as stored (objects' boxes are quantized in their leaf's).
    pub frames: &'a [Aabb],
    /// Per node: the share of the model's queries that read its node block.
    pub read_share: &'a [f64],
    /// Per node: a leaf's entries, in record order (empty for internal nodes).
    pub entries: &'a [Vec<LeafEntry<'a>>],
}

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
    /// Per node: the finest bound stored for each object (object index, set).
    pub finest: Vec<Vec<(u16, Voxels)>>,
}

impl StoredBounds {
    /// The same levels with no bound stored (what a file whose bounds do
    /// not pay as a whole keeps).
    pub fn none(&self) -> StoredBounds {
        let n = self.bounds.len();
        let levels = self.usage.len();
        StoredBounds {
            bounds: vec![Vec::new(); n],
            errors: vec![[0.0; 2]; levels],
            usage: vec![[0; 2]; levels],
            predicted: vec![[0.0; 2]; levels],
            finest: vec![Vec::new(); n],
            ..self.clone()
        }
    }

    /// True when no bound is stored.
    pub fn is_empty(&self) -> bool {
        self.bounds.iter().all(Vec::is_empty)
    }
}

/// One candidate: an object's bound at a level, with its model value.
struct Candidate {
    level: u8,
    blob: Vec<u8>,
    voxels: Voxels,
    saving: f64,
    cost: f64,
}

/// An object as the model's queries see it in a geometry block.
struct Sharer {
    object: ObjectId,
    qbox: QuantBox,
}

impl Sharer {
    /// True when `q` meets the box and holds none of its faces.
    fn undecided(&self, q: &Aabb) -> bool {
        self.qbox.outer.intersects(q) && !self.qbox.face_slabs().iter().any(|f| q.contains(f))
    }
}

/// Decides and encodes the bounds of `tree` over `scene` for M = `m`
/// levels and blocks of `block_size` bytes, judged on `mix` over `layout`.
pub fn plan_bounds(
    scene: &Scene,
    tree: &Hierarchy,
    m: u8,
    block_size: u32,
    params: &LodParams,
    mix: &QueryMix,
    layout: &Layout,
) -> Result<StoredBounds, LodError> {
    let levels = usize::from(m);
    let mut out = StoredBounds {
        bounds: vec![Vec::new(); tree.nodes.len()],
        errors: vec![[0.0; 2]; levels],
        usage: vec![[0; 2]; levels],
        grid_level: vec![0; levels],
        lattice: None,
        query_extent: mix.extents().first().copied().unwrap_or_default(),
        predicted: vec![[0.0; 2]; levels],
        finest: vec![Vec::new(); tree.nodes.len()],
    };
    if m < 3 {
        return Ok(out);
    }
    let plan = LodPlan::new(scene, m, params)?;
    out.grid_level = plan.grid_level.clone();
    out.lattice = Some(plan.lattice);
    let node_capacity = capacity(block_size) as f64;
    // Every entry of every geometry block, with its box as its leaf stores it.
    let mut sharers: HashMap<u64, Vec<Sharer>> = HashMap::new();
    for (i, entries) in layout.entries.iter().enumerate() {
        for e in entries {
            let Some(qbox) = QuantBox::decode(&layout.frames[i], quantize(&layout.frames[i], &e.mesh.aabb()))
            else {
                continue;
            };
            for b in e.blocks.clone() {
                sharers.entry(b).or_default().push(Sharer { object: e.id, qbox });
            }
        }
    }
    let ctx = Ctx { plan: &plan, params, mix, layout, sharers: &sharers, node_capacity };
    let chosen: Vec<(usize, Vec<(u16, Candidate)>)> = layout
        .entries
        .par_iter()
        .enumerate()
        .filter(|(_, entries)| !entries.is_empty())
        .map(|(i, entries)| {
            let mut picked = Vec::new();
            for (j, e) in entries.iter().enumerate() {
                let all = (2..m)
                    .filter_map(|k| ctx.candidate(k, i, e).transpose())
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
        for (j, c) in picked {
            // Candidates come level by level: a later one of the same object is finer.
            match out.finest[i].last_mut() {
                Some(last) if last.0 == j => last.1 = c.voxels.clone(),
                _ => out.finest[i].push((j, c.voxels.clone())),
            }
            let k = usize::from(c.level) - 1;
            out.usage[k][0] += c.blob.len() as u64;
            out.usage[k][1] += 1;
            out.predicted[k][0] += c.saving;
            out.predicted[k][1] += c.cost;
            out.errors[k][0] = out.errors[k][0].max(c.voxels.grid().max_cell_diagonal());
            if let Some(e) = layout.entries[i].get(usize::from(j)) {
                let probe = ErrorProbe::new([e.mesh]);
                out.errors[k][1] = out.errors[k][1].max(probe.measure(&c.voxels, params.error_samples));
            }
            out.bounds[i].push(BoundEntry { target: j, level: c.level, blob: c.blob });
        }
    }
    Ok(out)
}

struct Ctx<'a> {
    plan: &'a LodPlan,
    params: &'a LodParams,
    mix: &'a QueryMix,
    layout: &'a Layout<'a>,
    sharers: &'a HashMap<u64, Vec<Sharer>>,
    node_capacity: f64,
}

impl Ctx<'_> {
    /// Entry `e` of leaf `i` bounded at level k, with its model value;
    /// `None` when the level's grid is too large or its blob too long.
    fn candidate(&self, k: u8, i: usize, e: &LeafEntry) -> Result<Option<Candidate>, LodError> {
        let (id, mesh) = (e.id, e.mesh);
        let frame = &self.layout.frames[i];
        let Some(qbox) = QuantBox::decode(frame, quantize(frame, &mesh.aabb())) else { return Ok(None) };
        // The grid over the box the reader holds: the decoded quantized box.
        let Some(grid) = grid(self.plan, self.params, k, &qbox.outer)? else { return Ok(None) };
        if grid.cells() > u64::from(u16::MAX) {
            return Ok(None);
        }
        let voxels = Voxels::of_surfaces(grid, [mesh]);
        let blob = encode(&voxels);
        if blob.len() > usize::from(u8::MAX) {
            return Ok(None);
        }
        let cost = self.layout.read_share[i]
            * (crate::store::format::node::BOUND_HEAD_LEN + blob.len()) as f64
            / self.node_capacity;
        let blocks: Vec<u64> = e.blocks.clone().collect();
        let scales = self.mix.extents().len();
        let per_scale = self.params.model_samples.div_ceil(scales).max(1);
        let samples = self.mix.sample(&qbox.outer, per_scale);
        let mut saving = 0.0;
        for (c, chunk) in samples.chunks(per_scale).enumerate() {
            let mut saved = 0u64;
            for q in chunk {
                if qbox.face_slabs().iter().any(|f| q.contains(f)) {
                    continue;
                }
                if voxels.may_meet(q) && !voxels.holds_a_cell_in(q) {
                    continue;
                }
                saved += blocks
                    .iter()
                    .filter(|b| {
                        self.sharers
                            .get(b)
                            .is_none_or(|v| v.iter().all(|s| s.object == id || !s.undecided(q)))
                    })
                    .count() as u64;
            }
            saving += self.mix.scale_probability(c, &qbox.outer) * saved as f64 / per_scale as f64;
        }
        saving /= scales as f64;
        Ok(Some(Candidate { level: k, blob, voxels, saving, cost }))
    }
}

/// The grid of level k over `b`: the cuberille's within its cell budget,
/// a polyhedral level's at its lattice level; `None` when too large.
fn grid(plan: &LodPlan, params: &LodParams, k: u8, b: &Aabb) -> Result<Option<Grid>, LodError> {
    let finest = plan.grid_level[usize::from(k) - 1];
    if k == 2 {
        for level in finest..=u8::MAX {
            match aligned_grid(&plan.lattice, level, b) {
                Ok(g) if g.cells() <= u64::from(params.cuberille_object_bits) => {
                    return Ok(Some(g));
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
