//! The locks as `LockFileEx` byte-range locks, owned by the handle.
//! Windows has no query for a conflicting lock: `taken` tries an exclusive
//! lock on the range and releases it at once. A range this handle itself
//! holds shared also counts as taken, which only keeps more blocks.

use std::fs::File;
use std::io;
use std::os::windows::io::AsRawHandle;

use windows_sys::Win32::Foundation::{ERROR_IO_PENDING, ERROR_LOCK_VIOLATION, HANDLE};
use windows_sys::Win32::Storage::FileSystem::{
    LOCKFILE_EXCLUSIVE_LOCK, LOCKFILE_FAIL_IMMEDIATELY, LockFileEx, UnlockFileEx,
};
use windows_sys::Win32::System::IO::OVERLAPPED;

use super::Kind;

/// An `OVERLAPPED` that carries only the range's start.
fn at(start: u64) -> OVERLAPPED {
    // SAFETY: `OVERLAPPED` is a plain C struct for which all-zero is valid.
    let mut o: OVERLAPPED = unsafe { std::mem::zeroed() };
    o.Anonymous.Anonymous.Offset = start as u32;
    o.Anonymous.Anonymous.OffsetHigh = (start >> 32) as u32;
    o
}

fn handle(file: &File) -> HANDLE {
    file.as_raw_handle() as HANDLE
}

/// Locks `len` bytes from `start`; `Ok(false)` on a conflict when not waiting.
fn lock(file: &File, exclusive: bool, start: u64, len: u64, wait: bool) -> io::Result<bool> {
    let mut flags = if wait { 0 } else { LOCKFILE_FAIL_IMMEDIATELY };
    if exclusive {
        flags |= LOCKFILE_EXCLUSIVE_LOCK;
    }
    let mut o = at(start);
    // SAFETY: a valid handle, and an OVERLAPPED that outlives the synchronous call.
    let ok = unsafe { LockFileEx(handle(file), flags, 0, len as u32, (len >> 32) as u32, &mut o) };
    if ok != 0 {
        return Ok(true);
    }
    let e = io::Error::last_os_error();
    match e.raw_os_error().map(|c| c as u32) {
        Some(ERROR_LOCK_VIOLATION) | Some(ERROR_IO_PENDING) if !wait => Ok(false),
        _ => Err(e),
    }
}

fn unlock(file: &File, start: u64, len: u64) -> io::Result<()> {
    let mut o = at(start);
    // SAFETY: as in `lock`.
    let ok = unsafe { UnlockFileEx(handle(file), 0, len as u32, (len >> 32) as u32, &mut o) };
    if ok != 0 { Ok(()) } else { Err(io::Error::last_os_error()) }
}

/// Sets (or releases) a lock on byte `start`; `Ok(false)` when another
/// owner holds a conflicting one and `wait` is false.
pub(super) fn set(file: &File, kind: Kind, start: u64, wait: bool) -> io::Result<bool> {
    match kind {
        Kind::Shared => lock(file, false, start, 1, wait),
        Kind::Exclusive => lock(file, true, start, 1, wait),
        Kind::Unlock => unlock(file, start, 1).map(|()| true),
    }
}

/// The kind of a lock another owner holds on byte `start`, if any. Windows
/// cannot be asked, so a shared lock is tried: it fails only beside an
/// exclusive one.
pub(super) fn holder(file: &File, start: u64, _len: u64) -> io::Result<Option<Kind>> {
    if !taken(file, start, 1)? {
        return Ok(None);
    }
    if lock(file, false, start, 1, false)? {
        unlock(file, start, 1)?;
        return Ok(Some(Kind::Shared));
    }
    Ok(Some(Kind::Exclusive))
}

/// True when a lock in `start .. start + len` conflicts with an exclusive one.
pub(super) fn taken(file: &File, start: u64, len: u64) -> io::Result<bool> {
    if lock(file, true, start, len, false)? {
        unlock(file, start, len)?;
        return Ok(false);
    }
    Ok(true)
}
