//! The bodies of the fuzz targets in `fuzz/`, as library functions so that
//! `cargo test` replays the checked-in corpus (`tests/fuzz_corpus.rs`). Each
//! must return normally on any input: errors are fine, panics and hangs are bugs.

use std::sync::Arc;

use crate::db::{Database, check};
use crate::geom::Aabb;
use crate::store::device::MemDevice;
use crate::store::format::freelist::FreeListBlock;
use crate::store::format::meta::Meta;
use crate::store::format::{frame, geometry, node, run};
use crate::store::{BlockDevice, ReadStats};

/// Decodes one block of arbitrary bytes as every block type. The first byte
/// chooses M (1..=16); the rest, padded or cut to 1,024 bytes, is the block.
pub fn decode_block(data: &[u8]) {
    let Some((&m, rest)) = data.split_first() else { return };
    let m = m % 16 + 1;
    let mut block = rest.to_vec();
    block.resize(1024, 0);
    let _ = frame::open(7, &block);
    let _ = node::decode_block(7, &block, m);
    let _ = Meta::decode(7, &block);
    let _ = FreeListBlock::decode(7, &block);
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
    }
    let _ = check(&db);
}
