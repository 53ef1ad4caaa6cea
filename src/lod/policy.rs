//! Which levels of detail a file stores: only those that pay (format-spec/
//! lod.md, "What pays"). Paper §1.5 stores every level of every node; here a
//! bound is stored inline in its leaf's record, where a query meets it with
//! no read of its own, and only when, under the read model ([`QueryMix`]),
//! the geometry reads it is expected to save exceed the node-block reads
//! its bytes cost.
//!
//! A bound saves a read only when it decides every object that would have
//! made a query read a geometry block: deciding one object of several in a
//! block saves nothing. So bounds are judged block by block. For a geometry
//! block b and a level k, the model's queries that meet the box around b's
//! entries (objects, or parts of larger ones) are sampled (`model_samples`,
//! spread over the scales); a query needs b when one of its entries is
//! undecided: its box meets the query and no face of it is held, and (with
//! bounds) its level-k bound neither misses the query nor has a cell held
//! by it (surface cells: each holds a piece of the surface, so a bound can
//! witness contact as well as rule it out).
//!
//! - saving(b, k) = Σ over scales of P(meets the box around b) x (share of
//!   samples needing b without bounds - share needing it with them), / scales;
//! - cost(b, k) = Σ over the bounds stored of their bytes / (bytes a node
//!   block holds) x the share of the model's queries that read their leaf's
//!   node block (in the layout without bounds).
//!
//! The level with the largest saving - cost > 0 is stored for b's entries
//! whose bound decides some sample; none otherwise (`LodParams::store_all`
//! stores every level of every entry, to measure them).

use std::borrow::Cow;

use rayon::prelude::*;

use super::compact::{aligned_grid, decode, encode};
use super::{ErrorProbe, Grid, GroupRule, Lattice, LodError, LodParams, LodPlan, Voxels, lift_group};
use crate::bulk::{Hierarchy, LoadProgress, QueryMix, Stage, StageMeter};
use crate::geom::Aabb;
use crate::scene::Mesh;
use crate::store::format::node::{BOUND_HEAD_LEN, BoundEntry, MAX_BOUND_BYTES, bounds_len, capacity};
use crate::store::format::quant::QuantBox;

/// An entry of a leaf: an object, or a part of one (format-spec/
/// geometry.md, "Parts"), with its box as the leaf stores it (quantized
/// in the leaf's frame, [`Layout::frames`]) and the geometry block its
/// record starts in (entries in leaf order start in blocks that never
/// decrease).
#[derive(Debug, Clone, Copy)]
pub struct LeafEntry {
    /// Its box (or the part's) in steps of the leaf's frame.
    pub qbox: [u16; 6],
    /// The geometry block its record starts in.
    pub block: u64,
}

/// Every leaf's entries, read in place from whatever laid them out: a copy
/// of them all would be 24 bytes an entry more, held through the stage
/// (240 MB at 10^7 objects).
pub trait LeafEntries: Sync {
    /// Nodes, in preorder (a leaf's entries are at its index).
    fn nodes(&self) -> usize;
    /// Entries of node `node`: 0 for an internal node or past the end.
    fn count(&self, node: usize) -> usize;
    /// Entry `j` of node `node`, if there is one.
    fn entry(&self, node: usize, j: usize) -> Option<LeafEntry>;
}

/// The mesh of entry j of leaf i, read when its bounds are computed: a
/// scene too large for memory keeps meshes on disk.
pub type EntryMesh<'a> = dyn Fn(usize, usize) -> Result<Cow<'a, Mesh>, LodError> + Sync + 'a;

/// What the bounds' cost and saving depend on of the tree's layout.
pub struct Layout<'a> {
    /// Per node: its box as stored (objects' boxes are quantized in their leaf's).
    pub frames: &'a [Aabb],
    /// Per node: the share of the model's queries that read its node block.
    pub read_share: &'a [f64],
    /// Per node: a leaf's entries, in record order (empty for internal nodes).
    pub entries: &'a dyn LeafEntries,
    /// The entries' meshes.
    pub mesh: &'a EntryMesh<'a>,
    /// The file's block size in bytes (what a node block holds).
    pub block_size: u32,
}

