//! `check`: verifies every block's checksum, that every block is reachable
//! or free exactly once, and every rule of the tree as the one traversal
//! walks it: the objects' partition (each id in exactly one leaf, its parts
//! consecutive and of one anchor, each record's id its entry's), each object
//! inside its stored box and tight on every face of it (the box witnesses
//! contact), each stored bound exactly the cells its surface touches on the
//! grid its level's rules give (so it both rules contact out and proves it),
//! encoded as the writer encodes it, within eps_k, the block counts every
//! child entry predicts, and the meta block's totals. Whatever it sizes, it
//! sizes by what it has read, never by a count the file states.
//!
//! `check` is a reader (format-spec/commit.md, "Many processes"): it pins
//! the newest snapshot and never keeps writers out. A writer may meanwhile
//! fill blocks that are free in that snapshot, so a free block that fails
//! its checksum is read again after the scan, and set aside when a writer
//! holds the lock, a commit landed, or a write was interrupted. One that no
//! writer explains is a warning, not a fault: it holds nothing, and a
//! commit interrupted before its pending mark was synced may have torn it
//! (format-spec/commit.md, step 1). The counts by block type then may
//! include such blocks as their new type.

use std::collections::{BTreeMap, HashMap, HashSet};
use std::sync::Arc;

mod keys;

use super::{Database, ReadTransaction, Reads, TreeInfo, Warning, view, walk_everything};
use crate::geom::{Aabb, Point};
use crate::lod::{LodParams, LodPlan, Voxels, bound_grid};
use crate::query::Visitor;
use crate::scene::Mesh;
use crate::store::format::frame::{self, BlockType};
use crate::store::format::freelist::{FreeListBlock, FreeRange};
use crate::store::format::header::Commit;
use crate::store::format::keys::TreePath;
use crate::store::format::meta::Meta;
use crate::store::format::node::{self, BoundView, LeafView, NodeView};
use crate::store::format::quant::QuantBox;
use crate::store::{Block, ReadStats, StorageError};
use keys::{KeyedObject, KeyedObjects};

/// What `check` found.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct CheckReport {
    /// The commit checked (its transaction id).
    pub txn: u64,
    /// File length in blocks at that commit.
    pub file_blocks: u32,
    /// Blocks whose frame verifies, by type name.
    pub blocks_by_type: BTreeMap<String, u64>,
    /// Blocks on the free list.
    pub free_blocks: u64,
    /// Objects in the tree.
    pub objects: u64,
    /// Nodes the walk of the tree reached, leaves included.
    pub nodes: u64,
    /// A write transaction was interrupted; its torn free blocks are not faults.
    pub interrupted: bool,
    /// What is damaged or torn but loses nothing: a slot copy failing its
    /// checksum while the other copy holds the slot. A crash can leave one
    /// too, so it is not a fault; the next write transaction repairs it.
    pub warnings: Vec<String>,
    /// Every fault found; empty when the file is sound.
    pub faults: Vec<String>,
}

impl CheckReport {
    /// True when no fault was found.
    pub fn ok(&self) -> bool {
        self.faults.is_empty()
    }
}

#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Owner {
    Unseen,
    Header,
    Free,
    Used(BlockType),
}

struct Checker {
    owner: Vec<Owner>,
    report: CheckReport,
}

impl Checker {
    fn fault(&mut self, f: impl Into<String>) {
        self.report.faults.push(f.into());
    }

    fn claim(&mut self, block: u32, owner: Owner) {
        match self.owner.get(block as usize).copied() {
            None => self.fault(format!("block {block} is referenced but past the end of the file")),
            Some(Owner::Unseen) => self.owner[block as usize] = owner,
            Some(prev) => self.fault(format!("block {block} is claimed twice ({prev:?} and {owner:?})")),
        }
    }
}

