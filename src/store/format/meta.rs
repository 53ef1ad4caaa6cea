//! The meta block (format-spec/meta.md).

use zerocopy::byteorder::little_endian::{F32, F64, U32, U64};
use zerocopy::{FromBytes, Immutable, IntoBytes, KnownLayout, Unaligned};

use super::all_zero;
use super::change_log::ChangeLog;
use super::frame::FRAME_LEN;
use super::keys;
use crate::store::StorageError;

/// Levels the LOD table has room for.
pub const LOD_TABLE_LEN: usize = 16;

#[derive(Debug, Clone, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
#[repr(C)]
pub(crate) struct MetaRecord {
    pub(crate) root_block: U32,
    pub(crate) root_checksum: U32,
    pub(crate) root_offset: U32,
    pub(crate) object_count: U32,
    pub(crate) node_count: U32,
    pub(crate) leaf_count: U32,
    pub(crate) depth: U32,
    pub(crate) node_blocks: U32,
    pub(crate) geometry_blocks: U64,
    pub(crate) triangle_count: U64,
    pub(crate) vertex_count: U64,
    pub(crate) scene_box: [F64; 6],
    pub(crate) method: u8,
    pub(crate) tie_break: u8,
    pub(crate) leaf_rule: u8,
    pub(crate) reserved1: u8,
    pub(crate) look_ahead: U32,
    pub(crate) rate: F64,
    pub(crate) leaf_capacity: U64,
    pub(crate) object_ids: U32,
    pub(crate) node_ids: U32,
    pub(crate) build_seconds: F64,
    pub(crate) lod_table: [[F64; 2]; LOD_TABLE_LEN],
    pub(crate) lattice_origin: [F64; 3],
    pub(crate) lattice_cell: F64,
    pub(crate) lod_flags: U32,
    pub(crate) cuberille_bits: U32,
    pub(crate) cuberille_object_bits: U32,
    pub(crate) reserved2: [u8; 4],
    pub(crate) lod_grid_level: [u8; LOD_TABLE_LEN],
    pub(crate) lod_usage: [[U64; 2]; LOD_TABLE_LEN],
    pub(crate) node_bytes: U64,
    pub(crate) geometry_bytes: U64,
    pub(crate) query_extent: [F64; 3],
    pub(crate) lod_predicted: [[F32; 2]; LOD_TABLE_LEN],
    pub(crate) keys_block: U32,
    pub(crate) keys_checksum: U32,
    pub(crate) keys_height: U32,
    pub(crate) keys_blocks: U32,
    pub(crate) log_since: U64,
    pub(crate) log_bytes: U32,
}
const _: () = assert!(FRAME_LEN + size_of::<MetaRecord>() == 932);

/// How the levels of detail below M were built (format-spec/meta.md).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LodCodes {
    /// The global voxel lattice: origin and level-0 cell (mm); cell 0 when
    /// no level below M holds voxels.
    pub lattice_origin: [f64; 3],
    /// Cell of lattice level 0, mm; 0 when no level below M holds voxels.
    pub lattice_cell: f64,
    /// Reserved: zero.
    pub flags: u32,
    /// Bit budgets of a node's and an object's cuberille (level 2).
    pub cuberille_bits: u32,
    /// Cell budget of an object's level-2 grid.
    pub cuberille_object_bits: u32,
    /// Per level k = 1 .. 16: the lattice level of its grids (level 2: the finest allowed).
    pub grid_level: [u8; LOD_TABLE_LEN],
    /// Per level k = 1 .. 16: (bytes of the bounds stored inline, bounds stored).
    pub usage: [[u64; 2]; LOD_TABLE_LEN],
    /// The query model the stored bounds were judged on: a box query of
    /// these extents (mm), placed uniformly (format-spec/lod.md, "What pays").
    pub query_extent: [f64; 3],
    /// Per level k = 1 .. 16: the model's expected (saving, cost) in block
    /// reads per query of the bounds stored.
    pub predicted: [[f32; 2]; LOD_TABLE_LEN],
}

/// How the tree was built, as raw codes (the db layer maps them to `build` types).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct BuildCodes {
    /// Bulk loader: 0 moa, 1 laa, 2 median, 3 hilbert, 4 sah, 5 vsah, 6 refine.
    pub method: u8,
    /// 0 first-found (the paper), 1 widest-gap, 2 most-balanced.
    pub tie_break: u8,
    /// 0 objects (`leaf_capacity` = MemPage objects), 1 bytes (`leaf_capacity` = bytes).
    pub leaf_rule: u8,
    /// `u32::MAX` = max.
    pub look_ahead: u32,
    /// R, in [0, 0.5].
    pub rate: f64,
    /// Objects or bytes per leaf, as `leaf_rule` says.
    pub leaf_capacity: u64,
    /// Wall time of the bulk load's tree stage (building the hierarchy), seconds.
    pub build_seconds: f64,
}