impl Layout<'_> {
    /// Entry `j` of leaf `i`'s box as the leaf stores it: what its bounds' grids cover.
    pub fn stored_box(&self, i: usize, j: usize) -> Option<Aabb> {
        let e = self.entries.entry(i, j)?;
        Some(QuantBox::decode(self.frames.get(i)?, e.qbox)?.outer)
    }
}

/// The bounds a tree stores, and what the meta block records of them.
#[derive(Debug, Clone, Default)]
pub struct StoredBounds {
    /// Per node (preorder): a leaf's per-object bounds B(o,k).
    pub bounds: Vec<Vec<BoundEntry>>,
    /// Per level k = 1 .. M: (eps_k, the largest sampled error) of what is
    /// stored; the error once [`StoredBounds::measure_errors`] has run.
    pub errors: Vec<[f64; 2]>,
    /// Per level k = 1 .. M: (bytes, bounds) stored.
    pub usage: Vec<[u64; 2]>,
    /// Per level k = 1 .. M: the lattice level of its grids (0 for 1 and M).
    pub grid_level: Vec<u8>,
    /// The voxel lattice the bounds are on; `None` when no level holds voxels.
    pub lattice: Option<Lattice>,
    /// The query model's extents q, mm.
    pub query_extent: [f64; 3],
    /// Per level k = 1 .. M: the model's expected saving and cost, in block
    /// reads per query, summed over the bounds stored (what `mktree lods` shows).
    pub predicted: Vec<[f64; 2]>,
    /// Per node, beside `bounds`: what each bound was judged worth.
    worth: Vec<Vec<Worth>>,
}

/// What a stored bound was judged worth. Its cells are not kept decoded
/// (a grid and a bit set, about 200 bytes): the blob is decoded where they
/// are read, which is rare.
#[derive(Debug, Clone)]
struct Worth {
    /// saving - cost of the group of bounds it was chosen with (block reads per query).
    value: f64,
    saving: f64,
    cost: f64,
    eps: f64,
}