/// Verifies the whole of `db` (see the module doc).
pub fn check(db: &Database) -> Result<CheckReport, StorageError> {
    let (txn, commit, free, warnings) = pinned(db)?;
    let pager = db.pager();
    let mut c = Checker {
        owner: vec![Owner::Unseen; commit.block_count as usize],
        report: CheckReport { txn: commit.txn, file_blocks: commit.block_count, ..CheckReport::default() },
    };
    for w in warnings {
        match w {
            Warning::Interrupted => c.report.interrupted = true,
            w => c.report.warnings.push(format!("block 0: {w}")),
        }
    }
    let torn_may_be_free = c.report.interrupted;
    let free: Vec<(u32, u32)> = free.iter().map(|r| (r.first, r.count)).collect();
    let is_free = |id: u32| {
        let i = free.partition_point(|&(f, _)| f <= id);
        i > 0 && id - free[i - 1].0 < free[i - 1].1
    };
    c.owner[0] = Owner::Header;
    // Every block's checksum, whatever it holds. A free block that fails
    // (or is gone: a compaction may cut the free end) is judged after the
    // scan, once it is known whether a writer wrote meanwhile.
    let mut free_failed = Vec::new();
    for id in 1..commit.block_count {
        let raw = match pager.read_raw(id) {
            Ok(raw) => raw,
            Err(_) if is_free(id) => {
                free_failed.push(id);
                continue;
            }
            Err(e) => return Err(e),
        };
        match frame::open(id, &raw) {
            Ok((_, t)) => *c.report.blocks_by_type.entry(t.name().to_string()).or_default() += 1,
            // An interrupted transaction may have torn the free blocks it wrote.
            Err(_) if torn_may_be_free && is_free(id) => {}
            Err(_) if is_free(id) => free_failed.push(id),
            Err(e) => c.fault(e.to_string()),
        }
    }
    for id in free_failed {
        if let Some(damage) = free_block_damage(db, &commit, id)? {
            c.report.warnings.push(format!("free block {id}, which holds nothing: {damage}"));
        }
    }
    for &(first, count) in &free {
        c.report.free_blocks += u64::from(count);
        for b in first..first + count {
            c.claim(b, Owner::Free);
        }
    }
    let mut next = (commit.freelist_block, commit.freelist_checksum);
    while next.0 != 0 {
        c.claim(next.0, Owner::Used(BlockType::FreeList));
        let (b, _) = pager.read(next.0, BlockType::FreeList, Some(next.1), &mut ReadStats::default())?;
        let fl = FreeListBlock::decode(next.0, &b)?;
        next = (fl.next_block, fl.next_checksum);
    }
    if commit.meta_block != 0 {
        c.claim(commit.meta_block, Owner::Used(BlockType::Meta));
        check_tree(&mut c, &txn)?;
    }
    for (b, o) in c.owner.clone().iter().enumerate() {
        if *o == Owner::Unseen {
            c.fault(format!("block {b} is neither reachable nor free"));
        }
    }
    Ok(c.report)
}

/// A read transaction on the newest snapshot, with that snapshot's commit,
/// free ranges and header warnings. Other processes' commits may land
/// between the pin and the look at the committed state: then pin again.
fn pinned(db: &Database) -> Result<(ReadTransaction, Commit, Vec<FreeRange>, Vec<Warning>), StorageError> {
    const ATTEMPTS: u32 = 100;
    for _ in 0..ATTEMPTS {
        let txn = db.begin_read()?;
        let (commit, free, warnings) = db.committed()?;
        if commit.txn == txn.snapshot.txn {
            return Ok((txn, commit, free, warnings));
        }
    }
    Err(StorageError::Contended { attempts: ATTEMPTS })
}

/// Free block `id` of `commit` failed its checksum (or could not be read)
/// in the scan: the failure, unless a writer may have been writing it. Free
/// blocks are a writer's to fill, so only a failure that no writer
/// explains is reported.
fn free_block_damage(db: &Database, commit: &Commit, id: u32) -> Result<Option<String>, StorageError> {
    let written = |db: &Database| -> Result<bool, StorageError> {
        if db.writer_active()? {
            return Ok(true);
        }
        // A fresh reader brings the committed state and its warnings up to date.
        drop(db.begin_read()?);
        let (now, _, warnings) = db.committed()?;
        Ok(now.txn != commit.txn || warnings.contains(&Warning::Interrupted))
    };
    if written(db)? {
        return Ok(None);
    }
    let fault = match db.pager().read_raw(id) {
        Ok(raw) => match frame::open(id, &raw) {
            Ok(_) => return Ok(None),
            Err(e) => e.to_string(),
        },
        Err(e) => e.to_string(),
    };
    // A writer that began after the first look may have torn it since.
    Ok(if written(db)? { None } else { Some(fault) })
}

