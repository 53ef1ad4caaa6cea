//! `check`: verifies every block's checksum, that every block is reachable
//! or free exactly once, and every structural rule of the tree: partition of
//! objects, boxes containing their children and objects, counts, and the
//! level-M read predictions.

use std::collections::BTreeMap;
use std::sync::Arc;

mod lod;

use std::collections::HashSet;

use super::{Database, NodeLocation, ReadTransaction, record_at};

use crate::geom::Aabb;
use crate::store::format::frame::{self, BlockType};
use crate::store::format::freelist::FreeListBlock;
use crate::store::format::node::{LodRef, NodeRecord};
use crate::store::format::run;
use crate::store::{ReadStats, StorageError};

/// What `check` found.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct CheckReport {
    pub txn: u64,
    pub file_blocks: u32,
    pub blocks_by_type: BTreeMap<String, u64>,
    pub free_blocks: u64,
    pub objects: u64,
    pub nodes: u64,
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

struct Checker<'a> {
    txn: &'a ReadTransaction,
    owner: Vec<Owner>,
    report: CheckReport,
}

impl Checker<'_> {
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

    fn claim_run(&mut self, lod: &LodRef, first_type: BlockType) {
        match *lod {
            LodRef::InBlock { block, .. } => self.claim(block, Owner::Used(first_type)),
            LodRef::Run { first, blocks, .. } => {
                self.claim(first, Owner::Used(first_type));
                for b in first + 1..first.saturating_add(blocks) {
                    self.claim(b, Owner::Used(first_type.continuation()));
                }
            }
            _ => {}
        }
    }
}

