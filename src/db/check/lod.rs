//! `check` for the levels of detail below M (format-spec/lod.md): every
//! stored bound contains the objects it bounds (vertices, edge midpoints and
//! triangle centroids), a level lies inside the level below it and inside
//! its ancestors', grids are no coarser than the level's eps, the sampled
//! error stays below eps, and every spread entry's predicted reads equal the
//! blocks its fetch reads.

use std::collections::{BTreeSet, HashMap};

use super::super::lod::fetch_reads;
use super::super::{NodeLocation, Piece, ReadTransaction};
use crate::geom::Point;
use crate::lod::{ErrorProbe, Voxels};
use crate::scene::{Mesh, ObjectId};
use crate::store::ReadStats;
use crate::store::format::node::{LodRef, NodeRecord};

/// Cells sampled per bound when `check` measures an error.
const ERROR_SAMPLES: usize = 32;
/// Rounding allowance on distances compared with eps.
fn tolerance(eps: f64) -> f64 {
    eps * 1e-9 + 1e-9
}

/// A node on the current root-to-node path, with its stored group sets by level.
struct OnPath {
    here: String,
    /// Index k - 1: the set b(S_n,k) resolves to, if it is one stored here, with the level it resolves to.
    sets: Vec<Option<(u8, Voxels)>>,
}

/// The state of the LOD checks through one traversal.
pub(super) struct LodChecker {
    m: u8,
    eps: Vec<f64>,
    path: Vec<OnPath>,
    /// Every record, by node id, with its node block and children (for the read predictions).
    records: Vec<(u32, NodeRecord)>,
    /// LOD blocks seen, by the level whose blobs they hold.
    blocks: Vec<BTreeSet<u32>>,
    pub(super) faults: Vec<String>,
}

impl LodChecker {
    pub(super) fn new(txn: &ReadTransaction) -> LodChecker {
        let info = txn.lod_info();
        let m = txn.pager().lod_levels();
        LodChecker {
            m,
            eps: info.map(|i| i.eps).unwrap_or_default(),
            path: Vec::new(),
            records: Vec::new(),
            blocks: vec![BTreeSet::new(); usize::from(m)],
            faults: Vec::new(),
        }
    }

    fn fault(&mut self, f: String) {
        self.faults.push(f);
    }

    /// Checks node `rec`'s own entries below M and pushes it on the path.
    /// Returns the LOD blocks and runs its entries name, for the caller to
    /// claim (a LOD block is shared by many entries: claimed once).
    pub(super) fn visit_node(
        &mut self,
        txn: &ReadTransaction,
        at: NodeLocation,
        rec: &NodeRecord,
        here: &str,
    ) -> Vec<LodRef> {
        self.records.push((at.block, rec.clone()));
        self.path.truncate(usize::from(rec.level));
        let m = self.m;
        let mut named = Vec::new();
        if m >= 2 && rec.lods[0][0] != LodRef::InRecord {
            self.fault(format!("{here}: b(S_n,1) must be the record's box"));
        }
        let mut sets: Vec<Option<(u8, Voxels)>> = vec![None; usize::from(m)];
        let mut own: Vec<Option<Voxels>> = vec![None; usize::from(m)];
        for k in 1..m {
            for obj in [false, true] {
                let e = rec.lods[usize::from(k) - 1][usize::from(obj)];
                if matches!(e, LodRef::Absent) {
                    self.fault(format!("{here}: level {k} is not stored"));
                    continue;
                }
                if !matches!(e, LodRef::InBlock { .. } | LodRef::Run { .. }) {
                    continue;
                }
                named.push(e);
                if let Some((b, _)) = e.block() {
                    self.blocks[usize::from(k) - 1].insert(b);
                }
                let mut stats = ReadStats::default();
                match txn.fetch_level(at, k, obj, &mut stats) {
                    Ok(level) => {
                        if stats.total() != e.reads() {
                            self.fault(format!(
                                "{here}: level {k} took {} reads, {} predicted",
                                stats.total(),
                                e.reads()
                            ));
                        }
                        for p in level.pieces {
                            self.check_piece(here, k, rec, p, &mut own);
                        }
                    }
                    Err(err) => self.fault(format!("{here}: level {k}: {err}")),
                }
            }
        }
        // What each level of b(S_n,k) resolves to, when it is a set stored here.
        for k in 2..m {
            if let Some((tk, false, LodRef::InBlock { .. } | LodRef::Run { .. })) = rec.entry(k, false)
                && tk < m
                && let Some(v) = &own[usize::from(tk) - 1]
            {
                sets[usize::from(k) - 1] = Some((tk, v.clone()));
            }
        }
        // Nesting: each set stored here lies in the nearest set that level
        // j <= k resolves to (at a level <= k), here or in an ancestor; the
        // rest follows by transitivity.
        for k in 2..m {
            let Some(v) = &own[usize::from(k) - 1] else { continue };
            for j in 2..=k {
                let fits =
                    |s: &Option<(u8, Voxels)>| s.as_ref().filter(|(tk, _)| *tk <= k).map(|(_, s)| s.clone());
                let mine =
                    if j < k { fits(&sets[usize::from(j) - 1]).map(|s| (here.to_string(), s)) } else { None };
                let above = mine.or_else(|| {
                    self.path
                        .iter()
                        .rev()
                        .find_map(|p| fits(&p.sets[usize::from(j) - 1]).map(|s| (p.here.clone(), s)))
                });
                if let Some((owner, s)) = above {
                    match v.is_subset_of(&s) {
                        Ok(true) => {}
                        Ok(false) => {
                            self.faults.push(format!("{here}: b(S_n,{k}) is not inside level {j} of {owner}"))
                        }
                        Err(e) => {
                            self.faults.push(format!("{here}: level {k} against level {j} of {owner}: {e}"))
                        }
                    }
                }
            }
        }
        self.path.push(OnPath { here: here.to_string(), sets });
        named
    }

