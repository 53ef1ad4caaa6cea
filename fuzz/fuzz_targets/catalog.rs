//! A catalog document from arbitrary bytes (format-spec/catalog.md).
#![no_main]

#[path = "../alloc_limit.rs"]
mod alloc_limit;

#[global_allocator]
static ALLOC: alloc_limit::Limited = alloc_limit::Limited;

libfuzzer_sys::fuzz_target!(|data: &[u8]| mktree_fuzz::catalog(data));
