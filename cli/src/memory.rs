//! The process's memory: the import's freed buffers handed back to the
//! system, and the peak resident size a build reports.

/// Hands the import's freed buffers back to the system. The parallel
/// importers free them in the allocator's per-thread arenas, where glibc
/// keeps them and the build's later allocations, mostly on other arenas,
/// do not reuse them: without this, ship 10^6 peaks 0.3 GB higher.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
pub fn release_freed_memory() {
    // SAFETY: malloc_trim only returns free pages of the allocator's
    // arenas to the system; it touches no live allocation.
    unsafe {
        libc::malloc_trim(0);
    }
}

#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
pub fn release_freed_memory() {}

/// The process's peak resident memory so far (the kernel's VmHWM), where
/// the system tells it.
pub fn peak_rss_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find_map(|l| l.strip_prefix("VmHWM:"))?;
    let kb: u64 = line.trim().strip_suffix("kB")?.trim().parse().ok()?;
    Some(kb * 1024)
}
