//! Every field offset and size in `format-spec/*.md` equals the Rust
//! record's, so the spec and the code cannot drift apart silently.

use std::mem::offset_of;

use super::frame::{FRAME_LEN, Frame};
use super::freelist::FreeListHeader;
use super::geometry::ObjectHeader;
use super::header::{FixedHeader, Slot};
use super::meta::MetaRecord;
use super::node::{BlockHead, BoundRaw, ChildRaw, InternalRaw, LeafRaw, ObjectRaw};

/// (offset, size) of the row whose name column is `` `name` `` in the
/// table that follows `heading` (or the file's first table) in `md`.
fn row(md: &str, heading: Option<&str>, name: &str) -> (usize, usize) {
    let text = heading.map_or(md, |h| &md[md.find(h).unwrap_or_else(|| panic!("heading {h}"))..]);
    let want = format!("`{name}`");
    let line = text
        .lines()
        .find(|l| l.starts_with('|') && l.split('|').nth(4).is_some_and(|c| c.trim() == want))
        .unwrap_or_else(|| panic!("no row {want} under {heading:?}"));
    let cells: Vec<&str> = line.split('|').map(str::trim).collect();
    (cells[1].parse().unwrap(), cells[2].parse().unwrap())
}

macro_rules! field {
    ($md:expr, $heading:expr, $base:expr, $ty:ty, $field:ident) => {{
        let got = $base + offset_of!($ty, $field);
        let size = size_of_val(&<$ty as zerocopy::FromZeros>::new_zeroed().$field);
        assert_eq!(
            row($md, $heading, stringify!($field)),
            (got, size),
            "{}::{}",
            stringify!($ty),
            stringify!($field)
        );
    }};
}

#[test]
fn spec_tables_match_the_records() {
    let blocks = include_str!("../../../format-spec/blocks.md");
    field!(blocks, None, 0, Frame, checksum);
    field!(blocks, None, 0, Frame, txn);
    assert_eq!(row(blocks, None, "type"), (offset_of!(Frame, block_type), 1));

    let header = include_str!("../../../format-spec/header.md");
    for f in [
        ("magic", offset_of!(FixedHeader, magic), 8),
        ("format_version", offset_of!(FixedHeader, format_version), 4),
        ("block_size", offset_of!(FixedHeader, block_size), 4),
        ("lod_levels", offset_of!(FixedHeader, lod_levels), 1),
        ("header_checksum", offset_of!(FixedHeader, header_checksum), 4),
    ] {
        assert_eq!(row(header, Some("## Fixed region"), f.0), (f.1, f.2), "{}", f.0);
    }
    let slot = Some("## Commit slot");
    field!(header, slot, 0, Slot, txn);
    field!(header, slot, 0, Slot, state);
    field!(header, slot, 0, Slot, meta_block);
    field!(header, slot, 0, Slot, meta_checksum);
    field!(header, slot, 0, Slot, block_count);
    field!(header, slot, 0, Slot, freelist_block);
    field!(header, slot, 0, Slot, freelist_checksum);
    field!(header, slot, 0, Slot, free_blocks);
    field!(header, slot, 0, Slot, slot_checksum);

    let meta = include_str!("../../../format-spec/meta.md");
    macro_rules! meta { ($($f:ident),*) => { $( field!(meta, None, FRAME_LEN, MetaRecord, $f); )* } }
    meta!(
        root_block,
        root_checksum,
        root_offset,
        object_count,
        node_count,
        leaf_count,
        depth,
        node_blocks,
        geometry_blocks,
        triangle_count,
        vertex_count,
        scene_box,
        method,
        tie_break,
        leaf_rule,
        look_ahead,
        rate,
        leaf_capacity,
        object_ids,
        build_seconds,
        lod_table,
        lattice_origin,
        lattice_cell,
        lod_flags,
        cuberille_bits,
        cuberille_object_bits,
        lod_grid_level,
        lod_usage,
        node_bytes,
        geometry_bytes,
        query_extent,
        lod_predicted,
        keys_block,
        keys_checksum,
        keys_height,
        keys_blocks,
        log_since,
        log_bytes
    );

    let node = include_str!("../../../format-spec/node.md");
    let payload = Some("## Block payload");
    field!(node, payload, FRAME_LEN, BlockHead, used_bytes);
    field!(node, payload, FRAME_LEN, BlockHead, record_count);
    field!(node, payload, FRAME_LEN, BlockHead, reserved);
    macro_rules! internal { ($($f:ident),*) => { $( field!(node, Some("## Internal record"), 0, InternalRaw, $f); )* } }
    internal!(kind, split, flags, reserved, node_id, object_count, split_overlap, split_gap, children);
    macro_rules! child { ($($f:ident),*) => { $( field!(node, Some("### Child entry"), 0, ChildRaw, $f); )* } }
    child!(qbox, block, checksum, offset, node_blocks, geometry_blocks);
    macro_rules! leaf { ($($f:ident),*) => { $( field!(node, Some("## Leaf record"), 0, LeafRaw, $f); )* } }
    leaf!(kind, flags, object_count, node_id, first_block, span, keys_bytes, bounds_bytes);
    macro_rules! object { ($($f:ident),*) => { $( field!(node, Some("### Object entry"), 0, ObjectRaw, $f); )* } }
    object!(object_id, qbox, position);
    macro_rules! bound { ($($f:ident),*) => { $( field!(node, Some("## Bounds"), 0, BoundRaw, $f); )* } }
    bound!(target, level_bytes);

    let lod = include_str!("../../../format-spec/lod.md");
    macro_rules! blob { ($($f:ident),*) => { $( field!(lod, Some("## Inline voxel blob"), 0, super::blob::BlobHead, $f); )* } }
    blob!(level, form);

    let geometry = include_str!("../../../format-spec/geometry.md");
    macro_rules! obj { ($($f:ident),*) => { $( field!(geometry, Some("## Object record"), 0, ObjectHeader, $f); )* } }
    obj!(object_id, vertex_count, triangle_count, anchor);

    #[cfg(feature = "redb")]
    {
        use super::table::StateRecord;
        let redb = include_str!("../../../format-spec/redb.md");
        let state = Some("## The state record");
        macro_rules! state { ($($f:ident),*) => { $( field!(redb, state, 0, StateRecord, $f); )* } }
        state!(
            magic,
            format_version,
            block_size,
            lod_levels,
            reserved0,
            meta_block,
            txn,
            meta_checksum,
            block_count,
            free_blocks,
            range_count,
            reserved1
        );
    }

    let freelist = include_str!("../../../format-spec/freelist.md");
    macro_rules! fl { ($($f:ident),*) => { $( field!(freelist, None, FRAME_LEN, FreeListHeader, $f); )* } }
    fl!(next_block, next_checksum, range_count);
}