/// The most bounds per level whose error is measured: a sample spread
/// evenly over the tree, so measuring costs the same for any scene size.
pub const MEASURED_BOUNDS: usize = 1024;

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
            grid_level: self.grid_level.clone(),
            lattice: self.lattice,
            query_extent: self.query_extent,
            predicted: vec![[0.0; 2]; levels],
            worth: vec![Vec::new(); n],
        }
    }

    /// Frees the bounds themselves once written, keeping the tables the
    /// meta block records (errors, usage, predictions, grids).
    pub fn release_bounds(&mut self) {
        self.bounds = Vec::new();
        self.worth = Vec::new();
    }

    fn push(&mut self, node: usize, bound: BoundEntry, w: Worth) {
        let k = usize::from(bound.level) - 1;
        self.usage[k][0] += bound.blob.len() as u64;
        self.usage[k][1] += 1;
        self.predicted[k][0] += w.saving;
        self.predicted[k][1] += w.cost;
        self.errors[k][0] = self.errors[k][0].max(w.eps);
        self.bounds[node].push(bound);
        self.worth[node].push(w);
    }

    /// The bounds judged worth at least `min_value` reads per query (with
    /// the group they were chosen in). Filtered in place, node by node: a
    /// second set of the per-node lists beside the first added to the
    /// choose stage's peak at 10^7 objects.
    pub fn keep(mut self, min_value: f64) -> StoredBounds {
        let levels = self.usage.len();
        self.errors = vec![[0.0; 2]; levels];
        self.usage = vec![[0; 2]; levels];
        self.predicted = vec![[0.0; 2]; levels];
        for node in 0..self.bounds.len() {
            let bounds = std::mem::take(&mut self.bounds[node]);
            let worth = self.worth.get_mut(node).map(std::mem::take).unwrap_or_default();
            for (b, w) in bounds.into_iter().zip(worth) {
                if w.value >= min_value {
                    self.push(node, b, w);
                }
            }
        }
        self
    }

    /// Record bytes of node `node`'s bounds worth at least `min_value`.
    pub fn bytes_at(&self, node: usize, min_value: f64) -> usize {
        let kept = self.bounds[node].iter().zip(&self.worth[node]).filter(|(_, w)| w.value >= min_value);
        bounds_len(kept.map(|(b, _)| b))
    }

    /// The finest bound worth at least `min_value` of entry `target` of
    /// leaf `node` (bounds come level by level: a later one is finer),
    /// decoded over the entry's box as the leaf stores it, `outer`.
    pub fn finest(&self, node: usize, target: usize, min_value: f64, outer: &Aabb) -> Option<Voxels> {
        let mut kept = self.bounds[node].iter().zip(&self.worth[node]).rev();
        let (b, _) = kept.find(|(b, w)| w.value >= min_value && usize::from(b.target) == target)?;
        decode(&b.blob, self.lattice.as_ref()?, outer).ok()
    }

    /// What every stored bound's group was judged worth, high to low.
    pub fn values(&self) -> Vec<f64> {
        let mut v: Vec<f64> = self.worth.iter().flatten().map(|w| w.value).collect();
        v.sort_by(|a, b| b.total_cmp(a));
        v
    }

    /// Measures the error of the bounds stored (`errors[k][1]`): per level,
    /// every ceil(n / `MEASURED_BOUNDS`)-th of its n bounds (`MEASURED_BOUNDS` = 1,024) in node order,
    /// at `cells` of its cells each (see [`ErrorProbe::measure`]).
    pub fn measure_errors(&mut self, layout: &Layout, cells: usize) -> Result<(), LodError> {
        let Some(lattice) = self.lattice else { return Ok(()) };
        let mut at_level: Vec<Vec<(usize, usize, &[u8])>> = vec![Vec::new(); self.errors.len()];
        for (i, bounds) in self.bounds.iter().enumerate() {
            for b in bounds {
                at_level[usize::from(b.level) - 1].push((i, usize::from(b.target), &b.blob));
            }
        }
        for (row, bounds) in self.errors.iter_mut().zip(&at_level) {
            let stride = bounds.len().div_ceil(MEASURED_BOUNDS).max(1);
            row[1] = bounds
                .par_iter()
                .step_by(stride)
                .map(|&(i, j, blob)| {
                    let outer = layout.stored_box(i, j).ok_or_else(|| {
                        LodError::Corrupt(format!("a bound of entry {j} of leaf {i}, which has no box"))
                    })?;
                    let v = decode(blob, &lattice, &outer)?;
                    Ok(ErrorProbe::new([&*(layout.mesh)(i, j)?]).measure(&v, cells))
                })
                .try_reduce(|| 0.0, |a, b| Ok(a.max(b)))?;
        }
        Ok(())
    }

    /// True when no bound is stored.
    pub fn is_empty(&self) -> bool {
        self.bounds.iter().all(Vec::is_empty)
    }
}

/// One candidate: an entry's bound at levels `level ..= top` (on one
/// grid), while its block's entries are judged.
struct Candidate {
    level: u8,
    top: u8,
    blob: Vec<u8>,
    voxels: Voxels,
}

/// A candidate chosen for its block: its bound and what it was judged worth.
struct Picked {
    level: u8,
    blob: Vec<u8>,
    worth: Worth,
}

/// One geometry block's entries: `len` of them in leaf order, from entry
/// `entry` of leaf `leaf` on. Listed as (leaf, entry) pairs only while the
/// block is judged: for every entry at once they were 16 bytes an entry
/// more, held through the stage.
struct Run {
    leaf: usize,
    entry: usize,
    len: usize,
}

impl Run {
    /// The run's entries as (leaf, entry) pairs, leaves without entries
    /// passed over.
    fn entries(&self, layout: &Layout) -> Vec<(usize, usize)> {
        let mut out = Vec::with_capacity(self.len);
        let (mut i, mut j) = (self.leaf, self.entry);
        let nodes = layout.entries.nodes();
        while out.len() < self.len && i < nodes {
            if j < layout.entries.count(i) {
                out.push((i, j));
                j += 1;
            } else {
                (i, j) = (i + 1, 0);
            }
        }
        out
    }
}

/// Per node, for a leaf: its entries' surfaces on the grid of its finest
/// group level (`GroupRule`), as encoded voxel blobs (lod.md), one per
/// geometry block of the leaf, whose union is the leaf's; what its group
/// bounds are built from (`db/load/groups.rs`).
pub type LeafShells = Vec<Vec<Vec<u8>>>;

