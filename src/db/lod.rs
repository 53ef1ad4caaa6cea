//! Reading levels of detail: a node's b(S_n,k) or B(S_n,k) fetched as the
//! paper's queries do, with every block read once and counted, so the reads
//! equal the count the record predicts (format-spec/node.md, lod.md).

use super::{NodeLocation, ReadTransaction, TraversalGuard, record_at};
use crate::geom::Aabb;
use crate::lod::{Lattice, Voxels};
use crate::scene::{Mesh, ObjectId};
use crate::store::format::frame::BlockType;
use crate::store::format::meta::{LOD_KEEP_IDENTITY, LOD_TABLE_LEN};
use crate::store::format::node::LodRef;
use crate::store::format::objboxes;
use crate::store::format::{geometry, lodblock};
use crate::store::{BlockCache, ReadStats, StorageError};

/// One stored piece of a level of detail.
#[derive(Debug, Clone)]
pub enum Piece {
    /// b(S_n,1): node `node`'s box.
    Box { node: u32, aabb: Aabb },
    /// B(S_n,1): a leaf's object boxes.
    ObjectBoxes(Vec<(ObjectId, Aabb)>),
    /// b(S_n,k), 1 < k < M: node `node`'s voxel set.
    Voxels { node: u32, voxels: Voxels },
    /// B(S_n,k), 1 < k < M: a leaf's per-object voxel sets.
    ObjectVoxels(Vec<(ObjectId, Voxels)>),
    /// Level M: a leaf's exact objects.
    Objects(Vec<(ObjectId, Mesh)>),
}

impl Piece {
    /// Faces of the bound: 6 per box, the merged boundary of a voxel set,
    /// the triangles of exact objects.
    pub fn faces(&self) -> u64 {
        match self {
            Piece::Box { .. } => 6,
            Piece::ObjectBoxes(b) => 6 * b.len() as u64,
            Piece::Voxels { voxels, .. } => voxels.faces() as u64,
            Piece::ObjectVoxels(v) => v.iter().map(|(_, v)| v.faces() as u64).sum(),
            Piece::Objects(o) => o.iter().map(|(_, m)| m.triangle_count() as u64).sum(),
        }
    }

    /// The objects this piece names, if it keeps their identity.
    pub fn object_ids(&self) -> Option<Vec<ObjectId>> {
        match self {
            Piece::ObjectBoxes(b) => Some(b.iter().map(|x| x.0).collect()),
            Piece::ObjectVoxels(v) => Some(v.iter().map(|x| x.0).collect()),
            Piece::Objects(o) => Some(o.iter().map(|x| x.0).collect()),
            Piece::Box { .. } | Piece::Voxels { .. } => None,
        }
    }
}

/// A fetched level: its pieces and the bytes they are stored in (blobs,
/// or geometry records at level M; b(S_n,1) costs none).
#[derive(Debug, Clone, Default)]
pub struct Level {
    pub pieces: Vec<Piece>,
    pub bytes: u64,
}

impl Level {
    /// Faces over all pieces.
    pub fn faces(&self) -> u64 {
        self.pieces.iter().map(Piece::faces).sum()
    }
}

/// The levels of detail a file holds, from its meta block.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct LodInfo {
    /// M.
    pub levels: u8,
    /// The voxel lattice (origin, level-0 cell in mm); `None` when no level holds voxels.
    #[serde(skip)]
    pub lattice: Option<Lattice>,
    /// B(S_n,k) keeps object identity at every node.
    pub keep_identity: bool,
    /// Per level k = 1 .. M: the guaranteed error eps_k and the measured one (mm).
    pub eps: Vec<f64>,
    pub measured_error: Vec<f64>,
    /// Per level k = 1 .. M: bytes of blobs stored and blocks holding them
    /// (level M: the geometry runs).
    pub bytes: Vec<u64>,
    pub blocks: Vec<u64>,
}

impl ReadTransaction {
    /// The voxel lattice of the snapshot's tree, when a level holds voxels.
    pub fn lattice(&self) -> Option<Lattice> {
        let l = &self.snapshot.meta.as_ref()?.lods;
        (l.lattice_cell > 0.0).then(|| Lattice { origin: l.lattice_origin.into(), cell: l.lattice_cell })
    }