/// The meta block, decoded.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Meta {
    /// The node block holding the root record.
    pub root_block: u32,
    /// The checksum that block must carry.
    pub root_checksum: u32,
    /// Byte offset of the root record in its block.
    pub root_offset: u32,
    /// Objects in the tree.
    pub object_count: u32,
    /// Nodes, leaves included.
    pub node_count: u32,
    /// Leaves.
    pub leaf_count: u32,
    /// Deepest node level (root 0); an upper bound after a change commit that merged leaves.
    pub depth: u32,
    /// Number of node blocks.
    pub node_blocks: u32,
    /// Number of geometry blocks.
    pub geometry_blocks: u64,
    /// Triangles over all objects.
    pub triangle_count: u64,
    /// Vertices over all objects.
    pub vertex_count: u64,
    /// R(S), x0 y0 z0 x1 y1 z1, exact: the root's box, the frame its children are quantized in.
    pub scene_box: [f64; 6],
    /// How the tree was built.
    pub build: BuildCodes,
    /// Object ids lie below this (at least `object_count`): a change
    /// commit gives a new object the next id and leaves a removed one's unused.
    pub object_ids: u32,
    /// 0: node ids are the preorder numbers `0 .. node_count` (a bulk
    /// load's). Else node ids lie below this, each used once, the root's
    /// 0, in no order: a change commit that split or merged a leaf gave new
    /// nodes the next ids and left removed ones' unused.
    pub node_ids: u32,
    /// Bytes of node records, and of geometry records, over all blocks (block fill).
    pub node_bytes: u64,
    /// Bytes of geometry records over all geometry blocks.
    pub geometry_bytes: u64,
    /// (eps_k, measured error) for k = 1 .. 16.
    pub lod_table: [[f64; 2]; LOD_TABLE_LEN],
    /// How the levels of detail below M were built.
    pub lods: LodCodes,
    /// The key index's root block and its checksum, its levels (1: the
    /// root is a leaf) and its blocks (format-spec/keys.md).
    pub keys_block: u32,
    /// The checksum the key index's root block must carry.
    pub keys_checksum: u32,
    /// Levels of the key index, 1 ..= 64.
    pub keys_height: u32,
    /// Blocks of the key index.
    pub keys_blocks: u32,
    /// Every other block the commit that wrote this meta block wrote, with
    /// the checksum it carries, when that commit synced once (its slot's
    /// state 3, format-spec/commit.md): a reader verifies them before it
    /// takes the commit as whole. Empty otherwise.
    pub written: Vec<(u32, u32)>,
    /// The keys the latest change commits changed, as many commits as the
    /// block has room for after `written` (format-spec/meta.md, "The change log").
    pub log: ChangeLog,
}

/// Where the list of written blocks starts: its count, then (block,
/// checksum) pairs.
const WRITTEN_AT: usize = FRAME_LEN + size_of::<MetaRecord>();

/// Blocks a meta block of `block_size` bytes can list as written.
pub fn written_capacity(block_size: u32) -> usize {
    (block_size as usize).saturating_sub(WRITTEN_AT + 4) / 8
}

/// Bytes a meta block of `block_size` bytes has for its change log when it
/// lists `written` blocks.
pub fn log_room(block_size: u32, written: usize) -> usize {
    (block_size as usize).saturating_sub(WRITTEN_AT + 4 + 8 * written)
}

/// The largest valid method code (6, refine).
pub const MAX_METHOD: u8 = 6;
/// The largest valid tie-break code.
pub const MAX_TIE_BREAK: u8 = 2;
/// The largest valid leaf-rule code.
pub const MAX_LEAF_RULE: u8 = 1;

