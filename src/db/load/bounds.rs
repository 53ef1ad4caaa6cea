//! Which levels of detail a bulk load stores (format-spec/lod.md, "What
//! pays"): the bounds `lod::plan_bounds` draws and values leaf by leaf,
//! then the share of them the read model finds pays as a whole, then their
//! errors measured.

use super::Load;
use super::plan::Plan;
use crate::bulk::{Hierarchy, LoadProgress, QueryMix, Stage, StageMeter};
use crate::lod::{EntryMesh, GroupRule, Layout, LeafShells, LodError, LodPlan, StoredBounds, plan_bounds};

/// The bounds to store for `load`'s tree laid out by `plan`, with M = `m`
/// levels on the grids of `lod_plan`, judged on `mix`; with `group`, also
/// the leaves' shells its group bounds are built from.
#[allow(clippy::too_many_arguments)]
pub(super) fn choose_bounds(
    load: &Load,
    plan: &Plan,
    lod_plan: Option<&LodPlan>,
    m: u8,
    mix: &QueryMix,
    block_size: u32,
    group: Option<&GroupRule>,
    progress: &(dyn Fn(LoadProgress) + Sync),
) -> Result<(StoredBounds, LeafShells), LodError> {
    let Load { objects, tree, lod_params: params, .. } = *load;
    let entries = plan.leaf_entries();
    let mesh: &EntryMesh = &|i, j| plan.entry_mesh(objects, i, j).map_err(|e| LodError::Mesh(e.to_string()));
    let layout =
        Layout { frames: &plan.frames, read_share: &plan.read_share, entries: &entries, mesh, block_size };
    let (mut stored, shells) = plan_bounds(lod_plan, tree, m, params, mix, &layout, group, progress)?;
    let choose = StageMeter::new(progress, Stage::Choose, 2);
    if !params.store_all && !stored.is_empty() {
        stored = worth_keeping(plan, tree, stored, block_size);
    }
    choose.add(1);
    stored.measure_errors(&layout, params.error_samples)?;
    Ok((stored, shells))
}

/// The bounds to store: chosen block by block, they may still not pay as a
/// whole, since the bytes they add change the packing. Of the best-valued
/// bounds (all, half, a quarter, an eighth, by value), the most the model's
/// queries read no more with at any scale than with none, and less in all;
/// none if no share passes.
fn worth_keeping(plan: &Plan, tree: &Hierarchy, stored: StoredBounds, block_size: u32) -> StoredBounds {
    let base = plan.expected_reads(tree, &stored, f64::INFINITY, block_size);
    let values = stored.values();
    let mut count = values.len();
    for _ in 0..4 {
        if count == 0 {
            break;
        }
        let min_value = values[count - 1];
        let reads = plan.expected_reads(tree, &stored, min_value, block_size);
        if reads.iter().zip(&base).all(|(x, y)| x <= y)
            && reads.iter().sum::<f64>() < base.iter().sum::<f64>()
        {
            return stored.keep(min_value);
        }
        count /= 2;
    }
    stored.none()
}
