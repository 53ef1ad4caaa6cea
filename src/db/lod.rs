//! A node's levels of detail as the paper's queries ask for them (§1.4):
//! b(S_n,k) or B(S_n,k) fetched with the number of block reads the records
//! predict. A node's group bound b(S_n,k), where its record's flags say its
//! block's group block holds it (`bFits[k]`), is that one block (`bPage[k]`,
//! format-spec/group.md). Otherwise a level is gathered from the node's
//! subtree, whose objects' bounds lie inline in the leaf records: its node
//! blocks (level < M) and its geometry blocks too (level M), counts its
//! parent's entry holds (format-spec/node.md): the paper's `BPage[k]`.

use std::sync::Arc;

use super::{NodeRef, ReadTransaction, Reads, view};
use crate::geom::Aabb;
use crate::lod::{LodParams, LodPlan, Voxels};
use crate::query::{QueryError, QueryOptions, Seen, Selection, Visitor, walk_level};
use crate::scene::{Mesh, ObjectId};
use crate::store::format::frame::BlockType;
use crate::store::format::meta::LOD_TABLE_LEN;
use crate::store::format::node::NodeView;
use crate::store::{Block, ReadStats, StorageError};

/// One stored piece of a level of detail.
#[derive(Debug, Clone)]
pub enum Piece {
    /// b(S_n,1): node `node`'s box.
    Box {
        /// The node's id.
        node: u32,
        /// Its box as stored.
        aabb: Aabb,
    },
    /// Objects bounded by their boxes at this level.
    ObjectBoxes(Vec<(ObjectId, Aabb)>),
    /// Objects bounded by a stored voxel set (its surface cells).
    ObjectVoxels(Vec<(ObjectId, Voxels)>),
    /// Level M: exact objects.
    Objects(Vec<(ObjectId, Mesh)>),
    /// b(S_n,k), 2 <= k < M: node `node`'s group bound, as stored.
    Group {
        /// The node's id.
        node: u32,
        /// The level k.
        level: u8,
        /// The bound's voxels.
        voxels: Voxels,
    },
}

impl Piece {
    /// Faces of the bound: 6 per box, the merged boundary of a voxel set,
    /// the triangles of exact objects.
    pub fn faces(&self) -> u64 {
        match self {
            Piece::Box { .. } => 6,
            Piece::ObjectBoxes(b) => 6 * b.len() as u64,
            Piece::ObjectVoxels(v) => v.iter().map(|(_, v)| v.faces() as u64).sum(),
            Piece::Objects(o) => o.iter().map(|(_, m)| m.triangle_count() as u64).sum(),
            Piece::Group { voxels, .. } => voxels.faces() as u64,
        }
    }
}

/// A fetched level: its pieces and the bytes they are stored in.
#[derive(Debug, Clone, Default)]
pub struct Level {
    /// The pieces the level is made of.
    pub pieces: Vec<Piece>,
    /// Bytes the pieces are stored in.
    pub bytes: u64,
    /// The reads the records predict for this fetch, with the node's record in hand.
    pub predicted_reads: u64,
}

impl Level {
    /// Faces over all pieces.
    pub fn faces(&self) -> u64 {
        self.pieces.iter().map(Piece::faces).sum()
    }
}

