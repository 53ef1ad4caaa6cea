//! Block 0 and the meta block of a valid file forged, every checksum re-sealed.
#![no_main]

#[path = "../alloc_limit.rs"]
mod alloc_limit;

#[global_allocator]
static ALLOC: alloc_limit::Limited = alloc_limit::Limited;

libfuzzer_sys::fuzz_target!(init: mktree_fuzz::one_thread(), |data: &[u8]| mktree_fuzz::forge_header(data));