/// Decides and encodes the bounds of `tree` for M = `m` levels on the
/// grids of `plan` (`None` when M < 3: no level between the box and the
/// exact geometry), judged on `mix` over `layout`. With `group_rule`, also each
/// leaf's shell for its group bounds, lifted from the entries' candidates
/// (each entry's surfaces are voxelized once for both).
#[allow(clippy::too_many_arguments)]
pub fn plan_bounds(
    plan: Option<&LodPlan>,
    tree: &Hierarchy,
    m: u8,
    params: &LodParams,
    mix: &QueryMix,
    layout: &Layout,
    group_rule: Option<&GroupRule>,
    progress: &(dyn Fn(LoadProgress) + Sync),
) -> Result<(StoredBounds, LeafShells), LodError> {
    let levels = usize::from(m);
    let mut out = StoredBounds {
        bounds: vec![Vec::new(); tree.nodes.len()],
        errors: vec![[0.0; 2]; levels],
        usage: vec![[0; 2]; levels],
        grid_level: vec![0; levels],
        lattice: None,
        query_extent: mix.extents().first().copied().unwrap_or_default(),
        predicted: vec![[0.0; 2]; levels],
        worth: vec![Vec::new(); tree.nodes.len()],
    };
    let mut shells: LeafShells = vec![Vec::new(); tree.nodes.len()];
    let Some(plan) = plan.filter(|_| m >= 3) else {
        return Ok((out, shells));
    };
    out.grid_level = plan.grid_level.clone();
    out.lattice = Some(plan.lattice);
    let ctx = Ctx { plan, params, layout };
    // Entries by the geometry block they start in: runs in leaf order.
    let mut runs: Vec<Run> = Vec::new();
    let mut block = None;
    for i in 0..layout.entries.nodes() {
        for j in 0..layout.entries.count(i) {
            let Some(e) = layout.entries.entry(i, j) else { break };
            match runs.last_mut() {
                Some(run) if block == Some(e.block) => run.len += 1,
                _ => runs.push(Run { leaf: i, entry: j, len: 1 }),
            }
            block = Some(e.block);
        }
    }
    let node_capacity = capacity(layout.block_size) as f64;
    // Block by block: its entries' candidates, level by level, judged
    // together; only the chosen ones outlive their block.
    type Block = (Vec<(usize, u16, Picked)>, Option<(usize, Vec<u8>)>);
    let picked: Vec<Block> = {
        let meter = StageMeter::new(progress, Stage::Levels, runs.len() as u64);
        runs.par_iter()
            .map(|run| {
                meter.add(1);
                let group = &run.entries(layout)[..];
                let mut cands: Vec<Vec<Candidate>> =
                    group.iter().map(|&(i, j)| ctx.candidates(m, i, j)).collect::<Result<_, LodError>>()?;
                let shell = match group_rule {
                    Some(rule) => ctx.shell(rule, group, &cands)?,
                    None => None,
                };
                let judged = judge(group, &cands, layout, mix, params, m, node_capacity);
                let picked = judged
                    .into_iter()
                    .filter_map(|(x, k, saving, cost, value)| {
                        let list = &mut cands[x];
                        let c = list.swap_remove(list.iter().position(|c| c.covers(k))?);
                        let eps = c.voxels.grid().max_cell_diagonal();
                        let worth = Worth { value, saving, cost, eps };
                        Some((group[x].0, group[x].1 as u16, Picked { level: k, blob: c.blob, worth }))
                    })
                    .collect();
                Ok((picked, shell))
            })
            .collect::<Result<_, LodError>>()?
    };
    // Blocks hold runs of leaves in leaf order, so a block's picks sorted
    // by leaf (stably) come leaf after leaf; each leaf's are stored by
    // entry and level as they end, and each block's list goes as it is
    // taken. Nothing holds every pick twice.
    let mut leaf: Option<(usize, Vec<(u16, Picked)>)> = None;
    let mut store = |(i, mut list): (usize, Vec<(u16, Picked)>)| {
        list.sort_by_key(|(j, c)| (*j, c.level));
        for (j, c) in list {
            out.push(i, BoundEntry { target: j, level: c.level, blob: c.blob }, c.worth);
        }
    };
    for (mut list, shell) in picked {
        list.sort_by_key(|&(i, ..)| i);
        for (i, j, c) in list {
            match &mut leaf {
                Some((at, taken)) if *at == i => taken.push((j, c)),
                _ => {
                    if let Some(done) = leaf.replace((i, vec![(j, c)])) {
                        store(done);
                    }
                }
            }
        }
        if let Some((i, blob)) = shell {
            shells[i].push(blob);
        }
    }
    if let Some(done) = leaf {
        store(done);
    }
    Ok((out, shells))
}