impl ReadTransaction {
    /// Node `node`: its record and the block counts its parent's entry
    /// holds for it (the root's come from the meta block). While ids are
    /// preorder numbers, one path from the root finds it; after a change
    /// commit split or merged a leaf (format-spec/meta.md, `node_ids`), a
    /// walk of the node records does. The reads to find it are not counted.
    pub fn locate(&self, node: u32) -> Result<(NodeRef, (u64, u64)), QueryError> {
        let (Some(meta), Some(root)) = (self.snapshot.meta.as_ref(), self.root()) else {
            return Err(QueryError::NoTree);
        };
        let bound = if meta.node_ids == 0 { meta.node_count } else { meta.node_ids };
        if node >= bound {
            return Err(QueryError::NoNode { id: node, bound });
        }
        // With the root's record in hand, its subtree is every other node block.
        let below = (u64::from(meta.node_blocks).saturating_sub(1), meta.geometry_blocks);
        let mut reads = Reads::new(None);
        // Records still to look at; more than the tree holds means the links loop.
        let mut pending = vec![(root, below)];
        let mut budget = u64::from(meta.node_count) + 1;
        while let Some((at, below)) = pending.pop() {
            budget = budget.checked_sub(1).ok_or_else(|| {
                StorageError::corrupt(
                    at.block,
                    "child_block",
                    "more records than the tree holds: the links loop",
                )
            })?;
            let block = self.block(at.block, BlockType::Node, at.checksum, &mut reads)?;
            let record = view(&block, at.offset)?;
            let id = record.node_id();
            if id == node {
                return Ok((at, below));
            }
            let NodeView::Internal(n) = record else { continue };
            if meta.node_ids == 0 {
                // Preorder: node lies under the second child when its id is at least the second child's.
                let second = n.child_ref(1);
                let second_block = self.node_block(&block, second, &mut reads)?;
                let second_id = view(&second_block, second.offset)?.node_id();
                if node > id {
                    pending.push(child_at(&at, &record, &n, usize::from(node >= second_id))?);
                }
            } else {
                for i in [1, 0] {
                    pending.push(child_at(&at, &record, &n, i)?);
                }
            }
        }
        Err(QueryError::NoNode { id: node, bound })
    }

    /// Fetches level `k` (1-based) of node `node` as the paper's queries do:
    /// B(S_n,k) (`objects` = true: each object's bound, its finest stored
    /// voxel set up to k or else its box) or b(S_n,k) (their union; at k = 1
    /// the node's box). From a cold cache with the node's record in hand,
    /// each block is read once; `stats` gets the reads, which equal the
    /// returned level's `predicted_reads`.
    pub fn fetch_level(
        &self,
        node: u32,
        k: u8,
        objects: bool,
        stats: &mut ReadStats,
    ) -> Result<Level, QueryError> {
        let m = self.pager().lod_levels();
        if k == 0 || k > m {
            return Err(QueryError::Level { k, m });
        }
        let (at, (node_blocks, geometry_blocks)) = self.locate(node)?;
        // b(S_n,1) is the node's box, unless level 1 is M (the exact objects).
        if k == 1 && !objects && m > 1 {
            return Ok(Level {
                pieces: vec![Piece::Box { node, aabb: at.aabb }],
                bytes: 0,
                predicted_reads: 0,
            });
        }
        let mut reads = Reads::new(None);
        let held = self.block(at.block, BlockType::Node, at.checksum, &mut Reads::new(None))?;
        // b(S_n,k) stored in the block's group block: that block, one read.
        if !objects && k < m {
            let mut group_reads = Reads::new(None);
            if let Some(voxels) = self.group_bound(&held, at.offset, &at.aabb, k, &mut group_reads)? {
                *stats += group_reads.stats;
                return Ok(Level {
                    bytes: crate::lod::encoded_len(&voxels) as u64,
                    pieces: vec![Piece::Group { node, level: k, voxels }],
                    predicted_reads: 1,
                });
            }
        }
        reads.hold(held);
        let mut gather = Gather::default();
        let opts = QueryOptions { lod: Some(k), budget: None, ..Default::default() };
        walk_level(self, at, &Gathering, k, &opts, &mut reads, &mut gather)?;
        *stats += reads.stats;
        let mut level = Level {
            predicted_reads: node_blocks.saturating_add(if k == m { geometry_blocks } else { 0 }),
            ..Level::default()
        };
        if !gather.boxes.is_empty() {
            level.bytes += gather.boxes.len() as u64 * crate::store::format::node::OBJECT_LEN as u64;
            level.pieces.push(Piece::ObjectBoxes(gather.boxes));
        }
        if !gather.voxels.is_empty() {
            level.bytes += gather.voxel_bytes;
            level.pieces.push(Piece::ObjectVoxels(gather.voxels));
        }
        if !gather.meshes.is_empty() {
            level.bytes +=
                gather.meshes.iter().map(|(_, m)| crate::store::format::geometry::record_len(m)).sum::<u64>();
            level.pieces.push(Piece::Objects(gather.meshes));
        }
        Ok(level)
    }
}

