//! The bodies of the fuzz targets in `fuzz/`, as library functions so that
//! `cargo test` replays the checked-in corpus (`tests/fuzz_corpus.rs`). Each
//! must return normally on any input: errors are fine, panics and hangs are
//! bugs. No count read from the input is capped here: the decoders must
//! bound their own work.

use std::sync::Arc;

use crate::db::{Database, check, read_hierarchy};
use crate::geom::Aabb;
use crate::query::{QueryOptions, Region, query_region};
use crate::store::BlockDevice;
use crate::store::device::MemDevice;
use crate::store::format::freelist::FreeListBlock;
use crate::store::format::meta::Meta;
use crate::store::format::node::{self, Limits};
use crate::store::format::{frame, geometry, run};

/// Decodes one block of arbitrary bytes as every block type, and the bytes
/// after the first as every blob kind. The first byte chooses M (1..=16);
/// the rest, padded or cut to 1,024 bytes, is the block.
pub fn decode_block(data: &[u8]) {
    let Some((&m, rest)) = data.split_first() else { return };
    let m = m % 16 + 1;
    let mut block = rest.to_vec();
    block.resize(1024, 0);
    let _ = frame::open(7, &block);
    if let Ok(offsets) =
        node::validate_block(7, &block, &Limits { block_size: 1024, lod_levels: m, object_count: 1 << 20 })
    {
        // A validated block must be readable in place without failing.
        for o in offsets {
            if node::NodeView::at(&block, o).is_err() {
                panic!("record {o} validated but cannot be viewed");
            }
        }
    }
    let _ = Meta::decode(7, &block);
    let _ = FreeListBlock::decode(7, &block);
    let lattice = crate::lod::Lattice { origin: crate::geom::Point::origin(), cell: 1.0 };
    let _ = crate::lod::decode(rest, &lattice, &Aabb::from_array([0.0, 0.0, 0.0, 40.0, 30.0, 20.0]));
    let _ = geometry::decode_object(7, rest);
    if let Ok((_, words, len)) = run::assemble(7, &[&block]) {
        let (records, _, _) = run::header(7, &block).unwrap_or_default();
        let _ = geometry::decode_names(7, &words, len, records);
    }
}

/// Opens arbitrary bytes as a file and, if that works, queries, walks and checks it.
pub fn open_and_query(data: &[u8]) {
    let Ok(db) = Database::open_on(Arc::new(MemDevice::from_bytes(data.to_vec())) as Arc<dyn BlockDevice>)
    else {
        return;
    };
    if let Ok(r) = db.begin_read() {
        for (b, lod) in
            [([-1e12, -1e12, -1e12, 1e12, 1e12, 1e12], None), ([0.0, 0.0, 0.0, 100.0, 100.0, 100.0], None)]
                .into_iter()
                .chain([([0.0, 0.0, 0.0, 100.0, 100.0, 100.0], Some(1))])
        {
            let _ = query_region(
                &r,
                &Region::Box(Aabb::from_array(b)),
                &QueryOptions { lod, ..Default::default() },
                None,
            );
        }
        let _ = read_hierarchy(&r);
        let _ = r.names();
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
