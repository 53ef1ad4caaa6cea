//! An arbitrary file, opened, queried, walked and checked.
#![no_main]

#[path = "../alloc_limit.rs"]
mod alloc_limit;

#[global_allocator]
static ALLOC: alloc_limit::Limited = alloc_limit::Limited;

libfuzzer_sys::fuzz_target!(|data: &[u8]| mktree_fuzz::open_and_query(data));
