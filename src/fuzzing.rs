//! The bodies of the fuzz targets in `fuzz/`, as library functions so that
//! `cargo test` replays the checked-in corpus (`tests/fuzz_corpus.rs`). Each
//! must return normally on any input: errors are fine, panics and hangs are bugs.

use std::sync::Arc;

use crate::db::{Database, check};
use crate::geom::Aabb;
use crate::store::device::MemDevice;
use crate::store::format::freelist::FreeListBlock;
use crate::store::format::meta::Meta;
use crate::store::format::{frame, geometry, lodblock, node, objboxes, run};
use crate::store::{BlockDevice, ReadStats};

/// Decodes one block of arbitrary bytes as every block type, and the bytes
/// after the first as every blob kind. The first byte chooses M (1..=16);
/// the rest, padded or cut to 1,024 bytes, is the block.
pub fn decode_block(data: &[u8]) {
    let Some((&m, rest)) = data.split_first() else { return };
    let m = m % 16 + 1;
    let mut block = rest.to_vec();
    block.resize(1024, 0);
    let _ = frame::open(7, &block);
    let _ = node::decode_block(7, &block, m);
    let _ = Meta::decode(7, &block);
    let _ = FreeListBlock::decode(7, &block);
    let _ = lodblock::blob_at(7, &block, lodblock::BLOBS_START as u32);
    let _ = objboxes::decode(rest);
    let lattice = crate::lod::Lattice { origin: crate::geom::Point::origin(), cell: 1.0 };
    let _ = crate::lod::decode(rest, &lattice);
    let _ = crate::lod::decode_objects(rest, &lattice);
    if let Ok((_, words, len)) = run::assemble(7, &[&block]) {
        let (records, _, _) = run::header(7, &block).unwrap_or_default();
        let _ = geometry::decode_objects(7, &words, len, records.min(1 << 16));
        let _ = geometry::decode_names(7, &words, len, records.min(1 << 16));
    }
}

/// Opens arbitrary bytes as a file and, if that works, queries, walks and checks it.
pub fn open_and_query(data: &[u8]) {
    let Ok(db) = Database::open_on(Arc::new(MemDevice::from_bytes(data.to_vec())) as Arc<dyn BlockDevice>)
    else {
        return;
    };
    if let Ok(r) = db.begin_read() {
        let _ = r.query_box(&Aabb::from_array([-1e12, -1e12, -1e12, 1e12, 1e12, 1e12]));
        let _ = r.query_box(&Aabb::from_array([0.0, 0.0, 0.0, 100.0, 100.0, 100.0]));
        let _ = r.walk_nodes(&mut ReadStats::default(), |_, _| Ok(()));
        let _ = r.names();
        if let (Some(root), Some(info)) = (r.root(), r.info()) {
            for k in 1..=info.lod_levels {
                for objects in [false, true] {
                    let _ = r.fetch_level(root, k, objects, &mut ReadStats::default());
                }
            }
        }
    }
    let _ = check(&db);
}
