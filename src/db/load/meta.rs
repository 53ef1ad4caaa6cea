//! The meta block a bulk load commits (format-spec/meta.md): the tree's
//! counts and root, how it was built, the levels of detail's tables and
//! the key index's root.

use super::keys::WrittenKeys;
use super::{Load, Written};
use crate::lod::StoredBounds;
use crate::store::format::meta::{LOD_TABLE_LEN, LodCodes, Meta};
use crate::tree::codes;

/// The meta block of `load`, written as `written` and `keys` say, with the
/// tables of `stored`.
pub(super) fn assemble(load: &Load, written: &Written, stored: &StoredBounds, keys: &WrittenKeys) -> Meta {
    let Load { objects, tree, params, build_seconds, lod_params } = *load;
    let mut lod_table = [[0.0; 2]; LOD_TABLE_LEN];
    for (row, e) in lod_table.iter_mut().zip(&stored.errors) {
        *row = *e;
    }
    let mut usage = [[0u64; 2]; LOD_TABLE_LEN];
    for (row, u) in usage.iter_mut().zip(&stored.usage) {
        *row = *u;
    }
    let mut predicted = [[0f32; 2]; LOD_TABLE_LEN];
    for (row, p) in predicted.iter_mut().zip(&stored.predicted) {
        *row = p.map(|x| x as f32);
    }
    let mut grid_level = [0u8; LOD_TABLE_LEN];
    for (g, l) in grid_level.iter_mut().zip(&stored.grid_level) {
        *g = *l;
    }
    let (root_block, root_checksum, root_offset) = written.root;
    Meta {
        root_block,
        root_checksum,
        root_offset,
        object_count: objects.len() as u32,
        object_ids: objects.len() as u32,
        node_ids: 0,
        node_count: tree.nodes.len() as u32,
        leaf_count: tree.leaves().count() as u32,
        depth: tree.depth().saturating_sub(1),
        node_blocks: written.node_blocks,
        geometry_blocks: written.geometry_blocks,
        triangle_count: objects.triangle_count(),
        vertex_count: written.vertices,
        scene_box: tree.nodes[0].aabb.to_array(),
        build: codes::encode(params, build_seconds),
        node_bytes: written.node_bytes,
        geometry_bytes: written.geometry_bytes,
        lod_table,
        lods: LodCodes {
            lattice_origin: stored.lattice.map_or([0.0; 3], |l| l.origin.coords.into()),
            lattice_cell: stored.lattice.map_or(0.0, |l| l.cell),
            flags: 0,
            cuberille_bits: written.group_cuberille_bits.unwrap_or(lod_params.cuberille_bits),
            cuberille_object_bits: lod_params.cuberille_object_bits,
            grid_level,
            usage,
            query_extent: stored.query_extent,
            predicted,
        },
        keys_block: keys.block,
        keys_checksum: keys.checksum,
        keys_height: keys.height,
        keys_blocks: keys.blocks,
        written: Vec::new(),
        // The caller's: a bulk load starts the log, a tree written whole for changes continues it.
        log: Default::default(),
    }
}