impl Meta {
    /// Writes the payload into `block` (frame left for `seal`).
    pub fn encode(&self, block: &mut [u8]) {
        let f = |x: f64| F64::new(x);
        let r = MetaRecord {
            root_block: self.root_block.into(),
            root_checksum: self.root_checksum.into(),
            root_offset: self.root_offset.into(),
            object_count: self.object_count.into(),
            node_count: self.node_count.into(),
            leaf_count: self.leaf_count.into(),
            depth: self.depth.into(),
            node_blocks: self.node_blocks.into(),
            geometry_blocks: self.geometry_blocks.into(),
            triangle_count: self.triangle_count.into(),
            vertex_count: self.vertex_count.into(),
            scene_box: self.scene_box.map(f),
            method: self.build.method,
            tie_break: self.build.tie_break,
            leaf_rule: self.build.leaf_rule,
            reserved1: 0,
            look_ahead: self.build.look_ahead.into(),
            rate: f(self.build.rate),
            leaf_capacity: self.build.leaf_capacity.into(),
            object_ids: self.object_ids.into(),
            node_ids: self.node_ids.into(),
            build_seconds: f(self.build.build_seconds),
            lod_table: self.lod_table.map(|p| p.map(f)),
            lattice_origin: self.lods.lattice_origin.map(f),
            lattice_cell: f(self.lods.lattice_cell),
            lod_flags: self.lods.flags.into(),
            cuberille_bits: self.lods.cuberille_bits.into(),
            cuberille_object_bits: self.lods.cuberille_object_bits.into(),
            reserved2: [0; 4],
            lod_grid_level: self.lods.grid_level,
            lod_usage: self.lods.usage.map(|p| p.map(U64::new)),
            node_bytes: self.node_bytes.into(),
            geometry_bytes: self.geometry_bytes.into(),
            query_extent: self.lods.query_extent.map(f),
            lod_predicted: self.lods.predicted.map(|p| p.map(F32::new)),
            keys_block: self.keys_block.into(),
            keys_checksum: self.keys_checksum.into(),
            keys_height: self.keys_height.into(),
            keys_blocks: self.keys_blocks.into(),
            log_since: self.log.since.into(),
            log_bytes: (self.log.bytes.len() as u32).into(),
        };
        block[FRAME_LEN..WRITTEN_AT].copy_from_slice(r.as_bytes());
        // The caller keeps the list within `written_capacity` and the log
        // within `log_room`.
        let mut at = WRITTEN_AT;
        block[at..at + 4].copy_from_slice(&(self.written.len() as u32).to_le_bytes());
        at += 4;
        for &(b, sum) in &self.written {
            block[at..at + 4].copy_from_slice(&b.to_le_bytes());
            block[at + 4..at + 8].copy_from_slice(&sum.to_le_bytes());
            at += 8;
        }
        block[at..at + self.log.bytes.len()].copy_from_slice(&self.log.bytes);
        block[at + self.log.bytes.len()..].fill(0);
    }

    /// Reads the payload of meta block `id` (checksum already verified).
    pub fn decode(id: u32, block: &[u8]) -> Result<Meta, StorageError> {
        let r = block
            .get(FRAME_LEN..WRITTEN_AT)
            .and_then(|b| MetaRecord::read_from_bytes(b).ok())
            .ok_or_else(|| StorageError::corrupt(id, "meta", "block too small"))?;
        let (written, list_end) = decode_written(id, block)?;
        let log_end = list_end.saturating_add(r.log_bytes.get() as usize);
        let log = ChangeLog {
            since: r.log_since.get(),
            bytes: block
                .get(list_end..log_end)
                .ok_or_else(|| {
                    StorageError::corrupt(id, "log_bytes", format!("a log of {} bytes past the block", r.log_bytes))
                })?
                .to_vec(),
        };
        let txn = block.get(8..16).and_then(|b| b.try_into().ok()).map_or(0, u64::from_le_bytes);
        log.validate(id, txn)?;
        if r.reserved1 != 0 || r.reserved2 != [0; 4] || !all_zero(block.get(log_end..).unwrap_or(&[])) {
            return Err(StorageError::corrupt(id, "reserved", "reserved bytes are not zero"));
        }
        let build = decode_build(id, &r)?;
        let (objects, nodes, leaves) = (r.object_count.get(), r.node_count.get(), r.leaf_count.get());
        if objects == 0 || leaves == 0 || u64::from(nodes) != 2 * u64::from(leaves) - 1 || leaves > objects {
            return bad(
                id,
                "node_count",
                format!("{nodes} nodes, {leaves} leaves, {objects} objects is not a binary tree"),
            );
        }
        let object_ids = r.object_ids.get();
        if object_ids < objects {
            return bad(id, "object_ids", format!("ids below {object_ids} for {objects} objects"));
        }
        let node_ids = r.node_ids.get();
        if node_ids != 0 && node_ids < nodes {
            return bad(id, "node_ids", format!("ids below {node_ids} for {nodes} nodes"));
        }
        let scene_box = r.scene_box.map(|x| x.get());
        if scene_box.iter().any(|x| !x.is_finite()) || (0..3).any(|i| scene_box[i] > scene_box[i + 3]) {
            return bad(id, "scene_box", format!("{scene_box:?} is not a box"));
        }
        let (lod_table, lods) = decode_lods(id, &r)?;
        let (keys_height, keys_blocks) = (r.keys_height.get(), r.keys_blocks.get());
        if r.keys_block.get() == 0
            || !(1..=keys::MAX_HEIGHT).contains(&keys_height)
            || keys_blocks < keys_height
        {
            return bad(
                id,
                "keys_height",
                format!(
                    "a key index of {keys_height} levels in {keys_blocks} blocks at block {}",
                    r.keys_block.get()
                ),
            );
        }
        Ok(Meta {
            root_block: r.root_block.get(),
            root_checksum: r.root_checksum.get(),
            root_offset: r.root_offset.get(),
            object_count: objects,
            node_count: nodes,
            leaf_count: leaves,
            depth: r.depth.get(),
            node_blocks: r.node_blocks.get(),
            geometry_blocks: r.geometry_blocks.get(),
            triangle_count: r.triangle_count.get(),
            vertex_count: r.vertex_count.get(),
            scene_box,
            build,
            object_ids,
            node_ids,
            node_bytes: r.node_bytes.get(),
            geometry_bytes: r.geometry_bytes.get(),
            lod_table,
            lods,
            keys_block: r.keys_block.get(),
            keys_checksum: r.keys_checksum.get(),
            keys_height,
            keys_blocks,
            written,
            log,
        })
    }
}

