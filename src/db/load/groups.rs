//! The group bounds b(S_n,k) of a bulk load (paper §1.4-1.5, `lod/group.rs`,
//! format-spec/group.md): every node's, built bottom up over the boxes the
//! records hold, and per node block the entries its group block holds.
//!
//! A leaf's bounds come from its shell: its entries' surfaces on its finest
//! group grid, lifted from the candidates the levels of detail voxelized
//! (`lod/policy.rs`, [`LeafShells`]), so a mesh is voxelized once for both.
//!
//! Subtrees build in parallel: a node's bounds need only its children's,
//! so the two halves of a large subtree are independent. Below
//! [`PARALLEL_NODES`] nodes, or [`PARALLEL_DEPTH`] joins deep, a subtree
//! builds on one thread, children first, holding only the bounds of nodes
//! whose parent is not built yet.

use std::borrow::Cow;
use std::collections::HashMap;
use std::sync::OnceLock;

use super::plan::Plan;
use crate::bulk::{Hierarchy, LoadProgress, Stage, StageMeter};
use crate::db::source::ObjectSource;
use crate::lod::{Grid, GroupRule, LeafShells, Voxels, leaf_group, lift_group};
use crate::scene::Mesh;
use crate::store::format::group::{self, GroupEntry};
use crate::store::layout::Packing;

/// A subtree of at least this many nodes builds its two halves in parallel.
const PARALLEL_NODES: usize = 2048;

/// At most this many joins deep (a skewed tree would otherwise recurse once
/// per node).
const PARALLEL_DEPTH: u32 = 12;

/// A finer group grid is kept when the group blocks still hold the level-2
/// bound of at least this share of the nodes that have one. A node left
/// without it shows as its box, or costs the reads below it, so finer
/// bounds pay only while they cost almost none; measured on the ship,
/// plant and tanker scenes in docs/viewing.md.
const KEPT_SHARE: f64 = 0.99;

/// Group entries per node block, and the rule they were built under.
pub(super) struct GroupEntries {
    /// Per node block of the packing, its group block's entries.
    pub per_block: Vec<Vec<GroupEntry>>,
    /// The rule's cells per level-2 grid (the meta block's `cuberille_bits`).
    pub cuberille_bits: u32,
}

/// Per node block of `packing`, the group entries its group block holds,
/// under `rule`'s finer rule ([`GroupRule::finer`]) when its level-2 bounds
/// fit for [`KEPT_SHARE`] of the nodes, else under `rule`. The leaves'
/// `shells` lie on the finer rule's grids (or coarser ones), so either
/// rule lifts them. Progress counts each node's levels built: one at the
/// finer rule's level 2, then every level of the rule chosen (a node's
/// levels cost about alike: the second pass took 2.2 times the first on
/// ship 10^6, building two levels to its one).
pub(super) fn group_entries(
    (rule, shells): (&GroupRule, &LeafShells),
    objects: &dyn ObjectSource,
    tree: &Hierarchy,
    plan: &Plan,
    (packing, offset): (&Packing, &[u32]),
    block_size: u32,
    progress: &(dyn Fn(LoadProgress) + Sync),
) -> Result<GroupEntries, crate::Error> {
    let nodes = tree.nodes.len() as u64;
    // Both rules have the same levels (`GroupRule::finer`).
    let levels = rule.group_levels().count() as u64;
    let meter = StageMeter::new(progress, Stage::Groups, nodes * (1 + levels));
    let packed = Packed {
        shells,
        objects,
        tree,
        plan,
        packing,
        offset,
        block_size,
        ends: subtree_ends(tree),
        meter: &meter,
    };
    let finer = rule.finer();
    // Whether the finer rule's bounds fit depends on their level-2 bounds
    // alone: a group block takes every member's level 2 before any finer
    // level. So that is decided on level 2 alone, at about half the cost of
    // every level (on every scene of 20,000 objects or more measured, the
    // finer bounds did not fit and were built for nothing).
    let finer_levels: Vec<u8> = finer.group_levels().collect();
    let (_, kept) = packed.entries_under(&finer, &finer_levels[..finer_levels.len().min(1)])?;
    let chosen = if kept >= KEPT_SHARE { finer } else { rule.clone() };
    let levels: Vec<u8> = chosen.group_levels().collect();
    let (per_block, _) = packed.entries_under(&chosen, &levels)?;
    Ok(GroupEntries { per_block, cuberille_bits: chosen.cuberille_bits })
}