/// What the walk learns of one record, for the checks that need the whole tree.
struct NodeFacts {
    id: u32,
    block: u32,
    depth: u32,
    /// Internal: the children's records and the counts the entries claim.
    children: Option<[ChildFacts; 2]>,
    /// Leaf: its geometry blocks.
    geometry: Vec<u32>,
    objects: u32,
    /// Its block's group block, and the group bounds its flags name there.
    group: Option<(u32, u32)>,
    group_levels: u32,
}

/// A child entry: where its record is (block, offset), and the (node,
/// geometry) block counts it claims.
type ChildFacts = ((u32, u32), (u32, u32));

/// Checks each record as the one traversal meets it.
struct Walker<'t> {
    txn: &'t ReadTransaction,
    reads: Reads<'static>,
    faults: Vec<String>,
    facts: Vec<NodeFacts>,
    at: HashMap<(u32, u32), usize>,
    depth_of: HashMap<(u32, u32), u32>,
    /// The path from the root to each record, as the walk met its parent.
    path_of: HashMap<(u32, u32), TreePath>,
    /// The object ids met: as many as the leaves hold, whatever the meta block says.
    seen: HashSet<u32>,
    objects: u32,
    /// How the writer chose each level's grids, from the meta block (none without a lattice).
    rules: Option<(LodPlan, LodParams)>,
    eps: Vec<f64>,
    triangles: u64,
    vertices: u64,
    /// Per object id: its key, where its first entry is, and the union of its parts' boxes.
    keyed: KeyedObjects,
}

impl Walker<'_> {
    /// Checks bound `b` of an entry whose box, as its leaf holds it, is
    /// `outer` and whose geometry is `mesh` (format-spec/lod.md).
    fn check_bound(&self, b: &BoundView, outer: &Aabb, mesh: &Mesh) -> Result<(), String> {
        let (plan, params) = self.rules.as_ref().ok_or("the meta block has no lattice")?;
        let v = crate::lod::decode(b.blob, &plan.lattice, outer).map_err(|e| e.to_string())?;
        let k = b.level;
        let grid = bound_grid(plan, params, k, outer)
            .map_err(|e| e.to_string())?
            .ok_or("its level's rules give no grid over the box")?;
        if *v.grid() != grid {
            return Err(format!(
                "lies on lattice level {}, its level's rules give {}",
                v.grid().level(),
                grid.level()
            ));
        }
        // What the writer stores, and what bounds the voxelization below.
        if grid.cells() > u64::from(u16::MAX) {
            return Err(format!("has {} cells, more than the 65,535 a stored bound has", grid.cells()));
        }
        // The writer's conservative test: a cell is set when a triangle touches it.
        let exact = Voxels::of_surfaces(grid, [mesh]);
        if !exact.is_subset_of(&v).unwrap_or(false) {
            return Err("does not hold its surface".into());
        }
        // A cell the surface does not touch would prove a contact that is not there.
        if exact != v {
            return Err("sets cells its surface does not touch".into());
        }
        if crate::lod::encode(&v) != b.blob {
            return Err("is not encoded as the writer encodes its cells".into());
        }
        let eps = self.eps.get(usize::from(k) - 1).copied().unwrap_or(0.0);
        if v.grid().max_cell_diagonal() > eps * (1.0 + 1e-9) {
            return Err(format!("has cells wider than eps_{k} = {eps}"));
        }
        Ok(())
    }

    /// Each object of `leaf` (record `offset` of `block`, whose box is
    /// `frame`): read whole, once, inside its tight stored box, with its
    /// bounds on their grids and within their eps.
    fn check_objects(&mut self, here: &str, block: &Arc<Block>, offset: u32, frame: &Aabb, leaf: &LeafView) {
        // The previous entry's id and anchor, when its record was read.
        let mut previous: Option<(u32, Point)> = None;
        for i in 0..leaf.len() {
            let Some(o) = leaf.object(i) else { continue };
            let (id, mesh) = match self.txn.read_object(block.id(), leaf, i, &mut self.reads) {
                Ok(x) => x,
                Err(e) => {
                    self.faults.push(format!("{here}: {e}"));
                    previous = None;
                    continue;
                }
            };
            self.triangles += mesh.triangle_count() as u64;
            self.vertices += mesh.vertex_count() as u64;
            // An object's parts are consecutive entries of one leaf.
            let part_of_previous = i > 0 && leaf.object(i - 1).is_some_and(|p| p.object_id == id.0);
            if id.0 >= self.objects || !self.seen.insert(id.0) && !part_of_previous {
                self.faults.push(format!("{here}: object {id} appears twice or is out of range"));
            }
            // Every part carries its object's anchor: a part relabelled
            // as its neighbour's has another one.
            if previous.is_some_and(|(p, a)| p == id.0 && a != mesh.anchor()) {
                self.faults.push(format!("{here}: object {id}'s parts have different anchors"));
            }
            previous = Some((id.0, mesh.anchor()));
            let path = self.path_of.get(&(block.id(), offset)).copied().unwrap_or_default();
            let k = self.keyed.entry(id.0, || KeyedObject { key: leaf.key(i), path, aabb: Aabb::EMPTY });
            k.aabb = k.aabb.union(&mesh.aabb());
            let Some(q) = QuantBox::decode(frame, o.qbox) else {
                self.faults.push(format!("{here}: object {id}'s box is backwards"));
                continue;
            };
            let b = mesh.aabb();
            if !q.outer.contains(&b) {
                self.faults.push(format!("{here}: object {id} lies outside its stored box"));
            }
            // Each face of the stored box must hold the true face: the box witnesses contact.
            let tight = (0..3).all(|a| {
                let (lower, upper) = (q.lower_face(a), q.upper_face(a));
                (lower.0..=lower.1).contains(&b.min[a]) && (upper.0..=upper.1).contains(&b.max[a])
            });
            if !tight {
                self.faults.push(format!("{here}: object {id}'s stored box is not tight on its surface"));
            }
            for bound in leaf.bounds().filter(|x| usize::from(x.target) == i) {
                if let Err(e) = self.check_bound(&bound, &q.outer, &mesh) {
                    self.faults.push(format!("{here}: object {id}'s bound at level {}: {e}", bound.level));
                }
            }
        }
    }
}

