//! An arbitrary file, opened, queried, walked and checked.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| mktree::fuzzing::open_and_query(data));
