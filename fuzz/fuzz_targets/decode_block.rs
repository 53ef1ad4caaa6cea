//! One block of arbitrary bytes, decoded as every block type.
#![no_main]

#[path = "../alloc_limit.rs"]
mod alloc_limit;

#[global_allocator]
static ALLOC: alloc_limit::Limited = alloc_limit::Limited;

libfuzzer_sys::fuzz_target!(|data: &[u8]| mktree_fuzz::decode_block(data));
