//! The read transaction: a consistent snapshot of the committed tree, with
//! verified, counted block reads (format-spec/node.md, geometry.md).

use std::sync::Arc;

use super::{Inner, Snapshot, codes};
use crate::build::BuildParams;
use crate::geom::Aabb;
use crate::scene::{Mesh, ObjectId};
use crate::store::format::frame::BlockType;
use crate::store::format::node::{self, LodRef, NodeRecord};
use crate::store::format::{geometry, run};
use crate::store::{BlockCache, Pager, ReadStats, StorageError};

/// Where a node record lives: its block and slot, and the checksum its
/// parent holds for that block (none for a record reached inside a block
/// already verified).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NodeLocation {
    pub block: u32,
    pub slot: u16,
    pub checksum: Option<u32>,
}

/// What a file holds, from its meta block.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct TreeInfo {
    pub txn: u64,
    pub block_size: u32,
    pub lod_levels: u8,
    pub file_blocks: u32,
    pub objects: u32,
    pub nodes: u32,
    pub leaves: u32,
    /// Deepest level (root 0).
    pub depth: u32,
    pub node_blocks: u32,
    pub geometry_blocks: u64,
    pub triangles: u64,
    pub vertices: u64,
    pub scene_box: [f64; 6],
    pub build_seconds: f64,
    #[serde(skip)]
    pub params: Option<BuildParams>,
}

/// A snapshot of the committed state, unaffected by later commits.
pub struct ReadTransaction {
    inner: Arc<Inner>,
    pub(super) snapshot: Arc<Snapshot>,
}

impl Drop for ReadTransaction {
    fn drop(&mut self) {
        self.inner.release_reader(self.snapshot.txn);
    }
}

impl ReadTransaction {
    pub(super) fn new(inner: Arc<Inner>, snapshot: Arc<Snapshot>) -> ReadTransaction {
        ReadTransaction { inner, snapshot }
    }

    pub(crate) fn pager(&self) -> &Pager {
        self.inner.pager()
    }

    /// The snapshot's tree, or `None` for a database with no tree yet.
    pub fn info(&self) -> Option<TreeInfo> {
        let m = self.snapshot.meta.as_ref()?;
        Some(TreeInfo {
            txn: self.snapshot.txn,
            block_size: self.pager().block_size(),
            lod_levels: self.pager().lod_levels(),
            file_blocks: self.snapshot.block_count,
            objects: m.object_count,
            nodes: m.node_count,
            leaves: m.leaf_count,
            depth: m.depth,
            node_blocks: m.node_blocks,
            geometry_blocks: m.geometry_blocks,
            triangles: m.triangle_count,
            vertices: m.vertex_count,
            scene_box: m.scene_box,
            build_seconds: m.build.build_seconds,
            params: codes::decode(&m.build),
        })
    }

    /// The root record's location, or `None` for an empty database.
    pub fn root(&self) -> Option<NodeLocation> {
        let m = self.snapshot.meta.as_ref()?;
        Some(NodeLocation { block: m.root_block, slot: m.root_slot, checksum: Some(m.root_checksum) })
    }

    /// Reads and decodes node block `block` (verified against `checksum` when given).
    pub fn read_node_block(
        &self,
        block: u32,
        checksum: Option<u32>,
        stats: &mut ReadStats,
        cache: Option<&mut BlockCache>,
    ) -> Result<Arc<Vec<NodeRecord>>, StorageError> {
        self.check_in_snapshot(block)?;
        let b = self.pager().read(block, BlockType::Node, checksum, stats, cache)?;
        Ok(Arc::new(node::decode_block(block, &b, self.pager().lod_levels())?))
    }

    pub(crate) fn check_in_snapshot(&self, block: u32) -> Result<(), StorageError> {
        if block >= self.snapshot.block_count {
            return Err(StorageError::corrupt(
                block,
                "reference",
                format!("past the committed end ({} blocks)", self.snapshot.block_count),
            ));
        }
        Ok(())
    }

    /// Reads the run whose first block is `first` (type `first_type`,
    /// carrying `checksum`), its length from its header, checked against
    /// `expected_blocks` when the parent says it; returns the record count,
    /// the stream (as aligned words) and the stream's length.
    pub(crate) fn read_run(
        &self,
        first: u32,
        checksum: u32,
        expected_blocks: Option<u32>,
        first_type: BlockType,
        stats: &mut ReadStats,
        mut cache: Option<&mut BlockCache>,
    ) -> Result<(u32, Vec<u32>, usize), StorageError> {
        self.check_in_snapshot(first)?;
        let head = self.pager().read(first, first_type, Some(checksum), stats, cache.as_deref_mut())?;
        let (blocks, _, _) = run::header(first, &head)?;
        if expected_blocks.is_some_and(|e| e != blocks) {
            let detail = format!("the parent says {expected_blocks:?} blocks, the run {blocks}");
            return Err(StorageError::corrupt(first, "run_blocks", detail));
        }
        let last =
            first.checked_add(blocks - 1).ok_or_else(|| StorageError::corrupt(first, "run", "overflows"))?;
        self.check_in_snapshot(last)?;
        let mut all = vec![head];
        for id in first + 1..=last {
            all.push(self.pager().read(id, first_type.continuation(), None, stats, cache.as_deref_mut())?);
        }
        let refs: Vec<&[u8]> = all.iter().map(|b| &b[..]).collect();
        run::assemble(first, &refs)
    }