    /// What levels of detail the snapshot's tree holds.
    pub fn lod_info(&self) -> Option<LodInfo> {
        let meta = self.snapshot.meta.as_ref()?;
        let m = self.pager().lod_levels();
        let l = &meta.lods;
        let per = |f: &dyn Fn(usize) -> f64| (0..usize::from(m).min(LOD_TABLE_LEN)).map(f).collect();
        let mut info = LodInfo {
            levels: m,
            lattice: self.lattice(),
            keep_identity: l.flags & LOD_KEEP_IDENTITY != 0,
            eps: per(&|k| meta.lod_table[k][0]),
            measured_error: per(&|k| meta.lod_table[k][1]),
            bytes: (0..usize::from(m)).map(|k| l.usage[k][0]).collect(),
            blocks: (0..usize::from(m)).map(|k| l.usage[k][1]).collect(),
        };
        // Level M is the geometry itself.
        let last = usize::from(m) - 1;
        info.blocks[last] = meta.geometry_blocks;
        Some(info)
    }

    /// Fetches level `k` (1-based) of node `at` as the paper's queries do:
    /// B(S_n,k) (`objects` = true) or b(S_n,k), following the node's entry:
    /// the record itself, one block, a run, or the children's entries through
    /// the subtree. From a cold cache with the node's record in hand, each
    /// block is read once; the reads equal the entry's prediction
    /// (`NodeRecord::predicted_reads`).
    pub fn fetch_level(
        &self,
        at: NodeLocation,
        k: u8,
        objects: bool,
        stats: &mut ReadStats,
    ) -> Result<Level, StorageError> {
        let m = self.pager().lod_levels();
        if k == 0 || k > m {
            return Err(StorageError::Invalid(format!("level {k} is not in 1..={m}")));
        }
        let mut cache = BlockCache::new(usize::MAX);
        // The record in hand is not counted.
        let records =
            self.read_node_block(at.block, at.checksum, &mut ReadStats::default(), Some(&mut cache))?;
        let mut out = Level::default();
        let mut stack = vec![(records, at, k, objects)];
        let mut guard = TraversalGuard::new(self);
        while let Some((records, at, k, objects)) = stack.pop() {
            guard.visit(at)?;
            let rec = record_at(&records, at.block, at.slot)?;
            let bad =
                |detail: String| StorageError::corrupt_record(at.block, u32::from(at.slot), "lods", detail);
            let (k, objects, entry) = rec.entry(k, objects).ok_or_else(|| bad(format!("no level {k}")))?;
            match entry {
                LodRef::Absent => {
                    return Err(StorageError::Invalid(format!(
                        "level {k} is not stored for node {}",
                        rec.node_id
                    )));
                }
                LodRef::InRecord => out.pieces.push(Piece::Box { node: rec.node_id, aabb: rec.aabb() }),
                LodRef::InBlock { .. } | LodRef::Run { .. } if k == m => {
                    let objects = self.read_objects(&entry, stats, Some(&mut cache))?;
                    out.bytes += objects.iter().map(|(_, o)| geometry::record_len(o)).sum::<u64>();
                    out.pieces.push(Piece::Objects(objects))
                }
                LodRef::InBlock { block, offset, checksum } => {
                    self.check_in_snapshot(block)?;
                    let b =
                        self.pager().read(block, BlockType::Lod, Some(checksum), stats, Some(&mut cache))?;
                    let blob = lodblock::blob_at(block, &b, offset)?;
                    out.bytes += blob.len() as u64;
                    out.pieces.push(self.decode_piece(rec.node_id, k, objects, block, blob)?);
                }
                LodRef::Run { first, blocks, checksum } => {
                    let (_, words, len) = self.read_run(
                        first,
                        checksum,
                        Some(blocks),
                        BlockType::LodRun,
                        stats,
                        Some(&mut cache),
                    )?;
                    let bytes: &[u8] = bytemuck::cast_slice(&words);
                    out.bytes += len as u64;
                    out.pieces.push(self.decode_piece(rec.node_id, k, objects, first, &bytes[..len])?);
                }
                LodRef::Spread { .. } => {
                    let Some((kids, _)) = &rec.children else {
                        return Err(bad("a leaf's entry is spread".into()));
                    };
                    for c in kids.iter().rev() {
                        let loc = NodeLocation { block: c.block, slot: c.slot, checksum: None };
                        let child = if c.block == at.block {
                            records.clone()
                        } else {
                            self.read_node_block(c.block, Some(c.checksum), stats, Some(&mut cache))?
                        };
                        stack.push((child, loc, k, objects));
                    }
                }
                LodRef::Same { .. } => return Err(bad("a level names a level that names another".into())),
            }
        }
        Ok(out)
    }