impl Candidate {
    fn covers(&self, k: u8) -> bool {
        (self.level..=self.top).contains(&k)
    }
}

struct Ctx<'a, 'm> {
    plan: &'a LodPlan,
    params: &'a LodParams,
    layout: &'a Layout<'m>,
}

impl Ctx<'_, '_> {
    /// The surfaces of one geometry block's entries `group` (all of one
    /// leaf) on their leaf's finest group grid, encoded: each entry's
    /// finest candidate lifted (levels nest on one lattice, and a lifted
    /// cell holds a cell that touches the surface), or, where none lifts
    /// (no candidate, or one coarser than the grid), its mesh voxelized.
    fn shell(
        &self,
        rule: &GroupRule,
        group: &[(usize, usize)],
        cands: &[Vec<Candidate>],
    ) -> Result<Option<(usize, Vec<u8>)>, LodError> {
        let (Some(&(leaf, _)), Some(k)) = (group.first(), rule.group_levels().last()) else {
            return Ok(None);
        };
        let grid = rule.grid(k, &self.layout.frames[leaf])?;
        let mut shell = Voxels::empty(grid.clone());
        for (&(i, j), list) in group.iter().zip(cands) {
            // `lift_into` checks the nesting before it sets a cell.
            if list.last().is_none_or(|c| c.voxels.lift_into(&mut shell).is_err()) {
                let mesh = (self.layout.mesh)(i, j)?;
                Voxels::of_surfaces(grid.clone(), [&*mesh]).lift_into(&mut shell)?;
            }
        }
        Ok(Some((leaf, encode(&shell))))
    }

    /// Entry `e` of leaf `i` bounded at levels 2 .. M-1, each `None` when
    /// its grid is too large or its blob too long for an inline bound. A
    /// level on the same grid as the level before is the same bound: it is
    /// voxelized once and stands for both (`Candidate::top`), except with
    /// `store_all`, which stores every level. Only the finest grid is
    /// voxelized from the mesh; each coarser level is the finer one lifted
    /// (as `shell` does), since a triangle's cost is paid per grid while a
    /// lift costs only the set cells.
    fn candidates(&self, m: u8, i: usize, j: usize) -> Result<Vec<Candidate>, LodError> {
        let frame = &self.layout.frames[i];
        let Some(e) = self.layout.entries.entry(i, j) else { return Ok(Vec::new()) };
        let Some(qbox) = QuantBox::decode(frame, e.qbox) else {
            return Ok(Vec::new());
        };
        // (level, top, grid) per distinct grid, coarsest first.
        let mut grids: Vec<(u8, u8, Grid)> = Vec::new();
        let mut previous: Option<Grid> = None;
        for k in 2..m {
            // The grid over the box the reader holds: the decoded quantized box.
            let grid = bound_grid(self.plan, self.params, k, &qbox.outer)?
                .filter(|g| g.cells() <= u64::from(u16::MAX));
            if grid.is_some() && grid == previous && !self.params.store_all {
                if let Some(last) = grids.last_mut().filter(|g| g.1 == k - 1) {
                    last.1 = k;
                }
                continue;
            }
            previous.clone_from(&grid);
            if let Some(grid) = grid {
                grids.push((k, k, grid));
            }
        }
        if grids.is_empty() {
            return Ok(Vec::new());
        }
        let mesh = (self.layout.mesh)(i, j)?;
        let mut out: Vec<Candidate> = Vec::with_capacity(grids.len());
        // The next finer level's set when its blob was too long to keep.
        let mut dropped: Option<Voxels> = None;
        for (level, top, grid) in grids.into_iter().rev() {
            let finer = dropped.as_ref().or_else(|| out.last().map(|c| &c.voxels));
            // `lift_into` checks the nesting before it sets a cell.
            let lifted = finer.and_then(|f| lift_group(grid.clone(), [f]).ok());
            let voxels = lifted.unwrap_or_else(|| Voxels::of_surfaces(grid, [&*mesh]));
            let blob = encode(&voxels);
            if blob.len() <= MAX_BOUND_BYTES {
                out.push(Candidate { level, top, blob, voxels });
                dropped = None;
            } else {
                dropped = Some(voxels);
            }
        }
        out.reverse();
        Ok(out)
    }
}

