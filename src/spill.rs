//! A temporary file for data that does not fit in memory while a scene is
//! read or loaded: appended to, read back at any offset. It lives in a
//! folder the caller names and is removed when dropped (on Unix at once,
//! so that only the open handle keeps it and a crash leaves nothing).

use std::fs::{File, OpenOptions};
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Distinct spill file names within one process.
static SPILLS: AtomicU64 = AtomicU64::new(0);

#[derive(Debug)]
pub(crate) struct SpillFile {
    path: PathBuf,
    writer: BufWriter<File>,
    reader: File,
    end: u64,
}

impl SpillFile {
    /// A new, empty spill file in folder `dir`, named after `what`.
    pub fn create_in(dir: &Path, what: &str) -> io::Result<SpillFile> {
        let n = SPILLS.fetch_add(1, Ordering::Relaxed);
        let path = dir.join(format!(".mktree-{what}-{}-{n}", std::process::id()));
        let file = OpenOptions::new().read(true).write(true).create_new(true).open(&path)?;
        let reader = file.try_clone()?;
        #[cfg(unix)]
        std::fs::remove_file(&path)?;
        Ok(SpillFile { path, writer: BufWriter::with_capacity(1 << 20, file), reader, end: 0 })
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Bytes appended so far.
    pub fn len(&self) -> u64 {
        self.end
    }

    /// Appends `bytes`, returning the offset they start at.
    pub fn append(&mut self, bytes: &[u8]) -> io::Result<u64> {
        self.writer.write_all(bytes)?;
        let at = self.end;
        self.end += bytes.len() as u64;
        Ok(at)
    }

    /// Makes everything appended readable.
    pub fn flush(&mut self) -> io::Result<()> {
        self.writer.flush()
    }

    /// Fills `buf` from offset `offset` (of bytes appended and flushed).
    pub fn read_exact_at(&self, buf: &mut [u8], offset: u64) -> io::Result<()> {
        read_exact_at(&self.reader, buf, offset)
    }
}

impl Drop for SpillFile {
    fn drop(&mut self) {
        #[cfg(not(unix))]
        let _ = std::fs::remove_file(&self.path);
    }
}

#[cfg(unix)]
fn read_exact_at(file: &File, buf: &mut [u8], offset: u64) -> io::Result<()> {
    std::os::unix::fs::FileExt::read_exact_at(file, buf, offset)
}

#[cfg(windows)]
fn read_exact_at(file: &File, mut buf: &mut [u8], mut offset: u64) -> io::Result<()> {
    while !buf.is_empty() {
        match std::os::windows::fs::FileExt::seek_read(file, buf, offset)? {
            0 => return Err(io::ErrorKind::UnexpectedEof.into()),
            n => {
                buf = &mut buf[n..];
                offset += n as u64;
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn appended_bytes_read_back_and_the_file_goes() {
        let dir = tempfile::tempdir().expect("dir");
        {
            let mut s = SpillFile::create_in(dir.path(), "test").expect("spill");
            assert_eq!(s.append(b"hello").expect("append"), 0);
            assert_eq!(s.append(b" world").expect("append"), 5);
            s.flush().expect("flush");
            let mut buf = [0u8; 5];
            s.read_exact_at(&mut buf, 6).expect("read");
            assert_eq!(&buf, b"world");
            assert_eq!(s.len(), 11);
            assert!(s.read_exact_at(&mut buf, 9).is_err(), "past the end");
        }
        assert_eq!(std::fs::read_dir(dir.path()).expect("dir").count(), 0);
    }
}
