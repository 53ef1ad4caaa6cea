//! The write transaction: bulk-loads a scene into new blocks (copy on write)
//! and commits it with the protocol of format-spec/commit.md.

use std::sync::{Arc, MutexGuard};
use std::time::Instant;

use super::{Inner, Snapshot, codes};
use crate::build::{BuildParams, BuildProgress, Hierarchy, Node, Order, build};
use crate::geom::Aabb;
use crate::lod::{Computed, Entry, LodParams, LodPlan};
use crate::scene::Scene;
use crate::store::alloc::FreeSpace;
use crate::store::format::frame::BlockType;
use crate::store::format::freelist::{FreeListBlock, ranges_per_block};
use crate::store::format::header::{self, Commit, Slot, SlotState};
use crate::store::format::lodblock::{self, LodBlockWriter};
use crate::store::format::meta::{LOD_KEEP_IDENTITY, LOD_TABLE_LEN, LodCodes, Meta};
use crate::store::format::node::{self, ChildRef, LodRef, NodeRecord, SplitInfo};
use crate::store::format::{geometry, run};
use crate::store::{StorageError, layout};

/// The one write transaction. Dropping it without `commit` aborts it: the
/// committed state is untouched.
pub struct WriteTransaction<'db> {
    inner: &'db Arc<Inner>,
    _guard: MutexGuard<'db, ()>,
    txn: u64,
    base: Commit,
    slot: usize,
    /// Blocks this transaction may allocate.
    avail: FreeSpace,
    /// Blocks this transaction wrote (as a set of ranges).
    written: FreeSpace,
    /// The new meta block (block, checksum), once a tree is loaded.
    meta: Option<(u32, u32, Meta)>,
    /// How the levels of detail below M are built.
    lod_params: LodParams,
    done: bool,
}

fn to_f32_box(b: &Aabb) -> [f32; 6] {
    let (lo, hi) = b.to_f32_outward();
    [lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]]
}

