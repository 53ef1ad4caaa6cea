//! Every field offset and size in `format-spec/*.md` equals the Rust
//! record's, so the spec and the code cannot drift apart silently.

use std::mem::offset_of;

use super::frame::{FRAME_LEN, Frame};
use super::freelist::FreeListHeader;
use super::geometry::ObjectHeader;
use super::header::{FixedHeader, Slot};
use super::meta::MetaRecord;
use super::node::{LodEntryRaw, NodeBlockHeader, NodeFixed};
use super::run::RunHeader;

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
        root_slot,
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
        names_block,
        names_checksum,
        build_seconds,
        lod_table
    );

    let node = include_str!("../../../format-spec/node.md");
    field!(node, Some("## Block payload"), FRAME_LEN, NodeBlockHeader, record_count);
    field!(node, Some("## Block payload"), FRAME_LEN, NodeBlockHeader, record_size);
    macro_rules! rec { ($($f:ident),*) => { $( field!(node, Some("## Node record"), 0, NodeFixed, $f); )* } }
    rec!(
        node_id,
        kind,
        split_axis,
        split_order,
        split_overlap,
        split_gap,
        level,
        object_count,
        child0_block,
        child0_checksum,
        child1_block,
        child1_checksum,
        child0_slot,
        child1_slot,
        child0_box,
        child1_box
    );
    assert_eq!(row(node, Some("## Node record"), "box"), (offset_of!(NodeFixed, aabb), 24));
    let lod = Some("## LOD entry");
    field!(node, lod, 0, LodEntryRaw, tag);
    field!(node, lod, 0, LodEntryRaw, value);
    field!(node, lod, 0, LodEntryRaw, aux);
    field!(node, lod, 0, LodEntryRaw, checksum);

    let geometry = include_str!("../../../format-spec/geometry.md");
    field!(geometry, Some("## First block"), FRAME_LEN, RunHeader, run_blocks);
    field!(geometry, Some("## First block"), FRAME_LEN, RunHeader, record_count);
    field!(geometry, Some("## First block"), FRAME_LEN, RunHeader, data_bytes);
    macro_rules! obj { ($($f:ident),*) => { $( field!(geometry, Some("## Object record"), 0, ObjectHeader, $f); )* } }
    obj!(object_id, vertex_count, triangle_count, anchor);

    let freelist = include_str!("../../../format-spec/freelist.md");
    macro_rules! fl { ($($f:ident),*) => { $( field!(freelist, None, FRAME_LEN, FreeListHeader, $f); )* } }
    fl!(next_block, next_checksum, range_count);
}
