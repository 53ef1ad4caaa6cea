//! A device over a file, with positioned reads and writes (no shared cursor,
//! so readers in several threads need no lock).

use std::fs::File;
use std::io;
use std::os::unix::fs::FileExt;

use super::BlockDevice;

/// A file on disk.
#[derive(Debug)]
pub struct FileDevice {
    file: File,
}

impl FileDevice {
    /// Wraps an open file (read-write for writes).
    pub fn new(file: File) -> FileDevice {
        FileDevice { file }
    }

    /// The underlying file (to lock it).
    pub fn file(&self) -> &File {
        &self.file
    }
}

impl BlockDevice for FileDevice {
    fn read_at(&self, offset: u64, buf: &mut [u8]) -> io::Result<()> {
        self.file.read_exact_at(buf, offset)
    }
    fn write_at(&self, offset: u64, data: &[u8]) -> io::Result<()> {
        self.file.write_all_at(data, offset)
    }
    fn sync(&self) -> io::Result<()> {
        self.file.sync_data()
    }
    fn len(&self) -> io::Result<u64> {
        Ok(self.file.metadata()?.len())
    }
    fn set_len(&self, len: u64) -> io::Result<()> {
        self.file.set_len(len)
    }
}
