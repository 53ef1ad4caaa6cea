//! The bodies of the fuzz targets in `fuzz/`, as library functions so that
//! `cargo test` replays the checked-in corpus (`tests/fuzz_corpus.rs`). Each
//! must return normally on any input: errors are fine, panics and hangs are
//! bugs. No count read from the input is capped here: the decoders must
//! bound their own work. The structure-aware targets (`structure.rs`)
//! forge one structure of a valid file (`base.rs`) past its checksums
//! (`forge.rs` reads and re-seals the bytes, `edit.rs` and `forgeries.rs`
//! change them), and a file `check` passes must also answer right;
//! `api.rs` runs API calls and crashes against a model of the committed
//! scene. They reach the format through mktree's `internals` feature.

mod api;
mod base;
mod edit;
pub mod forge;
mod forgeries;
mod structure;

use std::sync::Arc;

pub use api::api_sequence;
pub use structure::{Structure, forged};

use mktree::db::{Database, check, read_hierarchy};
use mktree::geom::Aabb;
use mktree::query::{QueryOptions, Region, query_region};
use mktree::store::BlockDevice;
use mktree::store::device::MemDevice;
use mktree::store::format::freelist::FreeListBlock;
use mktree::store::format::meta::Meta;
use mktree::store::format::node::{self, Limits};
use mktree::store::format::quant::QuantBox;
use mktree::store::format::{frame, geometry, group, keys};

/// Makes the calling thread rayon's one worker, for a fuzz target's
/// process (its `init`): the bodies' parallel work (a write's layout and
/// levels of detail) then runs where it is called, with no hand-off to a
/// pool and no idle workers spinning beside the fuzzer. Answers do not
/// depend on the number of threads. A pool already built stays as it is.
pub fn one_thread() {
    let _ = rayon::ThreadPoolBuilder::new().num_threads(1).use_current_thread().build_global();
}

/// Decodes one block of arbitrary bytes as every block type, and the bytes
/// after the first as every blob kind. The first byte chooses M (1..=16);
/// the rest, padded or cut to 1,024 bytes, is the block.
pub fn decode_block(data: &[u8]) {
    let Some((&m, rest)) = data.split_first() else { return };
    let m = m % 16 + 1;
    let mut block = rest.to_vec();
    block.resize(1024, 0);
    let _ = frame::open(7, &block);
    let lattice = mktree::lod::Lattice { origin: mktree::geom::Point::origin(), cell: 1.0 };
    // A lone block has no meta block to bound its object ids: every id passes.
    let limits = Limits { block_size: 1024, lod_levels: m, object_count: u32::MAX };
    if let Ok(offsets) = node::validate_block(7, &block, &limits) {
        // A validated block must be readable in place without failing, and
        // every part of a record must read without a panic: child and object
        // boxes decode in a frame, inline bounds decode as voxel blobs.
        let frame = Aabb::from_array([0.0, 0.0, 0.0, 40.0, 30.0, 20.0]);
        for o in offsets {
            let view = node::NodeView::at(&block, o);
            let _ = view.as_ref().map(|v| v.frame(frame));
            match view {
                Err(_) => panic!("record {o} validated but cannot be viewed"),
                Ok(node::NodeView::Internal(n)) => {
                    for i in 0..2 {
                        let _ = n.child_box(i, &frame).map(|q| q.face_slabs());
                        let _ = (n.child_ref(i), n.child_blocks(i));
                    }
                    let _ = n.split();
                }
                Ok(node::NodeView::Leaf(l)) => {
                    let mut boxes = Vec::new();
                    for i in 0..l.len() {
                        let Some(ob) = l.object(i) else {
                            panic!("object {i} of record {o} validated but is missing")
                        };
                        boxes.push(QuantBox::decode(&frame, ob.qbox).map(|q| (q.outer, q.face_slabs())));
                    }
                    let _ = (l.geometry().1.count(), l.object_count());
                    // A validated leaf holds one key per object.
                    for i in 0..l.len() {
                        if l.key(i).is_none() {
                            panic!("entry {i} of record {o} validated but has no key")
                        }
                    }
                    for b in l.bounds() {
                        if let Some(Some((outer, _))) = boxes.get(usize::from(b.target)) {
                            let _ = mktree::lod::decode(b.blob, &lattice, outer);
                        }
                    }
                }
            }
        }
    }
    let _ = Meta::decode(7, &block);
    for leaf in [true, false] {
        // A decoded key block re-encodes to its own bytes (the encoding is canonical).
        if let Ok(kb) = keys::decode(7, &block, leaf) {
            let mut again = vec![0u8; block.len()];
            match &kb {
                keys::KeyBlock::Leaf(entries) => keys::encode_leaf(entries, &mut again),
                keys::KeyBlock::Branch(children) => keys::encode_branch(children, &mut again),
            }
            .unwrap_or_else(|e| panic!("a decoded key block does not encode: {e}"));
            assert_eq!(
                again[frame::FRAME_LEN..],
                block[frame::FRAME_LEN..],
                "a key block's encoding is canonical"
            );
        }
    }
    // A validated group block's entries are found and re-encode to its own bytes.
    if let Ok(entries) = group::validate(7, &block, m) {
        let mut drafts = Vec::new();
        for (record, level, range) in &entries {
            let blob = group::find(&block, &entries, *record, *level)
                .unwrap_or_else(|| panic!("entry ({record}, {level}) validated but is not found"));
            assert_eq!(blob, &block[range.clone()]);
            let _ = mktree::lod::decode(blob, &lattice, &Aabb::from_array([0.0, 0.0, 0.0, 40.0, 30.0, 20.0]));
            drafts.push(group::GroupEntry { record: *record, level: *level, blob: blob.to_vec() });
        }
        let mut again = vec![0u8; block.len()];
        group::encode(&drafts, &mut again)
            .unwrap_or_else(|e| panic!("a validated group block does not encode: {e}"));
        assert_eq!(
            again[frame::FRAME_LEN..],
            block[frame::FRAME_LEN..],
            "a group block's encoding is canonical"
        );
    }
    let _ = FreeListBlock::decode(7, &block);
    let _ = mktree::lod::decode(rest, &lattice, &Aabb::from_array([0.0, 0.0, 0.0, 40.0, 30.0, 20.0]));
    let _ = geometry::decode_object(7, rest);
}

