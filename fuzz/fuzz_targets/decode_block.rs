//! One block of arbitrary bytes, decoded as every block type.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| mktree::fuzzing::decode_block(data));