/// A corruption of meta block `id`'s `field`.
fn bad<T>(id: u32, field: &'static str, detail: String) -> Result<T, StorageError> {
    Err(StorageError::corrupt(id, field, detail))
}

/// The blocks meta block `id` lists as written, and the end of the list.
fn decode_written(id: u32, block: &[u8]) -> Result<(Vec<(u32, u32)>, usize), StorageError> {
    let count = block
        .get(WRITTEN_AT..WRITTEN_AT + 4)
        .and_then(|b| b.try_into().ok())
        .map_or(0, |b| u32::from_le_bytes(b) as usize);
    if count > written_capacity(block.len() as u32) {
        return bad(
            id,
            "written",
            format!("{count} blocks listed, a block holds {}", written_capacity(block.len() as u32)),
        );
    }
    let list_end = WRITTEN_AT + 4 + 8 * count;
    let written = block[WRITTEN_AT + 4..list_end]
        .chunks_exact(8)
        .map(|p| (u32::from_le_bytes([p[0], p[1], p[2], p[3]]), u32::from_le_bytes([p[4], p[5], p[6], p[7]])))
        .collect();
    Ok((written, list_end))
}

/// How the tree of meta block `id` was built, every code a known one.
fn decode_build(id: u32, r: &MetaRecord) -> Result<BuildCodes, StorageError> {
    if r.method > MAX_METHOD {
        return bad(id, "method", format!("unknown code {}", r.method));
    }
    if r.tie_break > MAX_TIE_BREAK {
        return bad(id, "tie_break", format!("unknown code {}", r.tie_break));
    }
    if r.leaf_rule > MAX_LEAF_RULE {
        return bad(id, "leaf_rule", format!("unknown code {}", r.leaf_rule));
    }
    let rate = r.rate.get();
    if !(0.0..=0.5).contains(&rate) {
        return bad(id, "rate", format!("{rate} is outside [0, 0.5]"));
    }
    Ok(BuildCodes {
        method: r.method,
        tie_break: r.tie_break,
        leaf_rule: r.leaf_rule,
        look_ahead: r.look_ahead.get(),
        rate,
        leaf_capacity: r.leaf_capacity.get(),
        build_seconds: r.build_seconds.get(),
    })
}