/// Opens arbitrary bytes as a file and, if that works, queries, walks and checks it.
pub fn open_and_query(data: &[u8]) {
    let Ok(db) = Database::open_on(Arc::new(MemDevice::from_bytes(data.to_vec())) as Arc<dyn BlockDevice>)
    else {
        return;
    };
    if let Ok(r) = db.begin_read() {
        // Every level (each decides objects by boxes, faces, inline bounds or
        // geometry), everything and a corner, and a block budget.
        let m = r.info().map_or(1, |i| i.lod_levels);
        let everything = Aabb::from_array([-1e12, -1e12, -1e12, 1e12, 1e12, 1e12]);
        let corner = Aabb::from_array([0.0, 0.0, 0.0, 100.0, 100.0, 100.0]);
        for lod in (1..=m).map(Some) {
            for b in [everything, corner] {
                let _ = query_region(&r, &Region::Box(b), &QueryOptions { lod, ..Default::default() }, None);
            }
        }
        let _ = query_region(
            &r,
            &Region::Box(corner),
            &QueryOptions { budget: Some(2), ..Default::default() },
            None,
        );
        let _ = read_hierarchy(&r);
        let _ = r.names();
        // The change log (format-spec/meta.md): from the start and from the commit before.
        let _ = r.changes_since(0);
        let _ = r.changes_since(r.txn().saturating_sub(1));
        // Views read group bounds (format-spec/group.md), with and without a budget.
        let _ = r.group_summary();
        if let Some(b) = r.info().map(|i| Aabb::from_array(i.scene_box)) {
            let eye = mktree::geom::Point::new(b.min.x - 1000.0, b.center().y - 700.0, b.center().z + 300.0);
            let view = mktree::query::View {
                eye,
                target: b.center(),
                fov_deg: 60.0,
                width_px: 64,
                height_px: 48,
                near_mm: 1.0,
                far_mm: 1.0,
            }
            .seeing_all_of(&b);
            for (tolerance_px, budget) in [(4.0, None), (1.0, Some(3))] {
                let opts = mktree::query::ViewOptions { tolerance_px, budget, shapes: true };
                let _ = r.view(&view, &opts, None);
            }
        }
        if let Some(info) = r.info() {
            for k in 1..=info.lod_levels {
                for objects in [false, true] {
                    let _ = r.fetch_level(0, k, objects, &mut Default::default());
                }
            }
        }
    }
    let _ = check(&db);
}

/// Block 0 (fixed header, both copies of both slots) and the meta block
/// forged with every checksum re-sealed (`structure.rs`).
pub fn forge_header(data: &[u8]) {
    structure::forge(structure::Structure::Header, data)
}

/// Node blocks forged with every checksum re-sealed.
pub fn forge_node(data: &[u8]) {
    structure::forge(structure::Structure::Node, data)
}

/// Geometry blocks and the leaves' spans over them forged with every checksum re-sealed.
pub fn forge_geometry(data: &[u8]) {
    structure::forge(structure::Structure::Geometry, data)
}

/// Inline bounds (voxel blobs) and the lattice forged with every checksum re-sealed.
pub fn forge_lod(data: &[u8]) {
    structure::forge(structure::Structure::Lod, data)
}

/// The free list forged with every checksum re-sealed.
pub fn forge_free_list(data: &[u8]) {
    structure::forge(structure::Structure::FreeList, data)
}

/// The key index (its blocks and the meta block's root) and the leaves'
/// keys areas forged with every checksum re-sealed; lookups by key answer
/// as the base scene when `check` passes.
pub fn forge_keys(data: &[u8]) {
    structure::forge(structure::Structure::Keys, data)
}

/// A clash status store (format-spec/clash-store.md) from arbitrary bytes.
/// The first byte chooses: even, the bytes after it are the whole file;
/// 1 modulo 4, they are a version 1 (JSON) body in a valid envelope (right
/// length and checksum), 3 modulo 4 a version 2 (binary) body, so
/// mutations reach each body's parser and checks. A store that reads must
/// write back to bytes that read as the same store.
pub fn clash_store(data: &[u8]) {
    use mktree::clash::{ClashStore, OLDEST_VERSION, VERSION, envelope};
    let Some((&mode, rest)) = data.split_first() else { return };
    let bytes = if mode % 2 == 0 {
        rest.to_vec()
    } else {
        envelope(if mode % 4 == 1 { OLDEST_VERSION } else { VERSION }, rest)
    };
    if let Ok(store) = ClashStore::from_bytes(&bytes) {
        let again = store.to_bytes().expect("a store that reads writes");
        assert_eq!(ClashStore::from_bytes(&again).as_ref(), Ok(&store), "a store reads back as itself");
    }
}

/// A catalog document from arbitrary bytes (format-spec/catalog.md): one
/// that reads must write back to a document that reads as the same
/// catalog.
pub fn catalog(data: &[u8]) {
    use mktree::catalog::Catalog;
    if let Ok(catalog) = Catalog::from_json(data, None) {
        let again = Catalog::from_json(catalog.to_json().as_bytes(), None);
        assert_eq!(again.as_ref().ok(), Some(&catalog), "a catalog reads back as itself");
    }
}
