//! The locks as `fcntl` record locks. On Linux they belong to the open file
//! (`F_OFD_*`), so threads of one process and several opens of one file
//! behave as separate owners should; elsewhere they are POSIX record locks,
//! owned by the process.

use std::fs::File;
use std::io;
use std::os::fd::AsRawFd;

use super::Kind;

#[cfg(any(target_os = "linux", target_os = "android"))]
const SET: libc::c_int = libc::F_OFD_SETLK;
#[cfg(any(target_os = "linux", target_os = "android"))]
const SET_WAIT: libc::c_int = libc::F_OFD_SETLKW;
#[cfg(any(target_os = "linux", target_os = "android"))]
const GET: libc::c_int = libc::F_OFD_GETLK;
#[cfg(not(any(target_os = "linux", target_os = "android")))]
const SET: libc::c_int = libc::F_SETLK;
#[cfg(not(any(target_os = "linux", target_os = "android")))]
const SET_WAIT: libc::c_int = libc::F_SETLKW;
#[cfg(not(any(target_os = "linux", target_os = "android")))]
const GET: libc::c_int = libc::F_GETLK;

fn flock(kind: Kind, start: u64, len: u64) -> libc::flock {
    // SAFETY: `flock` is a plain C struct for which all-zero is valid
    // (and `l_pid` must be 0 for open-file-description locks).
    let mut fl: libc::flock = unsafe { std::mem::zeroed() };
    fl.l_type = match kind {
        Kind::Shared => libc::F_RDLCK,
        Kind::Exclusive => libc::F_WRLCK,
        Kind::Unlock => libc::F_UNLCK,
    } as _;
    fl.l_whence = libc::SEEK_SET as _;
    fl.l_start = start as libc::off_t;
    fl.l_len = len as libc::off_t;
    fl
}

/// Sets (or releases) a lock on byte `start`; `Ok(false)` when another
/// owner holds a conflicting one and `wait` is false.
pub(super) fn set(file: &File, kind: Kind, start: u64, wait: bool) -> io::Result<bool> {
    let fl = flock(kind, start, 1);
    loop {
        // SAFETY: a valid descriptor and a valid `flock` for the call's duration.
        let r = unsafe { libc::fcntl(file.as_raw_fd(), if wait { SET_WAIT } else { SET }, &fl) };
        if r == 0 {
            return Ok(true);
        }
        let e = io::Error::last_os_error();
        match e.raw_os_error() {
            Some(libc::EINTR) => continue,
            Some(libc::EAGAIN) | Some(libc::EACCES) if !wait => return Ok(false),
            _ => return Err(e),
        }
    }
}

/// True when another owner holds a lock in `start .. start + len` that an
/// exclusive lock would conflict with.
pub(super) fn taken(file: &File, start: u64, len: u64) -> io::Result<bool> {
    Ok(holder(file, start, len)?.is_some())
}

/// The kind of a lock another owner holds in `start .. start + len`, if any.
pub(super) fn holder(file: &File, start: u64, len: u64) -> io::Result<Option<Kind>> {
    let mut fl = flock(Kind::Exclusive, start, len);
    // SAFETY: as in `set`; the kernel writes the conflicting lock into `fl`.
    let r = unsafe { libc::fcntl(file.as_raw_fd(), GET, &mut fl) };
    if r != 0 {
        return Err(io::Error::last_os_error());
    }
    Ok(match fl.l_type as libc::c_int {
        libc::F_UNLCK => None,
        libc::F_RDLCK => Some(Kind::Shared),
        _ => Some(Kind::Exclusive),
    })
}