impl<'db> WriteTransaction<'db> {
    pub(super) fn begin(
        inner: &'db Arc<Inner>,
        guard: MutexGuard<'db, ()>,
    ) -> Result<WriteTransaction<'db>, StorageError> {
        let (base, slot, avail) = {
            let mut s = inner.lock_state();
            // Blocks freed by a commit become reusable once no reader older than it lives.
            let oldest = s.readers.keys().next().copied();
            s.freed_at.retain(|(t, _)| oldest.is_some_and(|r| r < *t));
            let mut avail = FreeSpace::new(s.committed.block_count, s.free.iter().copied());
            for (_, pinned) in &s.freed_at {
                avail.remove_all(pinned);
            }
            (s.committed, 1 - s.committed_slot, avail)
        };
        let txn = base.txn + 1;
        // Step 1: the other slot may hold the state before `base`, whose blocks we may reuse.
        let pending = Slot::encode(slot, SlotState::Pending, &Commit { txn, ..Commit::default() });
        inner.pager().write_header_bytes(header::slot_offset(slot) as u64, &pending)?;
        inner.pager().sync()?;
        let end = avail.end();
        Ok(WriteTransaction {
            inner,
            _guard: guard,
            txn,
            base,
            slot,
            avail,
            written: FreeSpace::new(end, []),
            meta: None,
            lod_params: LodParams::default(),
            done: false,
        })
    }

    /// Sets how the next tree's levels of detail are built (default:
    /// `LodParams::default()`, eps from the scene).
    pub fn set_lod_params(&mut self, params: LodParams) {
        self.lod_params = params;
    }

    /// This transaction's id.
    pub fn id(&self) -> u64 {
        self.txn
    }

    fn allocate(&mut self, count: u32) -> Result<u32, StorageError> {
        let first = self.avail.allocate(count)?;
        self.written.release(first, count);
        Ok(first)
    }

    /// Writes `payloads` as a run (first block `first_type`, then continuations).
    fn write_run(
        &mut self,
        mut payloads: Vec<Vec<u8>>,
        first_type: BlockType,
    ) -> Result<LodRef, StorageError> {
        let n = payloads.len() as u32;
        let first = self.allocate(n)?;
        let mut checksum = 0;
        for (j, b) in payloads.iter_mut().enumerate() {
            let t = if j == 0 { first_type } else { first_type.continuation() };
            let s = self.inner.pager().write(first + j as u32, b, t, self.txn)?;
            if j == 0 {
                checksum = s;
            }
        }
        Ok(if n == 1 {
            LodRef::InBlock { block: first, offset: run::FIRST_DATA as u32, checksum }
        } else {
            LodRef::Run { first, blocks: n, checksum }
        })
    }

    /// Builds the MKtree of `scene` with `params` and writes it: geometry runs,
    /// node blocks, names, meta. Replaces the tree on commit. Returns the
    /// hierarchy that was written.
    pub fn bulk_load(
        &mut self,
        scene: &Scene,
        params: &BuildParams,
        progress: &(dyn Fn(BuildProgress) + Sync),
    ) -> Result<Hierarchy, crate::Error> {
        if self.meta.is_some() {
            return Err(StorageError::Invalid("a transaction writes one tree".into()).into());
        }
        let started = Instant::now();
        let boxes = scene.object_boxes();
        let sizes: Vec<u64> = scene.objects().iter().map(|o| geometry::record_len(&o.mesh)).collect();
        let tree = build(&boxes, Some(&sizes), params, progress)?;
        let build_seconds = started.elapsed().as_secs_f64();
        self.write(scene, &tree, params, build_seconds)?;
        Ok(tree)
    }

    /// Writes a tree already built from `scene` with `params` (e.g. once for
    /// several files); `build_seconds` is recorded in the meta block. The tree
    /// must be a valid hierarchy of exactly the scene's objects.
    pub fn write_tree(
        &mut self,
        scene: &Scene,
        tree: &Hierarchy,
        params: &BuildParams,
        build_seconds: f64,
    ) -> Result<(), StorageError> {
        if self.meta.is_some() {
            return Err(StorageError::Invalid("a transaction writes one tree".into()));
        }
        let boxes = scene.object_boxes();
        let sizes: Vec<u64> = scene.objects().iter().map(|o| geometry::record_len(&o.mesh)).collect();
        tree.validate(&boxes, Some(&sizes), params)
            .map_err(|e| StorageError::Invalid(format!("the tree does not fit the scene: {e}")))?;
        self.write(scene, tree, params, build_seconds)
    }

    /// Writes a valid tree of `scene` (built here, or checked by `write_tree`).
    fn write(
        &mut self,
        scene: &Scene,
        tree: &Hierarchy,
        params: &BuildParams,
        build_seconds: f64,
    ) -> Result<(), StorageError> {
        let pager = self.inner.pager().clone();
        let (bs, m) = (pager.block_size(), pager.lod_levels());
        let nodes = &tree.nodes;
        let n = nodes.len();
        if tree.depth() > u32::from(u16::MAX) {
            return Err(StorageError::Invalid(format!(
                "the tree has {} levels; a file holds at most 65,535",
                tree.depth()
            )));
        }
        // Geometry runs, one per leaf, in preorder.
        let mut exact = vec![LodRef::Absent; n];
        let mut stream = Vec::new();
        let mut geometry_blocks = 0u64;
        for (i, node) in nodes.iter().enumerate() {
            if let Some(objects) = node.objects() {
                stream.clear();
                for id in objects {
                    let o =
                        scene.object(*id).ok_or_else(|| StorageError::Invalid(format!("no object {id}")))?;
                    geometry::encode_object(*id, &o.mesh, &mut stream);
                }
                let payloads = run::encode(&stream, objects.len() as u32, bs);
                geometry_blocks += payloads.len() as u64;
                exact[i] = self.write_run(payloads, BlockType::Geometry)?;
            }
        }
        // Levels of detail below M, placed in LOD blocks level by level.
        let lods = if m >= 2 {
            let plan = LodPlan::new(scene, m, &self.lod_params).map_err(lod_error)?;
            let computed = crate::lod::compute(scene, tree, &plan, &self.lod_params, lodblock::max_blob(bs))
                .map_err(lod_error)?;
            Some(computed)
        } else {
            None
        };
        let mut entries = vec![vec![[LodRef::Absent; 2]; m as usize]; n];
        let mut usage = [[0u64; 2]; LOD_TABLE_LEN];
        if let Some(c) = &lods {
            self.place_lods(c, &mut entries, &mut usage)?;
        }
        // Pack nodes into blocks; block ids in the order blocks were started.
        let capacity = node::records_per_block(bs, m);
        let packing = layout::pack(n, |i| nodes[i].children().map(|c| c.map(|x| x.index())), capacity);
        let block_ids: Vec<u32> =
            (0..packing.blocks.len()).map(|_| self.allocate(1)).collect::<Result<_, _>>()?;
        let node_block: Vec<u32> = packing.place.iter().map(|p| block_ids[p.0 as usize]).collect();
        // Level M: a leaf's geometry run; an internal node spreads over its children.
        let mut object_count = vec![0u32; n];
        for i in (0..n).rev() {
            match nodes[i].children() {
                None => {
                    object_count[i] = nodes[i].objects().map_or(0, |o| o.len() as u32);
                    entries[i][m as usize - 1] = [exact[i]; 2];
                }
                Some(kids) => {
                    object_count[i] = kids.iter().map(|c| object_count[c.index()]).sum();
                    entries[i][m as usize - 1] = [LodRef::Spread { reads: 0 }; 2];
                }
            }
        }
        // Every spread entry's reads: the distinct blocks its fetch touches.
        let mut spread_reads = Vec::new();
        for (i, node_entries) in entries.iter().enumerate() {
            for (k, pair) in node_entries.iter().enumerate() {
                for obj in [false, true] {
                    if let LodRef::Spread { .. } = pair[usize::from(obj)] {
                        let reads = super::lod::fetch_reads(
                            i,
                            k as u8 + 1,
                            obj,
                            |j, k, obj| entries[j][usize::from(k) - 1][usize::from(obj)],
                            |j| nodes[j].children().map(|c| c.map(|c| c.index())),
                            |j| node_block[j],
                        );
                        let reads = u32::try_from(reads).map_err(|_| {
                            StorageError::Invalid("a level needs more than 2^32 reads".into())
                        })?;
                        spread_reads.push((i, k, usize::from(obj), reads));
                    }
                }
            }
        }
        for (i, k, obj, reads) in spread_reads {
            entries[i][k][obj] = LodRef::Spread { reads };
        }
        // Write node blocks last to first: a child block is always started
        // after its parent's, so its checksum is known when the parent is written.
        let mut checksums = vec![0u32; block_ids.len()];
        for b in (0..packing.blocks.len()).rev() {
            let records: Vec<NodeRecord> = packing.blocks[b]
                .iter()
                .map(|&i| {
                    record(nodes, i as usize, &entries[i as usize], &object_count, |c| {
                        let (cb, slot) = packing.place[c];
                        let checksum = if cb as usize == b { 0 } else { checksums[cb as usize] };
                        ChildRef {
                            block: block_ids[cb as usize],
                            slot,
                            checksum,
                            aabb: to_f32_box(&nodes[c].aabb),
                        }
                    })
                })
                .collect();
            let mut block = vec![0u8; bs as usize];
            node::encode_block(&records, m, &mut block);
            checksums[b] = pager.write(block_ids[b], &mut block, BlockType::Node, self.txn)?;
        }
        // Names, apart from geometry so queries never read them.
        stream.clear();
        for o in scene.objects() {
            geometry::encode_name(&o.name, &mut stream);
        }
        let names = self.write_run(run::encode(&stream, scene.len() as u32, bs), BlockType::Names)?;
        let (names_block, names_checksum) = match names {
            LodRef::InBlock { block, checksum, .. } => (block, checksum),
            LodRef::Run { first, checksum, .. } => (first, checksum),
            _ => (0, 0),
        };
        let (root_block, root_slot) = packing.place[0];
        let meta = Meta {
            root_block: block_ids[root_block as usize],
            root_checksum: checksums[root_block as usize],
            root_slot,
            object_count: scene.len() as u32,
            node_count: n as u32,
            leaf_count: tree.leaves().count() as u32,
            depth: tree.depth().saturating_sub(1),
            node_blocks: block_ids.len() as u32,
            geometry_blocks,
            triangle_count: scene.triangle_count() as u64,
            vertex_count: scene.vertex_count() as u64,
            scene_box: scene.aabb().to_array(),
            build: codes::encode(params, build_seconds),
            names_block,
            names_checksum,
            lod_table: lod_table(lods.as_ref()),
            lods: LodCodes {
                lattice_origin: lods.as_ref().map_or([0.0; 3], |c| c.plan.lattice.origin.coords.into()),
                lattice_cell: lods.as_ref().map_or(0.0, |c| c.plan.lattice.cell),
                flags: if self.lod_params.keep_identity { LOD_KEEP_IDENTITY } else { 0 },
                cuberille_bits: self.lod_params.cuberille_bits,
                cuberille_object_bits: self.lod_params.cuberille_object_bits,
                grid_level: lods.as_ref().map_or([0; LOD_TABLE_LEN], |c| {
                    let mut g = [0; LOD_TABLE_LEN];
                    g[..c.plan.grid_level.len()].copy_from_slice(&c.plan.grid_level);
                    g
                }),
                usage,
            },
        };
        let meta_block = self.allocate(1)?;
        let mut block = vec![0u8; bs as usize];
        meta.encode(&mut block);
        let sum = pager.write(meta_block, &mut block, BlockType::Meta, self.txn)?;
        self.meta = Some((meta_block, sum, meta));
        Ok(())
    }

    /// Makes the transaction durable: writes the free list, syncs, writes the
    /// commit slot, syncs (format-spec/commit.md, steps 3 to 5).
    pub fn commit(mut self) -> Result<(), StorageError> {
        let pager = self.inner.pager().clone();
        let Some((meta_block, meta_checksum, meta)) = self.meta.take() else {
            // Nothing loaded: the same state under a new transaction id.
            let c = Commit { txn: self.txn, ..self.base };
            return self.finish(c, None);
        };
        // The new free list: everything this transaction did not write. Its own
        // blocks come from `avail` (never from the blocks it frees).
        let per = ranges_per_block(pager.block_size());
        let mut list_blocks: Vec<u32> = Vec::new();
        let free = loop {
            let free = FreeSpace::complement(self.avail.end(), &self.written);
            if free.len().div_ceil(per) <= list_blocks.len() {
                break free;
            }
            list_blocks.push(self.allocate(1)?);
        };
        let (mut next, mut next_sum) = (0u32, 0u32);
        let chunks: Vec<&[(u32, u32)]> = free.chunks(per).collect();
        for (j, &id) in list_blocks.iter().enumerate().rev() {
            let fl = FreeListBlock {
                next_block: next,
                next_checksum: next_sum,
                ranges: chunks.get(j).map_or(Vec::new(), |c| c.to_vec()),
            };
            let mut block = vec![0u8; pager.block_size() as usize];
            fl.encode(&mut block);
            next_sum = pager.write(id, &mut block, BlockType::FreeList, self.txn)?;
            next = id;
        }
        let c = Commit {
            txn: self.txn,
            meta_block,
            meta_checksum,
            block_count: self.avail.end(),
            freelist_block: next,
            freelist_checksum: next_sum,
            free_blocks: free.iter().map(|r| r.1).sum(),
        };
        self.finish(c, Some((meta, free)))
    }

    fn finish(&mut self, c: Commit, loaded: Option<(Meta, Vec<(u32, u32)>)>) -> Result<(), StorageError> {
        let pager = self.inner.pager();
        pager.sync()?;
        pager.write_header_bytes(
            header::slot_offset(self.slot) as u64,
            &Slot::encode(self.slot, SlotState::Committed, &c),
        )?;
        pager.sync()?;
        self.done = true;
        let mut s = self.inner.lock_state();
        let old_used = FreeSpace::new(self.base.block_count, s.free.iter().copied());
        let (meta, free) = match loaded {
            Some((meta, free)) => {
                // The old tree and old free-list blocks are free now, but pinned for older readers.
                s.freed_at.push((c.txn, FreeSpace::complement(self.base.block_count, &old_used)));
                (Some(meta), free)
            }
            None => (s.snapshot.meta.clone(), s.free.clone()),
        };
        s.committed = c;
        s.committed_slot = self.slot;
        s.free = free;
        s.snapshot = Arc::new(Snapshot { txn: c.txn, meta, block_count: c.block_count });
        Ok(())
    }

    /// Writes the blobs of every level below M into LOD blocks, level by
    /// level in preorder (a level's blobs for nearby nodes share blocks),
    /// each blob larger than a block as its own run; fills `entries` and
    /// per level the bytes and blocks used.
    fn place_lods(
        &mut self,
        c: &Computed,
        entries: &mut [Vec<[LodRef; 2]>],
        usage: &mut [[u64; 2]; LOD_TABLE_LEN],
    ) -> Result<(), StorageError> {
        let bs = self.inner.pager().block_size();
        for k in 1..c.plan.levels {
            let ki = usize::from(k) - 1;
            let mut block = LodBlockWriter::new(bs);
            let mut waiting: Vec<(usize, usize, u32)> = Vec::new();
            for obj in [0, 1] {
                for (i, node) in c.nodes.iter().enumerate() {
                    entries[i][ki][obj] = match &node[ki][obj] {
                        Entry::InRecord => LodRef::InRecord,
                        Entry::Spread => LodRef::Spread { reads: 0 },
                        Entry::Same { level, objects } => LodRef::Same { level: *level, objects: *objects },
                        Entry::Blob { bytes, .. } if bytes.len() > lodblock::max_blob(bs) => {
                            let payloads = run::encode(bytes, 1, bs);
                            usage[ki][0] += bytes.len() as u64;
                            usage[ki][1] += payloads.len() as u64;
                            self.write_run(payloads, BlockType::LodRun)?
                        }
                        Entry::Blob { bytes, .. } => {
                            if !block.fits(bytes.len()) {
                                let full = std::mem::replace(&mut block, LodBlockWriter::new(bs));
                                self.flush_lod_block(full, &mut waiting, entries, ki)?;
                                usage[ki][1] += 1;
                            }
                            usage[ki][0] += bytes.len() as u64;
                            waiting.push((i, obj, block.push(bytes)));
                            LodRef::Absent // filled when the block is written
                        }
                    };
                }
            }
            if !block.is_empty() {
                self.flush_lod_block(block, &mut waiting, entries, ki)?;
                usage[ki][1] += 1;
            }
        }
        Ok(())
    }

    fn flush_lod_block(
        &mut self,
        block: LodBlockWriter,
        waiting: &mut Vec<(usize, usize, u32)>,
        entries: &mut [Vec<[LodRef; 2]>],
        ki: usize,
    ) -> Result<(), StorageError> {
        let id = self.allocate(1)?;
        let mut bytes = block.finish();
        let checksum = self.inner.pager().write(id, &mut bytes, BlockType::Lod, self.txn)?;
        for (i, obj, offset) in waiting.drain(..) {
            entries[i][ki][obj] = LodRef::InBlock { block: id, offset, checksum };
        }
        Ok(())
    }

    /// Abandons the transaction; the file keeps its committed state.
    pub fn abort(mut self) -> Result<(), StorageError> {
        self.rollback()
    }

    fn rollback(&mut self) -> Result<(), StorageError> {
        self.done = true;
        let pager = self.inner.pager();
        // Nothing was torn: the pending slot can be cleared, and appended blocks dropped.
        pager.device().set_len(u64::from(self.base.block_count) * u64::from(pager.block_size()))?;
        pager.sync()?;
        pager.write_header_bytes(header::slot_offset(self.slot) as u64, &[0u8; 256])?;
        pager.sync()
    }
}