/// The levels of detail of meta block `id`: the LOD table, and how the
/// levels below M were built.
fn decode_lods(id: u32, r: &MetaRecord) -> Result<([[f64; 2]; LOD_TABLE_LEN], LodCodes), StorageError> {
    let lattice_origin = r.lattice_origin.map(|x| x.get());
    let lattice_cell = r.lattice_cell.get();
    if lattice_origin.iter().any(|x| !x.is_finite()) || !(lattice_cell.is_finite() && lattice_cell >= 0.0) {
        return bad(id, "lattice", format!("origin {lattice_origin:?}, cell {lattice_cell}"));
    }
    let query_extent = r.query_extent.map(|x| x.get());
    if query_extent.iter().any(|x| !(x.is_finite() && *x >= 0.0)) {
        return bad(id, "query_extent", format!("{query_extent:?}"));
    }
    if r.lod_flags.get() != 0 {
        return bad(id, "lod_flags", format!("unknown bits {:#x}", r.lod_flags.get()));
    }
    if r.lod_predicted.iter().flatten().any(|x| !(x.get().is_finite() && x.get() >= 0.0)) {
        return bad(id, "lod_predicted", "a prediction is negative or not finite".into());
    }
    if r.lod_table.iter().flatten().any(|x| !(x.get().is_finite() && x.get() >= 0.0)) {
        return bad(id, "lod_table", "an error is negative or not finite".into());
    }
    let lods = LodCodes {
        lattice_origin,
        lattice_cell,
        flags: r.lod_flags.get(),
        cuberille_bits: r.cuberille_bits.get(),
        cuberille_object_bits: r.cuberille_object_bits.get(),
        grid_level: r.lod_grid_level,
        usage: r.lod_usage.map(|p| p.map(|x| x.get())),
        query_extent,
        predicted: r.lod_predicted.map(|p| p.map(|x| x.get())),
    };
    Ok((r.lod_table.map(|p| p.map(|x| x.get())), lods))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Key;
    use crate::store::format::change_log::ChangeKind;
    use crate::store::format::frame::{BlockType, seal};

    /// A meta block of `bs` bytes for commit `txn`, listing `written` and `log`.
    fn block(bs: usize, txn: u64, written: usize, log: &ChangeLog) -> (Meta, Vec<u8>) {
        let meta = Meta {
            object_count: 1,
            node_count: 1,
            leaf_count: 1,
            object_ids: 1,
            keys_block: 5,
            keys_height: 1,
            keys_blocks: 1,
            written: (0..written as u32).map(|b| (b + 10, b)).collect(),
            log: log.clone(),
            ..Meta::default()
        };
        let mut bytes = vec![0u8; bs];
        meta.encode(&mut bytes);
        seal(1, &mut bytes, BlockType::Meta, txn);
        (meta, bytes)
    }

    #[test]
    fn the_log_follows_the_written_list_and_comes_back_as_written() {
        let changes = [(ChangeKind::Inserted, Key::Int(4)), (ChangeKind::Removed, Key::Int(9))];
        let log = ChangeLog::starting_at(2).after(3, &changes, log_room(1024, 3)).unwrap();
        assert_eq!(log.bytes.len(), 32);
        let (meta, bytes) = block(1024, 3, 3, &log);
        assert_eq!(&bytes[920..928], &2u64.to_le_bytes(), "log_since");
        assert_eq!(&bytes[936 + 24..936 + 24 + 8], &3u64.to_le_bytes(), "the record after the list");
        assert_eq!(Meta::decode(1, &bytes).unwrap(), meta);
        // The room left after the list bounds the log.
        assert_eq!(log_room(1024, 11), 0);
        assert_eq!(written_capacity(1024), 11);
        let full = ChangeLog::starting_at(2).after(3, &changes, log_room(1024, 11)).unwrap();
        assert_eq!(full, ChangeLog::starting_at(3));
    }

    #[test]
    fn a_log_past_the_block_or_after_its_commit_is_refused() {
        let log = ChangeLog::starting_at(2).after(3, &[(ChangeKind::Updated, Key::Int(1))], 100).unwrap();
        let (_, bytes) = block(1024, 3, 0, &log);
        let resealed = |f: &dyn Fn(&mut [u8]), txn: u64| {
            let mut b = bytes.clone();
            f(&mut b);
            seal(1, &mut b, BlockType::Meta, txn);
            Meta::decode(1, &b)
        };
        assert!(resealed(&|_| {}, 3).is_ok());
        assert!(resealed(&|_| {}, 2).is_err(), "a record of a later commit than the block's");
        assert!(resealed(&|b| b[928..932].copy_from_slice(&200u32.to_le_bytes()), 3).is_err(), "log_bytes past the block");
        assert!(resealed(&|b| b[928..932].copy_from_slice(&21u32.to_le_bytes()), 3).is_err(), "a record cut short");
        assert!(resealed(&|b| b[1000] = 1, 3).is_err(), "a byte after the log");
    }
}
