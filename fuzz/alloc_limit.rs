//! A global allocator that refuses any one allocation above [`LIMIT`], so
//! that an allocation sized from a forged count fails the run (an abort,
//! which libFuzzer reports as a crash) even when its pages are never
//! touched and the RSS limit would not see it. The fuzzed files are a few
//! KiB: nothing decoding them needs a fraction of the limit.

use std::alloc::{GlobalAlloc, Layout, System};

/// The largest single allocation allowed.
pub const LIMIT: usize = 64 << 20;

/// The system allocator, refusing allocations above [`LIMIT`].
pub struct Limited;

// SAFETY: every call is forwarded to `System` unchanged, or refused with a
// null pointer, which `GlobalAlloc` allows for any allocation.
unsafe impl GlobalAlloc for Limited {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if layout.size() > LIMIT { std::ptr::null_mut() } else { unsafe { System.alloc(layout) } }
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        if layout.size() > LIMIT { std::ptr::null_mut() } else { unsafe { System.alloc_zeroed(layout) } }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if new_size > LIMIT { std::ptr::null_mut() } else { unsafe { System.realloc(ptr, layout, new_size) } }
    }
}
