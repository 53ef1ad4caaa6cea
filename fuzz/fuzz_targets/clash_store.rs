//! A clash status store from arbitrary bytes: the whole file, or a
//! version 1 (JSON) or version 2 (binary) body in a valid envelope
//! (format-spec/clash-store.md).
#![no_main]

#[path = "../alloc_limit.rs"]
mod alloc_limit;

#[global_allocator]
static ALLOC: alloc_limit::Limited = alloc_limit::Limited;

libfuzzer_sys::fuzz_target!(|data: &[u8]| mktree_fuzz::clash_store(data));
