//! The bulk load's write pipeline: a built tree and its objects in, the
//! blocks written and the meta block's contents out. One file per step:
//!
//! 1. `plan.rs`: where every record goes, and how node records pack
//!    (chosen by the read model of `read_model.rs`);
//! 2. `bounds.rs`: which levels of detail pay to store (format-spec/lod.md),
//!    and the leaves' shells the group bounds are built from;
//! 3. `blocks.rs`: geometry, node and group blocks (format-spec/node.md,
//!    geometry.md, group.md), with the group bounds built by `groups.rs`;
//! 4. the key index, bottom up (`keys.rs`, format-spec/keys.md);
//! 5. `meta.rs`: the meta block's fields (format-spec/meta.md).
//!
//! The write transaction lends allocation ([`Sink`]) and writes the meta
//! block and the commit (format-spec/commit.md); change commits
//! (`db/write/cow/`) reuse the read model and the record helpers.

mod blocks;
mod bounds;
mod groups;
mod keys;
mod meta;
mod plan;
mod read_model;

pub(crate) use blocks::{Written, split_info};
pub(crate) use read_model::{SAMPLES_PER_SCALE, choose_packing, node_reads_per_scale};

use super::source::ObjectSource;
use crate::bulk::{BuildParams, CostModel, Hierarchy, LoadProgress, QueryMix, Stage, StageMeter};
use crate::lod::{GroupRule, LodParams, LodPlan};
use crate::store::format::meta::Meta;
use crate::store::{Pager, StorageError};

/// Where a write transaction's new blocks go: its pager and id, and its
/// allocator (count -> first block).
pub(crate) struct Sink<'a> {
    pub pager: &'a Pager,
    pub txn: u64,
    pub allocate: &'a mut dyn FnMut(u32) -> Result<u32, StorageError>,
}

/// One bulk load's inputs.
pub(crate) struct Load<'a> {
    pub objects: &'a dyn ObjectSource,
    pub tree: &'a Hierarchy,
    pub params: &'a BuildParams,
    pub build_seconds: f64,
    pub lod_params: &'a LodParams,
}

impl Load<'_> {
    /// Writes the tree's blocks and key index into `sink`; returns the
    /// meta block to commit.
    pub fn write(&self, sink: Sink, progress: &(dyn Fn(LoadProgress) + Sync)) -> Result<Meta, crate::Error> {
        let Sink { pager, txn, allocate } = sink;
        let Load { objects, tree, params, lod_params, .. } = *self;
        let (bs, m) = (pager.block_size(), pager.lod_levels());
        if tree.nodes.is_empty() {
            return Err(crate::bulk::BuildError::EmptyInput.into());
        }
        // What needs every object's box at once, before anything else is held.
        let (mix, lod_plan) = {
            let boxes = objects.object_boxes();
            let q = CostModel::of_boxes(&boxes, params.query_extent).query_extent();
            let lod_plan = (m >= 3).then(|| LodPlan::new(&boxes, m, lod_params)).transpose()?;
            (QueryMix::new(&tree.nodes[0].aabb, q), lod_plan)
        };
        let plan = {
            let _layout = StageMeter::new(progress, Stage::Layout, 1);
            plan::Plan::new(objects, tree, bs, &mix)?
        };
        let group_rule = match (&lod_plan, lod_params.group_bounds) {
            (Some(p), true) => Some(GroupRule {
                lattice: p.lattice,
                levels: m,
                floor: p.grid_level.clone(),
                cuberille_bits: lod_params.cuberille_bits,
            }),
            _ => None,
        };
        // The leaves' shells on the grids of the finer of the two rules the
        // group bounds may be built under (`groups.rs`): either lifts them.
        let shell_rule = group_rule.as_ref().map(GroupRule::finer);
        let (mut stored, shells) = bounds::choose_bounds(
            self,
            &plan,
            lod_plan.as_ref(),
            m,
            &mix,
            bs,
            shell_rule.as_ref(),
            progress,
        )?;
        let written = blocks::write(
            Sink { pager, txn, allocate: &mut *allocate },
            objects,
            tree,
            &plan,
            &stored.bounds,
            group_rule.as_ref().map(|rule| (rule, &shells)),
            progress,
        )?;
        // Written: only the tables of the bounds are left to record.
        drop((plan, shells));
        stored.release_bounds();
        let keys = keys::write(Sink { pager, txn, allocate }, objects, &written, progress)?;
        Ok(meta::assemble(self, &written, &stored, &keys))
    }
}