impl Visitor for Walker<'_> {
    fn node(&mut self, block: &Arc<Block>, offset: u32, frame: &Aabb) -> Result<(), StorageError> {
        let rec = view(block, offset)?;
        let here = format!("node {} (block {}, offset {offset})", rec.node_id(), block.id());
        let depth = self.depth_of.get(&(block.id(), offset)).copied().unwrap_or(0);
        let mut facts = NodeFacts {
            id: rec.node_id(),
            block: block.id(),
            depth,
            children: None,
            geometry: Vec::new(),
            objects: rec.object_count(),
            group: node::group_ref(block.bytes()),
            group_levels: 0,
        };
        // Each group bound the flags name is in the group block, on its grid (format-spec/group.md).
        for k in rec.group_levels() {
            facts.group_levels += 1;
            match self.txn.group_bound(block, offset, frame, k, &mut self.reads) {
                Ok(Some(_)) => {}
                Ok(None) => self.faults.push(format!("{here}: its group bound at level {k} is missing")),
                Err(e) => self.faults.push(format!("{here}: its group bound at level {k}: {e}")),
            }
        }
        match rec {
            NodeView::Internal(n) => {
                let mut kids = [((0, 0), (0, 0)); 2];
                for (i, kid) in kids.iter_mut().enumerate() {
                    let r = n.child_ref(i);
                    let b = if r.block == 0 { block.id() } else { r.block };
                    *kid = ((b, r.offset), n.child_blocks(i));
                    self.depth_of.insert((b, r.offset), depth + 1);
                    let path = self.path_of.get(&(block.id(), offset)).copied().unwrap_or_default();
                    self.path_of.insert((b, r.offset), path.child(i));
                }
                facts.children = Some(kids);
            }
            NodeView::Leaf(leaf) => {
                let (first, sums) = leaf.geometry();
                facts.geometry = (0..sums.len() as u32).map(|i| first.saturating_add(i)).collect();
                self.check_objects(&here, block, offset, frame, &leaf);
            }
        }
        self.at.insert((block.id(), offset), self.facts.len());
        self.facts.push(facts);
        Ok(())
    }
}