    /// The exact objects a level-M entry names (a leaf's geometry run).
    pub fn read_objects(
        &self,
        lod: &LodRef,
        stats: &mut ReadStats,
        cache: Option<&mut BlockCache>,
    ) -> Result<Vec<(ObjectId, Mesh)>, StorageError> {
        let (first, blocks, checksum) = match *lod {
            LodRef::InBlock { block, offset, checksum } if offset as usize == run::FIRST_DATA => {
                (block, 1, checksum)
            }
            LodRef::InBlock { block, offset, .. } => {
                let detail = format!("a run starts at {}, not {offset}", run::FIRST_DATA);
                return Err(StorageError::corrupt(block, "lod offset", detail));
            }
            LodRef::Run { first, blocks, checksum } => (first, blocks, checksum),
            _ => return Err(StorageError::Invalid("not a geometry reference".into())),
        };
        let (records, words, len) =
            self.read_run(first, checksum, Some(blocks), BlockType::Geometry, stats, cache)?;
        let objects = geometry::decode_objects(first, &words, len, records)?;
        let count = self.snapshot.meta.as_ref().map_or(0, |m| m.object_count);
        if let Some((id, _)) = objects.iter().find(|(id, _)| id.0 >= count) {
            return Err(StorageError::corrupt(first, "object_id", format!("{id} >= {count} objects")));
        }
        Ok(objects)
    }

    /// Every object's name, by id (reads the names run).
    pub fn names(&self) -> Result<Vec<String>, StorageError> {
        let Some(m) = self.snapshot.meta.as_ref() else { return Ok(Vec::new()) };
        if m.names_block == 0 {
            return Ok(Vec::new());
        }
        let first = m.names_block;
        let (records, words, len) =
            self.read_run(first, m.names_checksum, None, BlockType::Names, &mut ReadStats::default(), None)?;
        if records != m.object_count {
            return Err(StorageError::corrupt(
                first,
                "record_count",
                format!("{records} names for {} objects", m.object_count),
            ));
        }
        geometry::decode_names(first, &words, len, records)
    }

    /// Visits every node in preorder (left child first) with its location and
    /// record, reading each node block once; `visit` may stop the walk with an error.
    pub fn walk_nodes(
        &self,
        stats: &mut ReadStats,
        mut visit: impl FnMut(NodeLocation, &NodeRecord) -> Result<(), StorageError>,
    ) -> Result<(), StorageError> {
        let Some(root) = self.root() else { return Ok(()) };
        let records = self.read_node_block(root.block, root.checksum, stats, None)?;
        let mut stack = vec![(records, root)];
        let mut guard = TraversalGuard::new(self);
        while let Some((records, at)) = stack.pop() {
            guard.visit(at)?;
            let rec = record_at(&records, at.block, at.slot)?;
            visit(at, rec)?;
            if let Some((kids, _)) = &rec.children {
                for c in kids.iter().rev() {
                    if c.block == at.block {
                        stack.push((
                            records.clone(),
                            NodeLocation { block: c.block, slot: c.slot, checksum: None },
                        ));
                    } else {
                        let child = self.read_node_block(c.block, Some(c.checksum), stats, None)?;
                        stack.push((
                            child,
                            NodeLocation { block: c.block, slot: c.slot, checksum: Some(c.checksum) },
                        ));
                    }
                }
            }
        }
        Ok(())
    }

    /// The objects whose exact geometry (surface) meets `query`, with the reads it took.
    pub fn query_box(&self, query: &Aabb) -> Result<crate::query::BoxQuery, StorageError> {
        crate::query::query_box(self, query, None)
    }
}

/// Stops a traversal of a damaged file whose child links loop: a tree
/// visits at most the meta block's node count of records.
pub(crate) struct TraversalGuard {
    limit: u64,
    visited: u64,
}

impl TraversalGuard {
    pub(crate) fn new(txn: &ReadTransaction) -> TraversalGuard {
        TraversalGuard {
            limit: txn.snapshot.meta.as_ref().map_or(0, |m| u64::from(m.node_count)),
            visited: 0,
        }
    }

    pub(crate) fn visit(&mut self, at: NodeLocation) -> Result<(), StorageError> {
        self.visited += 1;
        if self.visited > self.limit {
            return Err(StorageError::corrupt_record(
                at.block,
                u32::from(at.slot),
                "child_block",
                format!("more than the {} nodes the meta block counts: the links loop", self.limit),
            ));
        }
        Ok(())
    }
}

/// Record `slot` of a decoded block, or a corruption error.
pub(crate) fn record_at(records: &[NodeRecord], block: u32, slot: u16) -> Result<&NodeRecord, StorageError> {
    records.get(usize::from(slot)).ok_or_else(|| {
        StorageError::corrupt(block, "child_slot", format!("slot {slot} of {} records", records.len()))
    })
}