impl Drop for WriteTransaction<'_> {
    fn drop(&mut self) {
        if !self.done {
            // Best effort: if it fails, the next open sees the pending slot and recovers.
            let _ = self.rollback();
        }
    }
}

/// Node `i`'s record: its box, split, children (through `child`), and its LOD entries.
fn record(
    nodes: &[Node],
    i: usize,
    lods: &[[LodRef; 2]],
    object_count: &[u32],
    child: impl Fn(usize) -> ChildRef,
) -> NodeRecord {
    let node = &nodes[i];
    let children = node.children().zip(node.split()).map(|(kids, s)| {
        let order = match s.order {
            Order::Min => 0,
            Order::Max => 1,
            Order::Center => 2,
        };
        (
            kids.map(|c| child(c.index())),
            SplitInfo { axis: s.axis, order, overlap: s.overlap as f32, gap: s.gap as f32 },
        )
    });
    NodeRecord {
        node_id: i as u32,
        aabb: to_f32_box(&node.aabb),
        level: node.level as u16, // checked in write_tree
        object_count: object_count[i],
        children,
        lods: lods.to_vec(),
    }
}

fn lod_error(e: crate::lod::LodError) -> StorageError {
    StorageError::Invalid(format!("levels of detail: {e}"))
}

/// Per level k = 1 .. 16: (eps_k, measured error).
fn lod_table(lods: Option<&Computed>) -> [[f64; 2]; LOD_TABLE_LEN] {
    let mut t = [[0.0; 2]; LOD_TABLE_LEN];
    if let Some(c) = lods {
        for (k, row) in t.iter_mut().enumerate().take(c.eps.len()) {
            *row = [c.eps[k], c.measured[k]];
        }
    }
    t
}