/// What the group bounds are built from and packed into, whichever rule.
struct Packed<'a> {
    shells: &'a LeafShells,
    objects: &'a dyn ObjectSource,
    tree: &'a Hierarchy,
    plan: &'a Plan,
    packing: &'a Packing,
    offset: &'a [u32],
    block_size: u32,
    ends: Vec<usize>,
    /// Counts each node as it is built.
    meter: &'a StageMeter<'a>,
}

impl Packed<'_> {
    /// Per node block of the packing, the group entries its group block
    /// holds under `rule` at `levels` (the rule's, or the first of them):
    /// level by level, coarse first, and within a level in the block's
    /// record order (a piece's root first), each that still fits; sorted
    /// by record and level. Also the share of the nodes with a bound at the
    /// first level whose bound is held (1 when none has one).
    fn entries_under(
        &self,
        rule: &GroupRule,
        levels: &[u8],
    ) -> Result<(Vec<Vec<GroupEntry>>, f64), crate::Error> {
        let Packed { shells, objects, tree, plan, packing, offset, block_size, meter, .. } = *self;
        let blobs = (0..tree.nodes.len()).map(|_| OnceLock::new()).collect();
        let build = Build { rule, shells, objects, tree, plan, levels, ends: &self.ends, blobs, meter };
        if !tree.nodes.is_empty() {
            build.subtree(0, 0)?;
        }
        let mut blobs: Vec<Vec<Option<Vec<u8>>>> =
            build.blobs.into_iter().map(|b| b.into_inner().unwrap_or_default()).collect();
        let bounded = blobs.iter().filter(|b| b.first().is_some_and(Option::is_some)).count();
        let mut held = 0usize;
        let capacity = group::capacity(block_size);
        let mut per_block = Vec::with_capacity(packing.blocks.len());
        for members in &packing.blocks {
            let mut chosen: Vec<GroupEntry> = Vec::new();
            let mut used = group::entries_len(&[]);
            for (li, &k) in levels.iter().enumerate() {
                for &m in members {
                    let Some(Some(blob)) = blobs[m as usize].get_mut(li) else { continue };
                    if used + group::ENTRY_LEN + blob.len() <= capacity {
                        used += group::ENTRY_LEN + blob.len();
                        held += usize::from(li == 0);
                        chosen.push(GroupEntry {
                            record: offset[m as usize],
                            level: k,
                            blob: std::mem::take(blob),
                        });
                    }
                }
            }
            chosen.sort_by_key(|e| (e.record, e.level));
            per_block.push(chosen);
        }
        let kept = if bounded == 0 { 1.0 } else { held as f64 / bounded as f64 };
        Ok((per_block, kept))
    }
}

/// Per node (preorder ids, so a subtree is a range of ids), one past the
/// last id of its subtree.
fn subtree_ends(tree: &Hierarchy) -> Vec<usize> {
    let mut ends = vec![0; tree.nodes.len()];
    for i in (0..tree.nodes.len()).rev() {
        ends[i] = match tree.nodes[i].children() {
            Some(kids) => {
                kids.iter().map(|c| ends.get(c.index()).copied().unwrap_or(0)).fold(i + 1, usize::max)
            }
            None => i + 1,
        };
    }
    ends
}

/// One load's group bounds in the making.
struct Build<'a> {
    rule: &'a GroupRule,
    shells: &'a LeafShells,
    objects: &'a dyn ObjectSource,
    tree: &'a Hierarchy,
    plan: &'a Plan,
    levels: &'a [u8],
    ends: &'a [usize],
    /// Per node, per level: the encoded bound (None: not stored, the level
    /// answers as the coarser one, or the bound is empty).
    blobs: Vec<OnceLock<Vec<Option<Vec<u8>>>>>,
    meter: &'a StageMeter<'a>,
}

