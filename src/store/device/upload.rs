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
        let mut writer = WriteMultipart::new_with_chunk_size(store.put_multipart(&path).await?, PART);
        let sent = send(&mut writer, device, len).await;
        // Every part in flight answered, so that a failed one is seen here.
        let sent = match sent {
            Ok(parts) => writer.wait_for_capacity(0).await.map(|()| parts),
            Err(e) => Err(e),
        };
        match sent {
            Ok(parts) => Ok((writer.finish().await?, parts.max(1))),
            Err(e) => {
                // Nothing half-written is left in the store.
                let _ = writer.abort().await;
                Err(e)
            }
        }
    })?;
    let (put, parts) = sent.map_err(|e| remote(&name, e.to_string()))?;
    Ok(Published { bytes: len, parts, e_tag: put.e_tag, version: put.version })
}

/// Reads `device` in parts (on a thread that may block, not the runtime's)
/// and hands them to `writer`; the parts sent.
async fn send(
    writer: &mut WriteMultipart,
    device: Arc<dyn BlockDevice>,
    len: u64,
) -> object_store::Result<u64> {
    let mut parts = 0u64;
    let mut at = 0u64;
    while at < len {
        let n = PART.min(usize::try_from(len - at).unwrap_or(usize::MAX));
        let device = device.clone();
        let read = tokio::task::spawn_blocking(move || {
            let mut buf = vec![0u8; n];
            device.read_at(at, &mut buf).map(|()| buf)
        })
        .await
        .map_err(std::io::Error::other)
        .and_then(|r| r);
        let buf =
            read.map_err(|e| object_store::Error::Generic { store: "local file", source: Box::new(e) })?;
        writer.wait_for_capacity(IN_FLIGHT).await?;
        writer.write(&buf);
        parts += 1;
        at += n as u64;
    }
    Ok(parts)
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
