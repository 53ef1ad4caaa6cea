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
    let mesh: &EntryMesh = &|i, j| plan.entry_mesh(objects, i, j).map_err(|e| LodError::Mesh(e.to_string()));
    let layout =
        Layout { frames: &plan.frames, read_share: &plan.read_share, entries: plan, mesh, block_size };
    let (mut stored, shells) = plan_bounds(lod_plan, tree, m, params, mix, &layout, group, progress)?;
    // Units: the read model's simulations, as many as there can be, then
    // the error measured; simulations not needed are counted at once.
    let choose = StageMeter::new(progress, Stage::Choose, SIMULATIONS + 1);
    if !params.store_all && !stored.is_empty() {
        stored = worth_keeping(plan, tree, stored, block_size, &choose);
    }
    choose.catch_up(SIMULATIONS);
    stored.measure_errors(&layout, params.error_samples)?;
    Ok((stored, shells))
}

/// The bounds to store: chosen block by block, they may still not pay as a
/// whole, since the bytes they add change the packing. Of the best-valued
/// bounds, the most ([`longest_passing`]) with which the model's queries
/// read no more at any scale than with none, and less in all; none if no
/// count tried passes.
fn worth_keeping(
    plan: &Plan,
    tree: &Hierarchy,
    stored: StoredBounds,
    block_size: u32,
    meter: &StageMeter,
) -> StoredBounds {
    let base = plan.expected_reads(tree, &stored, f64::INFINITY, block_size);
    meter.add(1);
    let values = stored.values();
    let passes = |count: usize| {
        let reads = plan.expected_reads(tree, &stored, values[count - 1], block_size);
        meter.add(1);
        reads.iter().zip(&base).all(|(x, y)| x <= y) && reads.iter().sum::<f64>() < base.iter().sum::<f64>()
    };
    match longest_passing(values.len(), passes) {
        0 => stored.none(),
        count => stored.keep(values[count - 1]),
    }
}

/// Simulations [`longest_passing`] runs after the one of all bounds.
const BISECTIONS: usize = 3;

/// The most simulations [`worth_keeping`] runs: none stored, all, and the
/// bisections.
const SIMULATIONS: u64 = 2 + BISECTIONS as u64;

/// The count of best-valued bounds to keep of `total`: `total` if it
/// `passes`, else the longest count found passing by bisection between
/// none and `total` in [`BISECTIONS`] more calls (a shorter prefix adds
/// fewer bytes, and passes more often), within an eighth of `total` of the
/// longest that passes when shorter counts pass too; 0 when none tried
/// passes. It never returns less than the first of `total`, a half, a
/// quarter and an eighth of it that passes, the writer's earlier rule.
fn longest_passing(total: usize, mut passes: impl FnMut(usize) -> bool) -> usize {
    if total == 0 || passes(total) {
        return total;
    }
    // `kept` passes (or is 0), `failed` does not.
    let (mut kept, mut failed) = (0, total);
    for _ in 0..BISECTIONS {
        let count = (kept + failed) / 2;
        if count == kept {
            break;
        }
        if passes(count) {
            kept = count;
        } else {
            failed = count;
        }
    }
    kept
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The writer's rule before the bisection: the first of all, a half, a
    /// quarter and an eighth that passes.
    fn halving(total: usize, passes: impl Fn(usize) -> bool) -> usize {
        let mut count = total;
        for _ in 0..4 {
            if count == 0 || passes(count) {
                return count;
            }
            count /= 2;
        }
        0
    }

    #[test]
    fn a_threshold_is_found_within_an_eighth() {
        for t in [0, 1, 99, 100, 370, 500, 999, 1000] {
            let kept = longest_passing(1000, |c| c <= t);
            assert!(kept <= t && t - kept < 125, "threshold {t}: kept {kept}");
        }
    }

    proptest! {
        /// Whatever passes: what is kept passed (or is none), it takes at
        /// most four simulations, and it keeps no fewer than halving did.
        #[test]
        fn what_is_kept_passed_and_is_no_less_than_halving_kept(
            total in 0usize..5000,
            pass in proptest::collection::vec(any::<bool>(), 5000),
        ) {
            let passes = |c: usize| pass[c - 1];
            let mut calls = 0;
            let kept = longest_passing(total, |c| {
                calls += 1;
                passes(c)
            });
            prop_assert!(kept == 0 || passes(kept));
            prop_assert!(calls <= 1 + BISECTIONS);
            prop_assert!(kept >= halving(total, passes));
        }
    }
}
