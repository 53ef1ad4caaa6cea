//! A ZIP archive of stored (uncompressed) entries, for BCF files
//! (docs/clash.md, "BCF"): local headers, the central directory and its
//! end record, as PKWARE's APPNOTE specifies them, without ZIP64. BCF
//! readers accept stored entries; the PNG snapshots are compressed already
//! and the XML is small, so no compressor is linked for it.

/// An archive being written, in memory.
#[derive(Default)]
pub(crate) struct ZipWriter {
    out: Vec<u8>,
    central: Vec<u8>,
    entries: u16,
}

/// The DOS date and time of 1 January 2026, 00:00 (entries carry no time of their own).
const DOS_TIME: u16 = 0;
const DOS_DATE: u16 = ((2026 - 1980) << 9) | (1 << 5) | 1;

impl ZipWriter {
    /// Adds the file `name` (a relative path with `/`) holding `data`.
    pub(crate) fn add(&mut self, name: &str, data: &[u8]) -> Result<(), String> {
        let too_big = || format!("{name}: the archive passes 4 GiB or 65,535 entries (no ZIP64 here)");
        let size = u32::try_from(data.len()).map_err(|_| too_big())?;
        let offset = u32::try_from(self.out.len()).map_err(|_| too_big())?;
        let name_len = u16::try_from(name.len()).map_err(|_| too_big())?;
        self.entries = self.entries.checked_add(1).ok_or_else(too_big)?;
        let crc = crc32fast::hash(data);
        // Local file header.
        let o = &mut self.out;
        o.extend_from_slice(&0x0403_4b50u32.to_le_bytes());
        o.extend_from_slice(&20u16.to_le_bytes()); // version needed: 2.0
        o.extend_from_slice(&0x0800u16.to_le_bytes()); // flags: names are UTF-8
        o.extend_from_slice(&0u16.to_le_bytes()); // stored
        o.extend_from_slice(&DOS_TIME.to_le_bytes());
        o.extend_from_slice(&DOS_DATE.to_le_bytes());
        o.extend_from_slice(&crc.to_le_bytes());
        o.extend_from_slice(&size.to_le_bytes());
        o.extend_from_slice(&size.to_le_bytes());
        o.extend_from_slice(&name_len.to_le_bytes());
        o.extend_from_slice(&0u16.to_le_bytes());
        o.extend_from_slice(name.as_bytes());
        o.extend_from_slice(data);
        u32::try_from(self.out.len()).map_err(|_| too_big())?;
        // Central directory entry.
        let c = &mut self.central;
        c.extend_from_slice(&0x0201_4b50u32.to_le_bytes());
        c.extend_from_slice(&20u16.to_le_bytes()); // made by: 2.0, MS-DOS
        c.extend_from_slice(&20u16.to_le_bytes());
        c.extend_from_slice(&0x0800u16.to_le_bytes());
        c.extend_from_slice(&0u16.to_le_bytes());
        c.extend_from_slice(&DOS_TIME.to_le_bytes());
        c.extend_from_slice(&DOS_DATE.to_le_bytes());
        c.extend_from_slice(&crc.to_le_bytes());
        c.extend_from_slice(&size.to_le_bytes());
        c.extend_from_slice(&size.to_le_bytes());
        c.extend_from_slice(&name_len.to_le_bytes());
        c.extend_from_slice(&[0; 12]); // extra, comment, disk, internal and external attributes
        c.extend_from_slice(&offset.to_le_bytes());
        c.extend_from_slice(name.as_bytes());
        Ok(())
    }

    /// The archive's bytes.
    pub(crate) fn finish(mut self) -> Result<Vec<u8>, String> {
        let too_big = || "the archive passes 4 GiB (no ZIP64 here)".to_string();
        let at = u32::try_from(self.out.len()).map_err(|_| too_big())?;
        let len = u32::try_from(self.central.len()).map_err(|_| too_big())?;
        self.out.extend_from_slice(&self.central);
        let o = &mut self.out;
        o.extend_from_slice(&0x0605_4b50u32.to_le_bytes());
        o.extend_from_slice(&[0; 4]); // this disk, the directory's disk
        o.extend_from_slice(&self.entries.to_le_bytes());
        o.extend_from_slice(&self.entries.to_le_bytes());
        o.extend_from_slice(&len.to_le_bytes());
        o.extend_from_slice(&at.to_le_bytes());
        o.extend_from_slice(&0u16.to_le_bytes());
        Ok(self.out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Reads the archive back by its central directory (as an unzipper
    /// does) and checks every entry's name, size, offset and checksum.
    #[test]
    fn entries_read_back_through_the_central_directory() {
        let files =
            [("bcf.version", b"<Version/>".to_vec()), ("a/b.png", vec![7u8; 1000]), ("empty", vec![])];
        let mut z = ZipWriter::default();
        for (n, d) in &files {
            z.add(n, d).unwrap();
        }
        let b = z.finish().unwrap();
        let u16_at = |i: usize| u16::from_le_bytes([b[i], b[i + 1]]) as usize;
        let u32_at = |i: usize| u32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]]) as usize;
        let end = b.len() - 22;
        assert_eq!(u32_at(end), 0x0605_4b50);
        assert_eq!(u16_at(end + 10), files.len());
        let mut at = u32_at(end + 16);
        for (name, data) in &files {
            assert_eq!(u32_at(at), 0x0201_4b50);
            let (size, nlen, offset) = (u32_at(at + 24), u16_at(at + 28), u32_at(at + 42));
            assert_eq!(&b[at + 46..at + 46 + nlen], name.as_bytes());
            assert_eq!(size, data.len());
            assert_eq!(u32_at(offset), 0x0403_4b50);
            let start = offset + 30 + u16_at(offset + 26);
            assert_eq!(&b[start..start + size], &data[..]);
            assert_eq!(u32_at(at + 16), crc32fast::hash(data) as usize);
            at += 46 + nlen;
        }
    }
}