    /// Checks a decoded piece of entry k of `rec`; keeps b(S_n,k) sets in `own`.
    fn check_piece(&mut self, here: &str, k: u8, rec: &NodeRecord, p: Piece, own: &mut [Option<Voxels>]) {
        let eps = self.eps.get(usize::from(k) - 1).copied().unwrap_or(0.0);
        match p {
            Piece::Voxels { voxels, .. } => {
                self.check_grid(here, k, &voxels, eps);
                if !rec.aabb().contains(voxels.grid().bounds()) {
                    self.fault(format!("{here}: b(S_n,{k}) reaches outside the node's box"));
                }
                own[usize::from(k) - 1] = Some(voxels);
            }
            Piece::ObjectVoxels(sets) => {
                for (id, v) in &sets {
                    self.check_grid(&format!("{here}, object {id}"), k, v, eps);
                }
            }
            Piece::ObjectBoxes(_) | Piece::Box { .. } | Piece::Objects(_) => {}
        }
    }

    fn check_grid(&mut self, here: &str, k: u8, v: &Voxels, eps: f64) {
        let d = v.grid().max_cell_diagonal();
        if d > eps + tolerance(eps) {
            self.fault(format!("{here}: level {k}'s cells are {d} mm across, above eps {eps}"));
        }
    }

    /// With a leaf's exact objects in hand: each object lies in its own
    /// bounds at every level and in every stored b(S_n,k) on the path, and
    /// each object's bounds nest and stay within eps of it.
    pub(super) fn visit_leaf_objects(
        &mut self,
        txn: &ReadTransaction,
        at: NodeLocation,
        here: &str,
        objects: &[(ObjectId, Mesh)],
    ) {
        let m = self.m;
        let samples: Vec<(ObjectId, Vec<Point>)> =
            objects.iter().map(|(id, mesh)| (*id, surface_samples(mesh))).collect();
        // The objects' own bounds, level by level.
        let mut per: HashMap<ObjectId, Vec<Option<Voxels>>> = HashMap::new();
        for k in 1..m {
            let mut stats = ReadStats::default();
            let pieces = match txn.fetch_level(at, k, true, &mut stats) {
                Ok(l) => l.pieces,
                Err(e) => {
                    self.fault(format!("{here}: B(S_n,{k}): {e}"));
                    continue;
                }
            };
            for p in pieces {
                match p {
                    Piece::ObjectBoxes(boxes) => {
                        for (id, b) in boxes {
                            if let Some((_, mesh)) = objects.iter().find(|o| o.0 == id)
                                && !b.contains(&mesh.aabb())
                            {
                                self.fault(format!("{here}: object {id}'s level-1 box does not hold it"));
                            }
                        }
                    }
                    Piece::ObjectVoxels(sets) => {
                        for (id, v) in sets {
                            per.entry(id).or_insert_with(|| vec![None; usize::from(m)])[usize::from(k) - 1] =
                                Some(v);
                        }
                    }
                    // B pointing to b, or to a coarser or exact level: checked through the path.
                    _ => {}
                }
            }
        }
        // Per level, the nearest set on the path: the rest of the path holds
        // it (the nesting check in `visit_node`), so it holds the objects too.
        let nearest: Vec<(&String, u8, &Voxels)> = (0..usize::from(m))
            .filter_map(|j| {
                self.path.iter().rev().find_map(|p| p.sets[j].as_ref().map(|(tk, s)| (&p.here, *tk, s)))
            })
            .collect();
        let mut outside = Vec::new();
        for (id, points) in &samples {
            for (owner, tk, s) in &nearest {
                if let Some(p) = points.iter().find(|p| !s.contains_point(p)) {
                    outside
                        .push(format!("{here}: object {id}'s point {p:?} is outside level {tk} of {owner}"));
                }
            }
        }
        self.faults.extend(outside);
        // The leaf's own sets stay within eps of its objects.
        if let Some(last) = self.path.last() {
            let probe = ErrorProbe::new(objects.iter().map(|(_, m)| m));
            let mut far = Vec::new();
            for (tk, v) in last.sets.iter().flatten() {
                let eps = self.eps.get(usize::from(*tk) - 1).copied().unwrap_or(0.0);
                let e = probe.measure(v, ERROR_SAMPLES);
                if e > eps + tolerance(eps) {
                    far.push(format!("{here}: b(S_n,{tk}) is {e} mm from its objects, eps {eps}"));
                }
            }
            self.faults.extend(far);
        }
        for ((id, mesh), (_, points)) in objects.iter().zip(&samples) {
            let Some(levels) = per.get(id) else { continue };
            let probe = ErrorProbe::new([mesh]);
            let mut coarser: Option<&Voxels> = None;
            for (k, v) in levels.iter().enumerate() {
                let Some(v) = v else { continue };
                let k = k + 1;
                if let Some(p) = points.iter().find(|p| !v.contains_point(p)) {
                    self.faults.push(format!("{here}: object {id}'s point {p:?} is outside b(o,{k})"));
                }
                let eps = self.eps.get(k - 1).copied().unwrap_or(0.0);
                let e = probe.measure(v, ERROR_SAMPLES);
                if e > eps + tolerance(eps) {
                    self.faults.push(format!("{here}: b(o,{k}) of object {id} is {e} mm from it, eps {eps}"));
                }
                if let Some(c) = coarser
                    && !matches!(v.is_subset_of(c), Ok(true))
                {
                    self.faults
                        .push(format!("{here}: b(o,{k}) of object {id} is not inside the level below"));
                }
                coarser = Some(v);
            }
        }
    }