impl Build<'_> {
    /// Builds the bounds of node `top`'s subtree; returns `top`'s per level.
    fn subtree(&self, top: usize, depth: u32) -> Result<Vec<Voxels>, crate::Error> {
        match self.tree.nodes[top].children() {
            Some([a, b]) if self.ends[top] - top >= PARALLEL_NODES && depth < PARALLEL_DEPTH => {
                let (a, b) =
                    rayon::join(|| self.subtree(a.index(), depth + 1), || self.subtree(b.index(), depth + 1));
                self.node(top, Some(vec![a?, b?]))
            }
            _ => self.in_order(top),
        }
    }

    /// Builds node `top`'s subtree on this thread, children first.
    fn in_order(&self, top: usize) -> Result<Vec<Voxels>, crate::Error> {
        // Preorder: children come after their parent, so walking ids down
        // builds children first.
        let mut held: HashMap<usize, Vec<Voxels>> = HashMap::new();
        for i in (top + 1..self.ends[top]).rev() {
            let kids = self.held_children(i, &mut held);
            held.insert(i, self.node(i, kids)?);
        }
        let kids = self.held_children(top, &mut held);
        self.node(top, kids)
    }

    fn held_children(&self, i: usize, held: &mut HashMap<usize, Vec<Voxels>>) -> Option<Vec<Vec<Voxels>>> {
        self.tree.nodes[i]
            .children()
            .map(|c| c.iter().map(|c| held.remove(&c.index()).unwrap_or_default()).collect())
    }

    /// Node `i`'s bounds per level: a leaf's from its objects' surfaces, an
    /// internal node's lifted from its children's (`kids`). Records the
    /// encoded ones and returns them all.
    fn node(&self, i: usize, kids: Option<Vec<Vec<Voxels>>>) -> Result<Vec<Voxels>, crate::Error> {
        let grids = self
            .levels
            .iter()
            .map(|&k| self.rule.grid(k, &self.plan.frames[i]))
            .collect::<Result<Vec<_>, _>>()?;
        let mine = match &kids {
            Some(kids) => grids
                .iter()
                .enumerate()
                .map(|(li, grid)| lift_group(grid.clone(), kids.iter().filter_map(|k| k.get(li))))
                .collect::<Result<Vec<_>, _>>()?,
            None => {
                // A leaf's finest level is its shell (or its meshes
                // voxelized, without one); each coarser level is lifted
                // from the next finer one (levels nest on one lattice).
                let mut fine_first: Vec<Voxels> = Vec::with_capacity(grids.len());
                for grid in grids.iter().rev() {
                    let v = match fine_first.last() {
                        Some(finer) => lift_group(grid.clone(), [finer])?,
                        None => self.leaf(i, grid)?,
                    };
                    fine_first.push(v);
                }
                fine_first.reverse();
                fine_first
            }
        };
        let mut last_level = None;
        let out = grids
            .iter()
            .zip(&mine)
            .map(|(grid, v)| {
                // A level on the same grid as the coarser one holds the same bound.
                let same = last_level == Some(grid.level());
                last_level = Some(grid.level());
                (!same && !v.is_empty()).then(|| crate::lod::encode(v))
            })
            .collect();
        // Each node is built once: by its own subtree's call.
        let _ = self.blobs[i].set(out);
        self.meter.add(self.levels.len() as u64);
        Ok(mine)
    }

    /// Leaf `i`'s surfaces on `grid`: the union of its shell's blobs lifted
    /// when they lie on that grid or a finer one nested in it, else its
    /// meshes voxelized.
    fn leaf(&self, i: usize, grid: &Grid) -> Result<Voxels, crate::Error> {
        let blobs = self.shells.get(i).map_or(&[][..], Vec::as_slice);
        let mut shell = Voxels::empty(grid.clone());
        let lifted = !blobs.is_empty()
            && blobs.iter().all(|b| {
                crate::lod::decode(b, &self.rule.lattice, &self.plan.frames[i])
                    .is_ok_and(|v| v.lift_into(&mut shell).is_ok())
            });
        if lifted {
            return Ok(shell);
        }
        let meshes: Vec<Cow<Mesh>> = (0..self.plan.entries[i].len())
            .map(|j| self.plan.entry_mesh(self.objects, i, j))
            .collect::<Result<_, _>>()?;
        Ok(leaf_group(grid.clone(), meshes.iter().map(|m| m.as_ref())))
    }
}
