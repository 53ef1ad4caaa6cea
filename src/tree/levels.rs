//! What levels of detail a snapshot's tree holds, from its meta block
//! (format-spec/meta.md, `lods`; paper §1.4): M, the voxel lattice, each
//! level's eps_k and what is stored of it.

use super::ReadTransaction;
use crate::lod::Lattice;
use crate::store::format::meta::LOD_TABLE_LEN;

/// The levels of detail a file holds, from its meta block.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct LodInfo {
    /// M.
    pub levels: u8,
    /// The voxel lattice (origin, level-0 cell in mm); `None` when no level holds voxels.
    #[serde(skip)]
    pub lattice: Option<Lattice>,
    /// Per level k = 1 .. M: the guaranteed error eps_k and the largest
    /// sampled one of the bounds stored (mm).
    pub eps: Vec<f64>,
    /// Per level k = 1 .. M: the largest sampled error of the bounds stored (mm).
    pub measured_error: Vec<f64>,
    /// Per level k = 1 .. M: bytes stored (level M: the geometry records).
    pub bytes: Vec<u64>,
    /// Per level k = 1 .. M: bounds stored (level 1: the objects' boxes; M: the objects).
    pub stored: Vec<u64>,
    /// Per level k = 1 .. M: blocks of their own (only level M's geometry; bounds lie in node blocks).
    pub blocks: Vec<u64>,
    /// Per level k = 1 .. M: the query model's expected geometry reads
    /// saved and node reads cost per query by the bounds stored.
    pub predicted_saving: Vec<f64>,
    /// Per level k = 1 .. M: the node reads the bounds stored cost per query.
    pub predicted_cost: Vec<f64>,
    /// The query model's extents q (mm).
    pub query_extent: [f64; 3],
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
        let m = usize::from(self.pager().lod_levels()).min(LOD_TABLE_LEN);
        let l = &meta.lods;
        let mut info = LodInfo {
            levels: m as u8,
            lattice: self.lattice(),
            eps: (0..m).map(|k| meta.lod_table[k][0]).collect(),
            measured_error: (0..m).map(|k| meta.lod_table[k][1]).collect(),
            bytes: (0..m).map(|k| l.usage[k][0]).collect(),
            stored: (0..m).map(|k| l.usage[k][1]).collect(),
            blocks: vec![0; m],
            predicted_saving: (0..m).map(|k| f64::from(l.predicted[k][0])).collect(),
            predicted_cost: (0..m).map(|k| f64::from(l.predicted[k][1])).collect(),
            query_extent: l.query_extent,
        };
        info.stored[0] = u64::from(meta.object_count);
        info.bytes[0] = u64::from(meta.object_count) * crate::store::format::node::OBJECT_LEN as u64;
        info.stored[m - 1] = u64::from(meta.object_count);
        info.bytes[m - 1] = meta.geometry_bytes;
        info.blocks[m - 1] = meta.geometry_blocks;
        Some(info)
    }
}