/// Child `i` of internal record `record` at `at`: its place, its box, and
/// its subtree's block counts with its own record in hand.
fn child_at(
    at: &NodeRef,
    record: &NodeView,
    n: &crate::store::format::node::InternalView,
    i: usize,
) -> Result<(NodeRef, (u64, u64)), StorageError> {
    let r = n.child_ref(i);
    let (nb, gb) = n.child_blocks(i);
    let frame = n
        .child_box(i, &record.frame(at.aabb))
        .ok_or_else(|| StorageError::corrupt(at.block, "child_box", "backwards"))?
        .outer;
    // The child's count excludes this block; with the child's own record in hand, its block too.
    let nodes = u64::from(nb).checked_sub(u64::from(r.block != 0)).ok_or_else(|| {
        StorageError::corrupt(at.block, "node_blocks", "a child in another block claims no node block")
    })?;
    let child = if r.block == 0 {
        NodeRef { block: at.block, checksum: at.checksum, offset: r.offset, aabb: frame }
    } else {
        NodeRef { block: r.block, checksum: r.checksum, offset: r.offset, aabb: frame }
    };
    Ok((child, (nodes, u64::from(gb))))
}

/// Every object of a subtree with its bound at the walk's level: may meet
/// anything, holds nothing, so every object reaches its finest bound up to
/// k; at M its geometry, every part of it (a part never meets, so none
/// decides its object before the others are read).
struct Gathering;

impl Selection for Gathering {
    fn may_meet_box(&self, _: &Aabb) -> bool {
        true
    }
    fn holds_box(&self, _: &Aabb) -> bool {
        false
    }
    fn may_meet_voxels(&self, _: &Voxels) -> bool {
        true
    }
    fn confirms_voxels(&self, _: &Voxels) -> bool {
        false
    }
    fn meets_mesh(&self, _: &Mesh, _: &mut u64) -> bool {
        false
    }
}

#[derive(Default)]
struct Gather {
    boxes: Vec<(ObjectId, Aabb)>,
    voxels: Vec<(ObjectId, Voxels)>,
    voxel_bytes: u64,
    meshes: Vec<(ObjectId, Mesh)>,
}

impl Visitor for Gather {
    fn node(&mut self, _: &Arc<Block>, _: u32, _: &Aabb) -> Result<(), StorageError> {
        Ok(())
    }

    fn object(&mut self, seen: &Seen) -> Result<(), StorageError> {
        let id = seen.decision.object;
        match (seen.mesh, seen.bound) {
            (Some(mesh), _) => self.meshes.push((id, mesh.clone())),
            (None, Some((_, v))) => {
                self.voxel_bytes += crate::lod::encoded_len(v) as u64;
                self.voxels.push((id, v.clone()));
            }
            (None, None) => self.boxes.push((id, seen.aabb)),
        }
        Ok(())
    }
}

/// The lattice plan and the parameters the writer chose bounds' grids by,
/// as the meta block records them: `check` holds every stored bound to
/// them, and a change commit draws its leaves' bounds by them.
pub(crate) fn bound_rules(txn: &ReadTransaction) -> Option<(LodPlan, LodParams)> {
    let meta = txn.snapshot.meta.as_ref()?;
    let levels = txn.pager().lod_levels();
    let grid_level = meta.lods.grid_level[..usize::from(levels).min(LOD_TABLE_LEN)].to_vec();
    let plan = LodPlan { levels, lattice: txn.lattice()?, grid_level };
    let params = LodParams { cuberille_object_bits: meta.lods.cuberille_object_bits, ..LodParams::default() };
    Some((plan, params))
}