/// A bound judged worth storing: (its entry's place in the group, level,
/// saving, cost, the group's saving - cost).
type Judged = (usize, u8, f64, f64, f64);

/// The bounds worth storing for the entries `group` of one geometry block,
/// all at the level that pays best, or every candidate with `store_all`.
fn judge(
    group: &[(usize, usize)],
    cands: &[Vec<Candidate>],
    layout: &Layout,
    mix: &QueryMix,
    params: &LodParams,
    m: u8,
    node_capacity: f64,
) -> Vec<Judged> {
    if params.store_all {
        return cands
            .iter()
            .enumerate()
            .flat_map(|(x, list)| list.iter().map(move |c| (x, c.level, 0.0, 0.0, 0.0)))
            .collect();
    }
    let boxes: Vec<Option<QuantBox>> = group
        .iter()
        .map(|&(i, j)| QuantBox::decode(&layout.frames[i], layout.entries.entry(i, j)?.qbox))
        .collect();
    let zone = boxes.iter().flatten().fold(Aabb::EMPTY, |z, b| z.union(&b.outer));
    if zone.is_empty() {
        return Vec::new();
    }
    let scales = mix.extents().len();
    let per_scale = params.model_samples.div_ceil(scales).max(1);
    let samples = mix.sample(&zone, per_scale);
    // Undecided by its box alone: meets the box, holds no face of it.
    let open =
        |b: &QuantBox, q: &Aabb| b.outer.intersects(q) && !b.face_slabs().iter().any(|f| q.contains(f));
    let mut best: Option<(f64, Vec<Judged>)> = None;
    let mut previous: Vec<Option<&Candidate>> = Vec::new();
    for k in 2..m {
        let at_k: Vec<Option<&Candidate>> =
            cands.iter().map(|list| list.iter().find(|c| c.covers(k))).collect();
        // The same bounds as the level before judge the same, and a tie never wins.
        let same = |a: &Option<&Candidate>, b: &Option<&Candidate>| match (a, b) {
            (Some(a), Some(b)) => std::ptr::eq(*a, *b),
            (a, b) => a.is_none() && b.is_none(),
        };
        if at_k.len() == previous.len() && at_k.iter().zip(&previous).all(|(a, b)| same(a, b)) {
            continue;
        }
        previous.clone_from(&at_k);
        let mut deciding = vec![false; group.len()];
        let mut saving = 0.0;
        for (s, chunk) in samples.chunks(per_scale).enumerate() {
            let (mut without, mut with) = (0u32, 0u32);
            for q in chunk {
                let mut need_without = false;
                let mut need_with = false;
                for (x, b) in boxes.iter().enumerate() {
                    let Some(b) = b else { continue };
                    if !open(b, q) {
                        continue;
                    }
                    need_without = true;
                    match at_k[x] {
                        Some(c) if !c.voxels.may_meet(q) || c.voxels.holds_a_cell_in(q) => deciding[x] = true,
                        _ => need_with = true,
                    }
                }
                without += u32::from(need_without);
                with += u32::from(need_with);
            }
            saving += mix.scale_probability(s, &zone) * f64::from(without - with) / per_scale as f64;
        }
        saving /= scales as f64;
        let stored: Vec<(usize, f64)> = group
            .iter()
            .zip(&at_k)
            .zip(&deciding)
            .enumerate()
            .filter_map(|(x, ((&(i, _), c), &d))| {
                let c = c.filter(|_| d)?;
                let cost = layout.read_share[i] * (BOUND_HEAD_LEN + c.blob.len()) as f64 / node_capacity;
                Some((x, cost))
            })
            .collect();
        let cost: f64 = stored.iter().map(|x| x.1).sum();
        if stored.is_empty() || saving <= cost || best.as_ref().is_some_and(|b| b.0 >= saving - cost) {
            continue;
        }
        let share = saving / stored.len() as f64;
        let value = saving - cost;
        best = Some((value, stored.into_iter().map(|(x, c)| (x, k, share, c, value)).collect()));
    }
    best.map_or_else(Vec::new, |b| b.1)
}