/// Verifies the whole of `db` (see the module doc).
pub fn check(db: &Database) -> Result<CheckReport, StorageError> {
    let (commit, free) = db.committed();
    let pager = db.pager();
    let txn = db.begin_read()?;
    let mut c = Checker {
        txn: &txn,
        owner: vec![Owner::Unseen; commit.block_count as usize],
        report: CheckReport { txn: commit.txn, file_blocks: commit.block_count, ..CheckReport::default() },
    };
    c.owner[0] = Owner::Header;
    // Every block's checksum, whatever it holds.
    for id in 1..commit.block_count {
        let raw = pager.read_raw(id)?;
        match frame::open(id, &raw) {
            Ok((_, t)) => *c.report.blocks_by_type.entry(t.name().to_string()).or_default() += 1,
            Err(e) => c.fault(e.to_string()),
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
        let b = pager.read(next.0, BlockType::FreeList, Some(next.1), &mut ReadStats::default(), None)?;
        let fl = FreeListBlock::decode(next.0, &b)?;
        next = (fl.next_block, fl.next_checksum);
    }
    if commit.meta_block != 0 {
        c.claim(commit.meta_block, Owner::Used(BlockType::Meta));
        check_tree(&mut c)?;
    }
    for (b, o) in c.owner.clone().iter().enumerate() {
        if *o == Owner::Unseen {
            c.fault(format!("block {b} is neither reachable nor free"));
        }
    }
    Ok(c.report)
}

/// A node still to check: its block's records, its location, the level it
/// must have, and the copy of its box its parent holds (none for the root).
type Pending = (Arc<Vec<NodeRecord>>, NodeLocation, u16, Option<[f32; 6]>);

fn check_tree(c: &mut Checker) -> Result<(), StorageError> {
    let txn = c.txn;
    let Some(info) = txn.info() else { return Ok(()) };
    let Some(root) = txn.root() else { return Ok(()) };
    let names = txn.names()?;
    if names.len() != info.objects as usize {
        c.fault(format!("{} names for {} objects", names.len(), info.objects));
    }
    // The names run's blocks.
    if let Some(m) = txn.snapshot.meta.as_ref().filter(|m| m.names_block != 0) {
        let head = txn.pager().read(
            m.names_block,
            BlockType::Names,
            Some(m.names_checksum),
            &mut ReadStats::default(),
            None,
        )?;
        let (blocks, _, _) = run::header(m.names_block, &head)?;
        let lod = if blocks == 1 {
            LodRef::InBlock { block: m.names_block, offset: 0, checksum: 0 }
        } else {
            LodRef::Run { first: m.names_block, blocks, checksum: 0 }
        };
        c.claim_run(&lod, BlockType::Names);
    }
    let m = txn.pager().lod_levels() as usize;
    let mut seen = vec![false; info.objects as usize];
    let (mut nodes, mut leaves, mut depth, mut node_blocks, mut geometry_blocks) =
        (0u64, 0u64, 0u32, 0u32, 0u64);
    let (mut triangles, mut vertices) = (0u64, 0u64);
    let mut next_id = 0u32;
    let records = txn.read_node_block(root.block, root.checksum, &mut ReadStats::default(), None)?;
    c.claim(root.block, Owner::Used(BlockType::Node));
    node_blocks += 1;
    let mut stack: Vec<Pending> = vec![(records, root, 0, None)];
    let mut lods = lod::LodChecker::new(txn);
    let mut lod_blocks = HashSet::new();
    let mut guard = super::TraversalGuard::new(txn);
    while let Some((records, at, level, parent_box)) = stack.pop() {
        guard.visit(at)?;
        let rec = record_at(&records, at.block, at.slot)?.clone();
        let here = format!("node {} (block {}, slot {})", rec.node_id, at.block, at.slot);
        nodes += 1;
        if rec.node_id != next_id {
            c.fault(format!("{here}: preorder id expected {next_id}"));
        }
        next_id = rec.node_id.wrapping_add(1);
        if rec.level != level {
            c.fault(format!("{here}: level {} expected {level}", rec.level));
        }
        depth = depth.max(rec.level.into());
        if let Some(pb) = parent_box
            && pb != rec.aabb
        {
            c.fault(format!("{here}: the parent's copy of the box differs"));
        }
        for e in lods.visit_node(txn, at, &rec, &here) {
            match e {
                // A LOD block holds many entries' blobs: claimed once.
                LodRef::InBlock { block, .. } if lod_blocks.insert(block) => {
                    c.claim(block, Owner::Used(BlockType::Lod))
                }
                LodRef::Run { .. } => c.claim_run(&e, BlockType::LodRun),
                _ => {}
            }
        }
        let exact = rec.lods[m - 1];
        if exact[0] != exact[1] {
            c.fault(format!("{here}: b(S_n,M) and B(S_n,M) differ"));
        }
        match &rec.children {
            Some((kids, _)) => {
                let mut child_objects = 0u64;
                for k in kids.iter().rev() {
                    if !rec.aabb().contains(&k.aabb()) {
                        c.fault(format!("{here}: a child's box is not inside the node's"));
                    }
                    let (child, loc) = if k.block == at.block {
                        (records.clone(), NodeLocation { block: k.block, slot: k.slot, checksum: None })
                    } else {
                        if k.slot != 0 {
                            c.fault(format!(
                                "{here}: a child in another block is not that block's first record"
                            ));
                        }
                        c.claim(k.block, Owner::Used(BlockType::Node));
                        node_blocks += 1;
                        let b =
                            txn.read_node_block(k.block, Some(k.checksum), &mut ReadStats::default(), None)?;
                        (b, NodeLocation { block: k.block, slot: k.slot, checksum: Some(k.checksum) })
                    };
                    let crec = record_at(&child, loc.block, loc.slot)?;
                    child_objects += u64::from(crec.object_count);
                    stack.push((child, loc, level.saturating_add(1), Some(k.aabb)));
                }
                if !matches!(exact[1], LodRef::Spread { .. }) {
                    c.fault(format!("{here}: level M of an internal node is {:?}, not spread", exact[1]));
                }
                if child_objects != u64::from(rec.object_count) {
                    c.fault(format!("{here}: {} objects, children hold {child_objects}", rec.object_count));
                }
            }
            None => {
                leaves += 1;
                c.claim_run(&exact[1], BlockType::Geometry);
                geometry_blocks += exact[1].reads();
                let objects = match txn.read_objects(&exact[1], &mut ReadStats::default(), None) {
                    Ok(o) => o,
                    Err(e) => {
                        c.fault(format!("{here}: {e}"));
                        continue;
                    }
                };
                if objects.len() != rec.object_count as usize {
                    c.fault(format!(
                        "{here}: {} objects stored, record says {}",
                        objects.len(),
                        rec.object_count
                    ));
                }
                lods.visit_leaf_objects(txn, at, &here, &objects);
                for (id, mesh) in &objects {
                    triangles += mesh.triangle_count() as u64;
                    vertices += mesh.vertex_count() as u64;
                    if !rec.aabb().contains(&mesh.aabb()) {
                        c.fault(format!("{here}: object {id} lies outside the leaf's box"));
                    }
                    match seen.get_mut(id.index()) {
                        Some(s) if !*s => *s = true,
                        _ => c.fault(format!("{here}: object {id} appears twice or is out of range")),
                    }
                }
            }
        }
    }
    lods.finish(&txn.lod_info().map(|i| i.blocks).unwrap_or_default());
    c.report.faults.append(&mut lods.faults);
    if let Some(missing) = seen.iter().position(|s| !s) {
        c.fault(format!("object {missing} is in no leaf"));
    }
    let expect = [
        ("nodes", nodes, u64::from(info.nodes)),
        ("leaves", leaves, u64::from(info.leaves)),
        ("depth", u64::from(depth), u64::from(info.depth)),
        ("node blocks", u64::from(node_blocks), u64::from(info.node_blocks)),
        ("geometry blocks", geometry_blocks, info.geometry_blocks),
        ("triangles", triangles, info.triangles),
        ("vertices", vertices, info.vertices),
    ];
    for (what, got, want) in expect {
        if got != want {
            c.fault(format!("meta says {want} {what}, the tree has {got}"));
        }
    }
    let root_box = Aabb::from_array(info.scene_box);
    let stored = record_at(
        &txn.read_node_block(root.block, root.checksum, &mut ReadStats::default(), None)?,
        root.block,
        root.slot,
    )?
    .aabb();
    if !stored.contains(&root_box) {
        c.fault("the root's box does not contain the scene box");
    }
    c.report.objects = u64::from(info.objects);
    c.report.nodes = nodes;
    Ok(())
}