    pub(crate) fn decode_piece(
        &self,
        node: u32,
        k: u8,
        objects: bool,
        block: u32,
        bytes: &[u8],
    ) -> Result<Piece, StorageError> {
        let bad = |detail: String| StorageError::corrupt(block, "lod blob", detail);
        let count = self.snapshot.meta.as_ref().map_or(0, |m| m.object_count);
        let check_ids = |ids: &[u32]| match ids.iter().find(|id| **id >= count) {
            Some(id) => Err(bad(format!("object {id} >= {count} objects"))),
            None => Ok(()),
        };
        if k == 1 {
            if !objects {
                return Err(bad("b(S_n,1) is the record's box, not a blob".into()));
            }
            let boxes = objboxes::decode(bytes).map_err(bad)?;
            check_ids(&boxes.iter().map(|b| b.0).collect::<Vec<_>>())?;
            return Ok(Piece::ObjectBoxes(boxes.into_iter().map(|(id, b)| (ObjectId(id), b)).collect()));
        }
        let lattice = self.lattice().ok_or_else(|| bad("the meta block has no lattice".into()))?;
        if objects {
            let sets = crate::lod::decode_objects(bytes, &lattice).map_err(|e| bad(e.to_string()))?;
            check_ids(&sets.iter().map(|s| s.0).collect::<Vec<_>>())?;
            Ok(Piece::ObjectVoxels(sets.into_iter().map(|(id, v)| (ObjectId(id), v)).collect()))
        } else {
            let (voxels, used) = crate::lod::decode(bytes, &lattice).map_err(|e| bad(e.to_string()))?;
            if used != bytes.len() {
                return Err(bad(format!("{} bytes after the voxel set", bytes.len() - used)));
            }
            Ok(Piece::Voxels { node, voxels })
        }
    }
}

/// The block reads of a cold fetch of entry (`k`, `objects`) of node `i`,
/// with its record in hand, as `fetch_level` does them: the entry's own
/// blocks, or for a spread entry every child record's node block and the
/// children's entries, each distinct block once. The writer predicts with
/// it and `check` verifies the stored predictions with it.
pub(crate) fn fetch_reads(
    i: usize,
    k: u8,
    objects: bool,
    entry: impl Fn(usize, u8, bool) -> LodRef,
    children: impl Fn(usize) -> Option<[usize; 2]>,
    node_block: impl Fn(usize) -> u32,
) -> u64 {
    let mut blocks = std::collections::BTreeSet::new();
    let mut stack = vec![(i, k, objects)];
    while let Some((j, mut k, mut obj)) = stack.pop() {
        let mut e = entry(j, k, obj);
        if let LodRef::Same { level, objects } = e {
            (k, obj) = (level, objects);
            e = entry(j, k, obj);
        }
        match e {
            LodRef::InBlock { block, .. } => {
                blocks.insert(block);
            }
            LodRef::Run { first, blocks: count, .. } => blocks.extend(first..first.saturating_add(count)),
            LodRef::Spread { .. } => {
                for c in children(j).into_iter().flatten() {
                    blocks.insert(node_block(c));
                    stack.push((c, k, obj));
                }
            }
            LodRef::Absent | LodRef::InRecord | LodRef::Same { .. } => {}
        }
    }
    blocks.remove(&node_block(i));
    blocks.len() as u64
}