fn check_tree(c: &mut Checker, txn: &ReadTransaction) -> Result<(), StorageError> {
    let Some(info) = txn.info() else { return Ok(()) };
    let Some(root) = txn.root() else { return Ok(()) };
    let meta = txn.snapshot.meta.clone().unwrap_or_default();
    let objects = object_room(info.objects, c.owner.len(), txn.pager().block_size());
    let mut w = Walker {
        txn,
        reads: Reads::new(None),
        faults: Vec::new(),
        facts: Vec::new(),
        at: HashMap::new(),
        depth_of: HashMap::new(),
        path_of: HashMap::new(),
        seen: HashSet::with_capacity(objects),
        objects: meta.object_ids,
        rules: super::lod::bound_rules(txn),
        eps: txn.lod_info().map(|l| l.eps).unwrap_or_default(),
        triangles: 0,
        vertices: 0,
        keyed: KeyedObjects::with_capacity(objects),
    };
    walk_everything(txn, root, &mut Reads::new(None), &mut w)?;
    c.report.faults.append(&mut w.faults);
    let (node_blocks, geometry_blocks, group_levels) = claim_blocks(c, &w.facts, &meta);
    check_group_blocks(c, txn, group_levels);
    check_child_counts(c, &w);
    check_totals(c, &info, &meta, &w, (node_blocks, geometry_blocks));
    w.keyed.sort();
    keys::check_keys(c, txn, &meta, &w.keyed)
}

/// Room for the per-object tables: the objects the meta block counts, made
/// at once, not grown by doubling (which holds the old table beside the
/// new), and no more than the file's blocks can hold entries for, so that
/// a hostile count sizes nothing.
fn object_room(objects: u32, blocks: usize, block_size: u32) -> usize {
    let entries = blocks.saturating_mul(block_size as usize / node::OBJECT_LEN);
    (objects as usize).min(entries)
}

/// Claims each node, group and geometry block of the tree for `c`'s map
/// of the file, checking node ids and that each block is claimed once:
/// the node and geometry blocks counted, and per group block the bounds
/// its node block's records name.
fn claim_blocks(c: &mut Checker, facts: &[NodeFacts], meta: &Meta) -> (u64, u64, HashMap<(u32, u32), u32>) {
    // Preorder ids (or, after a split or merge, ids unique below `node_ids`), and each block claimed once.
    let mut node_blocks = HashSet::new();
    let mut geometry_blocks = HashSet::new();
    // Per group block: the group bounds its node block's records name.
    let mut group_levels: HashMap<(u32, u32), u32> = HashMap::new();
    let mut parent_block: HashMap<u32, u32> = HashMap::new();
    let mut ids = HashSet::new();
    for (i, f) in facts.iter().enumerate() {
        if meta.node_ids == 0 && f.id as usize != i {
            c.fault(format!("node {} is met at preorder position {i}", f.id));
        }
        if meta.node_ids != 0 && (f.id >= meta.node_ids || !ids.insert(f.id) || (i == 0) != (f.id == 0)) {
            c.fault(format!(
                "node {} at preorder position {i}: not a unique id below {}",
                f.id, meta.node_ids
            ));
        }
        if node_blocks.insert(f.block) {
            c.claim(f.block, Owner::Used(BlockType::Node));
            if let Some((g, _)) = f.group {
                c.claim(g, Owner::Used(BlockType::Group));
            }
        }
        if let Some(g) = f.group {
            *group_levels.entry(g).or_insert(0) += f.group_levels;
        }
        // A leaf's span holds no other leaf's records (format-spec/geometry.md).
        for &g in &f.geometry {
            if geometry_blocks.insert(g) {
                c.claim(g, Owner::Used(BlockType::Geometry));
            } else {
                c.fault(format!("node {}: geometry block {g} holds another leaf's records too", f.id));
            }
        }
        // A node block's records are named from one other block at most
        // (format-spec/node.md, "Packing"): a change commit rewrites a
        // block's one parent block with it.
        for ((b, _), _) in f.children.into_iter().flatten() {
            if b != f.block && *parent_block.entry(b).or_insert(f.block) != f.block {
                c.fault(format!("node block {b} is named from blocks {} and {}", parent_block[&b], f.block));
            }
        }
    }
    (node_blocks.len() as u64, geometry_blocks.len() as u64, group_levels)
}

