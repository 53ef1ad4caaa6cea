//! The key index of a valid file (its blocks, the meta block's root) and
//! the leaves' keys areas forged, every checksum re-sealed; lookups by key
//! must answer as the base scene when `check` passes.
#![no_main]

#[path = "../alloc_limit.rs"]
mod alloc_limit;

#[global_allocator]
static ALLOC: alloc_limit::Limited = alloc_limit::Limited;

libfuzzer_sys::fuzz_target!(init: mktree_fuzz::one_thread(), |data: &[u8]| mktree_fuzz::forge_keys(data));