/// The grid of level k over `b`: the cuberille's within its cell budget,
/// a polyhedral level's at its lattice level; `None` when too large. The
/// writer bounds on it, and `check` holds every stored bound to it.
pub(crate) fn bound_grid(
    plan: &LodPlan,
    params: &LodParams,
    k: u8,
    b: &Aabb,
) -> Result<Option<Grid>, LodError> {
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

#[cfg(test)]
mod tests {
    use super::*;

    impl LeafEntries for Vec<Vec<LeafEntry>> {
        fn nodes(&self) -> usize {
            self.len()
        }

        fn count(&self, node: usize) -> usize {
            self.get(node).map_or(0, Vec::len)
        }

        fn entry(&self, node: usize, j: usize) -> Option<LeafEntry> {
            self.get(node)?.get(j).copied()
        }
    }

    #[test]
    fn keeping_filters_the_bounds_and_counts_again_what_the_meta_block_records() {
        let mut all = StoredBounds {
            bounds: vec![Vec::new(); 3],
            errors: vec![[0.0; 2]; 2],
            usage: vec![[0; 2]; 2],
            grid_level: vec![0, 0],
            lattice: None,
            query_extent: [1.0; 3],
            predicted: vec![[0.0; 2]; 2],
            worth: vec![Vec::new(); 3],
        };
        let bound = |level, len| BoundEntry { target: 0, level, blob: vec![0; len] };
        let worth = |value: f64, eps| Worth { value, saving: value + 1.0, cost: 1.0, eps };
        all.push(0, bound(1, 10), worth(0.5, 2.0));
        all.push(0, bound(2, 20), worth(0.125, 3.0));
        all.push(2, bound(2, 30), worth(0.25, 1.0));
        let kept = all.clone().keep(0.25);
        assert_eq!(kept.usage, [[10, 1], [30, 1]]);
        assert_eq!(kept.errors, [[2.0, 0.0], [1.0, 0.0]]);
        assert_eq!(kept.predicted, [[1.5, 1.0], [1.25, 1.0]]);
        assert_eq!(kept.bounds.iter().map(Vec::len).collect::<Vec<_>>(), [1, 0, 1]);
        assert_eq!(kept.bounds[2][0].blob.len(), 30);
        assert_eq!(kept.values(), [0.5, 0.25]);
        let every = all.clone().keep(f64::NEG_INFINITY);
        assert_eq!(
            (&every.usage, &every.errors, &every.predicted),
            (&all.usage, &all.errors, &all.predicted)
        );
        assert!(all.keep(f64::INFINITY).is_empty());
    }

    #[test]
    fn a_run_lists_its_entries_in_leaf_order_past_leaves_without_any() {
        let entry = |block| LeafEntry { qbox: [0; 6], block };
        let entries = vec![vec![entry(0), entry(0)], Vec::new(), vec![entry(0), entry(1), entry(1)]];
        let mesh = |_: usize, _: usize| -> Result<Cow<'_, Mesh>, LodError> {
            Err(LodError::Mesh("not read".into()))
        };
        let layout = Layout {
            frames: &[Aabb::EMPTY; 3],
            read_share: &[0.0; 3],
            entries: &entries,
            mesh: &mesh,
            block_size: 4096,
        };
        let run = |leaf, entry, len| Run { leaf, entry, len }.entries(&layout);
        assert_eq!(run(0, 1, 3), [(0, 1), (2, 0), (2, 1)]);
        assert_eq!(run(2, 1, 2), [(2, 1), (2, 2)]);
        // A run longer than what is left ends with the entries.
        assert_eq!(run(2, 2, 5), [(2, 2)]);
    }
}