fn check_group_blocks(c: &mut Checker, txn: &ReadTransaction, group_levels: HashMap<(u32, u32), u32>) {
    // A group block holds the bounds its node block's records name, and no other.
    for ((g, sum), named) in group_levels {
        match txn.block(g, BlockType::Group, sum, &mut Reads::new(None)) {
            Ok(b) if b.groups.len() as u32 != named => c.fault(format!(
                "group block {g} holds {} bounds, its node block's records name {named}",
                b.groups.len()
            )),
            Ok(_) => {}
            Err(e) => c.fault(format!("group block {g}: {e}")),
        }
    }
}

fn check_child_counts(c: &mut Checker, w: &Walker) {
    // Each child entry's counts: (at least) the distinct node blocks of its
    // subtree other than the parent's, and the geometry blocks of its objects.
    let n = w.facts.len();
    let mut sub_nodes: Vec<HashSet<u32>> = vec![HashSet::new(); n];
    let mut sub_geometry: Vec<HashSet<u32>> = vec![HashSet::new(); n];
    for i in (0..n).rev() {
        let f = &w.facts[i];
        let mut nodes = HashSet::from([f.block]);
        let mut geometry: HashSet<u32> = f.geometry.iter().copied().collect();
        if let Some(kids) = f.children {
            let mut objects = 0u64;
            for ((at, (nb, gb)), _) in kids.iter().zip(0..) {
                let Some(&j) = w.at.get(at) else { continue };
                let mut below = sub_nodes[j].clone();
                below.remove(&f.block);
                // Node blocks are exact after a bulk load and at most a bound after
                // change commits (format-spec/commit.md, "Change commits").
                if below.len() as u64 > u64::from(*nb) || sub_geometry[j].len() as u64 != u64::from(*gb) {
                    c.fault(format!(
                        "node {}: a child entry predicts {nb} node and {gb} geometry blocks, the subtree has {} and {}",
                        f.id,
                        below.len(),
                        sub_geometry[j].len()
                    ));
                }
                objects += u64::from(w.facts[j].objects);
                nodes.extend(sub_nodes[j].iter());
                geometry.extend(sub_geometry[j].iter());
            }
            if objects != u64::from(f.objects) {
                c.fault(format!("node {}: {} objects, children hold {objects}", f.id, f.objects));
            }
        }
        sub_nodes[i] = nodes;
        sub_geometry[i] = geometry;
    }
}

/// The tree's totals against the meta block's.
fn check_totals(
    c: &mut Checker,
    info: &TreeInfo,
    meta: &Meta,
    w: &Walker,
    (node_blocks, geometry_blocks): (u64, u64),
) {
    // Ids are unique below `object_ids` (checked per entry); the tree holds as many as the meta block counts.
    let n = w.facts.len();
    if w.seen.len() as u64 != u64::from(info.objects) {
        c.fault(format!("meta says {} objects, the tree's leaves hold {}", info.objects, w.seen.len()));
    }
    let leaves = w.facts.iter().filter(|f| f.children.is_none()).count() as u64;
    let depth = w.facts.iter().map(|f| f.depth).max().unwrap_or(0);
    let expect = [
        ("nodes", n as u64, u64::from(info.nodes)),
        ("leaves", leaves, u64::from(info.leaves)),
        ("depth", u64::from(depth), u64::from(info.depth)),
        ("node blocks", node_blocks, u64::from(info.node_blocks)),
        ("geometry blocks", geometry_blocks, info.geometry_blocks),
        ("triangles", w.triangles, info.triangles),
        ("vertices", w.vertices, info.vertices),
    ];
    for (what, got, want) in expect {
        // A merge may leave the meta block's depth deeper than the tree (format-spec/meta.md).
        let bound = what == "depth" && meta.node_ids != 0;
        if got != want && !(bound && got < want) {
            c.fault(format!("meta says {want} {what}, the tree has {got}"));
        }
    }
    c.report.objects = u64::from(info.objects);
    c.report.nodes = n as u64;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_object_tables_take_room_for_no_more_entries_than_the_blocks_hold() {
        assert_eq!(object_room(10_000_000, 725_437, 16_384), 10_000_000);
        // A 16 KiB block holds at most 819 entries of 20 bytes.
        assert_eq!(object_room(u32::MAX, 10, 16_384), 8_190);
        assert_eq!(object_room(5, 0, 16_384), 0);
    }
}