    /// After the walk: every spread entry predicts the reads its fetch
    /// takes, and the meta block's per-level usage matches the blobs.
    pub(super) fn finish(&mut self, usage_blocks: &[u64]) {
        let children = child_indices(&self.records);
        let mut faults = Vec::new();
        for (i, (_, rec)) in self.records.iter().enumerate() {
            for k in 1..=self.m {
                for obj in [false, true] {
                    if let LodRef::Spread { reads } = rec.lods[usize::from(k) - 1][usize::from(obj)] {
                        let want = fetch_reads(
                            i,
                            k,
                            obj,
                            |j, k, obj| self.records[j].1.lods[usize::from(k) - 1][usize::from(obj)],
                            |j| children[j],
                            |j| self.records[j].0,
                        );
                        if u64::from(reads) != want {
                            faults.push(format!(
                                "node {}: level {k} predicts {reads} reads, its fetch takes {want}",
                                rec.node_id
                            ));
                        }
                    }
                }
            }
        }
        self.faults.extend(faults);
        for k in 0..usize::from(self.m.saturating_sub(1)) {
            let blocks = self.blocks[k].len() as u64;
            if usage_blocks.get(k).copied().unwrap_or(0) != blocks {
                self.fault(format!(
                    "meta says level {} uses {} blocks, its entries name {blocks}",
                    k + 1,
                    usage_blocks.get(k).copied().unwrap_or(0)
                ));
            }
        }
    }
}

/// Each record's children as indices into `records` (preorder: the first
/// child follows its parent, the second follows the first child's subtree).
fn child_indices(records: &[(u32, NodeRecord)]) -> Vec<Option<[usize; 2]>> {
    let n = records.len();
    let mut size = vec![1usize; n];
    let mut out = vec![None; n];
    for i in (0..n).rev() {
        if records[i].1.children.is_some() && i + 1 < n {
            let left = i + 1;
            let right = left + size[left];
            if right < n {
                size[i] = 1 + size[left] + size[right];
                out[i] = Some([left, right]);
            }
        }
    }
    out
}

/// Points of a mesh's surface to test containment with: its vertices,
/// edge midpoints and triangle centroids.
fn surface_samples(mesh: &Mesh) -> Vec<Point> {
    let mut out: Vec<Point> = mesh.vertices().collect();
    for [a, b, c] in mesh.triangle_points() {
        out.push(Point::from((a.coords + b.coords + c.coords) / 3.0));
        out.push(nalgebra::center(&a, &b));
        out.push(nalgebra::center(&b, &c));
        out.push(nalgebra::center(&c, &a));
    }
    out
}
