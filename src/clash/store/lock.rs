//! One writer of a clash store at a time (format-spec/clash-store.md,
//! "Writing and crashes"). A run loads the store, measures for minutes on a large file,
//! and writes the store back whole; a status set by another process in
//! between would be lost under it. So a writer holds an exclusive lock on
//! `STORE.lock` from before it loads until after it has saved.
//!
//! The lock is the operating system's whole-file lock (`flock` on Unix,
//! `LockFileEx` on Windows, through `std::fs::File::lock`), held by an open
//! handle of the lock file: it excludes other processes and other handles
//! in the same process alike, and the system drops it when the process
//! ends, however it ends. The store itself cannot carry it: a save renames
//! a new file over it. The lock file is never removed, since removing it
//! would let a waiter lock a file no longer at the path.

use std::fs::{File, OpenOptions, TryLockError};
use std::path::{Path, PathBuf};

use super::ClashStore;
use crate::clash::ClashError;

/// The exclusive right to change the clash store at a path, until dropped.
#[derive(Debug)]
pub struct StoreLock {
    store: PathBuf,
    /// Holds the lock while open.
    _file: File,
}

/// The lock file of the store at `store`: `STORE.lock`.
pub fn lock_path(store: &Path) -> PathBuf {
    let mut s = store.as_os_str().to_owned();
    s.push(".lock");
    PathBuf::from(s)
}

impl StoreLock {
    /// The lock of the store at `store`, waiting while another writer
    /// holds it.
    pub fn acquire(store: &Path) -> Result<StoreLock, ClashError> {
        let (path, file) = open(store)?;
        file.lock().map_err(|e| ClashError::io(&path, e))?;
        Ok(StoreLock { store: store.to_path_buf(), _file: file })
    }

    /// The lock of the store at `store` if no other writer holds it;
    /// `None` if one does.
    pub fn try_acquire(store: &Path) -> Result<Option<StoreLock>, ClashError> {
        let (path, file) = open(store)?;
        match file.try_lock() {
            Ok(()) => Ok(Some(StoreLock { store: store.to_path_buf(), _file: file })),
            Err(TryLockError::WouldBlock) => Ok(None),
            Err(TryLockError::Error(e)) => Err(ClashError::io(&path, e)),
        }
    }

    /// The store's path.
    pub fn path(&self) -> &Path {
        &self.store
    }

    /// The store as it is now (an empty store when there is no file).
    pub fn load(&self) -> Result<ClashStore, ClashError> {
        ClashStore::load(&self.store)
    }

    /// Writes `store` over the locked one: a new file beside it, synced and
    /// renamed over it, so a crash leaves the old store or this one.
    pub fn save(&self, store: &ClashStore) -> Result<(), ClashError> {
        store.write_to(&self.store)
    }
}

/// The lock file of `store`, opened for locking (created when absent).
fn open(store: &Path) -> Result<(PathBuf, File), ClashError> {
    let path = lock_path(store);
    let file = OpenOptions::new()
        .read(true)
        .write(true)
        .create(true)
        .truncate(false)
        .open(&path)
        .map_err(|e| ClashError::io(&path, e))?;
    Ok((path, file))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_second_handle_waits_until_the_first_is_dropped() {
        let dir = tempfile::tempdir().unwrap();
        let store = dir.path().join("m.mkt.clash");
        let first = StoreLock::acquire(&store).unwrap();
        assert!(StoreLock::try_acquire(&store).unwrap().is_none());
        let (tx, rx) = std::sync::mpsc::channel();
        let waiter = std::thread::spawn({
            let store = store.clone();
            move || {
                let lock = StoreLock::acquire(&store).unwrap();
                tx.send(()).unwrap();
                drop(lock);
            }
        });
        // The waiter cannot have the lock while the first holds it.
        assert!(rx.recv_timeout(std::time::Duration::from_millis(200)).is_err());
        drop(first);
        rx.recv_timeout(std::time::Duration::from_secs(30)).unwrap();
        waiter.join().unwrap();
        assert!(StoreLock::try_acquire(&store).unwrap().is_some());
        assert!(lock_path(&store).exists());
    }

    #[test]
    fn a_lock_in_a_missing_folder_is_an_io_error_naming_it() {
        let dir = tempfile::tempdir().unwrap();
        let store = dir.path().join("no such folder").join("m.mkt.clash");
        let e = StoreLock::acquire(&store).unwrap_err();
        assert!(matches!(e, ClashError::Io { .. }), "{e}");
        assert!(e.to_string().contains("m.mkt.clash.lock"), "{e}");
    }
}
