//! A device in memory: for tests, fuzzing and benchmarks.

use std::io;
use std::sync::RwLock;

use super::BlockDevice;

/// Bytes in memory.
#[derive(Debug, Default)]
pub struct MemDevice {
    data: RwLock<Vec<u8>>,
}

impl MemDevice {
    /// An empty device.
    pub fn new() -> MemDevice {
        MemDevice::default()
    }

    /// A device holding `bytes` (an image to open).
    pub fn from_bytes(bytes: Vec<u8>) -> MemDevice {
        MemDevice { data: RwLock::new(bytes) }
    }

    /// A copy of the bytes.
    pub fn to_bytes(&self) -> Vec<u8> {
        self.data.read().unwrap_or_else(|e| e.into_inner()).clone()
    }
}

fn range(offset: u64, len: usize) -> io::Result<std::ops::Range<usize>> {
    let start = usize::try_from(offset).map_err(|_| io::Error::other("offset too large"))?;
    let end = start.checked_add(len).ok_or_else(|| io::Error::other("offset too large"))?;
    Ok(start..end)
}

/// Writes `bytes` at `offset` of `image`, growing it with zeros as needed;
/// an empty write grows nothing, as on a file.
pub(super) fn write_into(image: &mut Vec<u8>, offset: u64, bytes: &[u8]) -> io::Result<()> {
    if bytes.is_empty() {
        return Ok(());
    }
    let r = range(offset, bytes.len())?;
    if image.len() < r.end {
        image.resize(r.end, 0);
    }
    image[r].copy_from_slice(bytes);
    Ok(())
}

impl BlockDevice for MemDevice {
    fn read_at(&self, offset: u64, buf: &mut [u8]) -> io::Result<()> {
        let data = self.data.read().unwrap_or_else(|e| e.into_inner());
        let r = range(offset, buf.len())?;
        let src = data.get(r).ok_or_else(|| io::Error::from(io::ErrorKind::UnexpectedEof))?;
        buf.copy_from_slice(src);
        Ok(())
    }
    fn write_at(&self, offset: u64, bytes: &[u8]) -> io::Result<()> {
        write_into(&mut self.data.write().unwrap_or_else(|e| e.into_inner()), offset, bytes)
    }
    fn sync(&self) -> io::Result<()> {
        Ok(())
    }
    fn len(&self) -> io::Result<u64> {
        Ok(self.data.read().unwrap_or_else(|e| e.into_inner()).len() as u64)
    }
    fn set_len(&self, len: u64) -> io::Result<()> {
        let len = usize::try_from(len).map_err(|_| io::Error::other("length too large"))?;
        self.data.write().unwrap_or_else(|e| e.into_inner()).resize(len, 0);
        Ok(())
    }
    fn writes_are_atomic(&self) -> bool {
        true
    }
}
