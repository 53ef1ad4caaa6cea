//! Publishing a committed file to object storage (format-spec/remote.md,
//! "Publishing"): the whole file as one object, uploaded in parts, so that
//! a reader sees the object before or after, never a mixture; the new
//! object's ETag and version.

use std::sync::Arc;

use object_store::{ObjectStore, WriteMultipart};

use super::BlockDevice;
use super::object::{RemoteOptions, remote, store_for_url, wait};
use crate::store::StorageError;

/// The size of an upload's parts: above S3's 5 MiB least, small enough
/// that four in flight stay modest.
const PART: usize = 16 << 20;
/// Parts uploading at once.
const IN_FLIGHT: usize = 4;

/// What a publish uploaded.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct Published {
    /// Bytes uploaded: the whole file.
    pub bytes: u64,
    /// Parts of the multipart upload.
    pub parts: u64,
    /// The new object's ETag, when the store gives one.
    pub e_tag: Option<String>,
    /// The new object's version, when the store keeps versions.
    pub version: Option<String>,
}

/// Uploads every byte of `device` as the object `url` names.
pub(crate) fn upload(
    device: Arc<dyn BlockDevice>,
    url: &str,
    options: &RemoteOptions,
) -> Result<Published, StorageError> {
    let (store, path) = store_for_url(url, options)?;
    let len = device.len()?;
    let name = url.to_string();
    let sent = wait(async move {
        let mut parts = 0u64;
        let mut writer = WriteMultipart::new_with_chunk_size(store.put_multipart(&path).await?, PART);
        let mut buf = vec![0u8; PART.min(usize::try_from(len).unwrap_or(PART))];
        let mut at = 0u64;
        while at < len {
            let n = buf.len().min(usize::try_from(len - at).unwrap_or(usize::MAX));
            if let Err(e) = device.read_at(at, &mut buf[..n]) {
                // Nothing half-written is left behind in the store.
                let _ = writer.abort().await;
                return Err(object_store::Error::Generic { store: "local file", source: Box::new(e) });
            }
            writer.wait_for_capacity(IN_FLIGHT).await?;
            writer.write(&buf[..n]);
            parts += 1;
            at += n as u64;
        }
        let put = writer.finish().await?;
        Ok::<_, object_store::Error>((put, parts.max(1)))
    })?;
    let (put, parts) = sent.map_err(|e| remote(&name, e.to_string()))?;
    Ok(Published { bytes: len, parts, e_tag: put.e_tag, version: put.version })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::store::device::MemDevice;

    #[test]
    fn a_file_url_receives_the_device_byte_for_byte() {
        let dir = tempfile::tempdir().expect("tempdir");
        let bytes: Vec<u8> = (0..(PART + 12_345)).map(|i| (i % 251) as u8).collect();
        let device = Arc::new(MemDevice::new());
        device.write_at(0, &bytes).expect("write");
        let target = dir.path().join("published.mkt");
        let url = format!("file://{}", target.display());
        let done = upload(device, &url, &RemoteOptions::default()).expect("upload");
        assert_eq!(done.bytes, bytes.len() as u64);
        assert_eq!(done.parts, 2);
        assert_eq!(std::fs::read(&target).expect("uploaded"), bytes);
    }
}
