//! Claim: every input in the checked-in fuzz corpus (`fuzz/corpus/`) runs
//! through the fuzz targets' bodies without a panic.

use std::path::Path;

fn replay(target: &str, body: fn(&[u8])) -> usize {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz/corpus").join(target);
    let mut n = 0;
    for entry in std::fs::read_dir(&dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display())) {
        let path = entry.unwrap().path();
        body(&std::fs::read(&path).unwrap());
        n += 1;
    }
    n
}

#[test]
fn the_corpus_replays_without_a_panic() {
    assert!(replay("decode_block", mktree::fuzzing::decode_block) > 0);
    assert!(replay("open_and_query", mktree::fuzzing::open_and_query) > 0);
}
