//! The clash store (format-spec/clash-store.md): saved tests and the last
//! recorded run of each, with statuses and each object's fingerprint, in a
//! sidecar file beside the .mkt file (`FILE.mkt.clash`). A versioned,
//! checksummed envelope around the body (`body.rs`; version 1's
//! JSON body is still read); written whole to a new file, synced and
//! renamed over the old one, so a crash leaves the old store or the new
//! one, by one writer at a time (`lock.rs`). Reading bounds the size
//! before it allocates, checks the envelope, the checksum and every field.

mod body;
mod lock;

use std::collections::BTreeMap;
use std::io::{Seek, Write};
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::ClashError;
use super::group::GroupBy;
use super::status::{Status, Tracked};
use super::test::Clash;
use super::test::{ClashTest, MAX_NAME};
use crate::geom::Aabb;
use crate::scene::Key;

pub use lock::{StoreLock, lock_path};

/// The envelope's first 8 bytes.
pub const MAGIC: [u8; 8] = *b"MKTCLASH";
/// The store version this build writes; it reads this and version 1
/// (a JSON body), whose statuses a re-run then carries into version 2.
pub const VERSION: u32 = 2;
/// The oldest store version this build reads.
pub const OLDEST_VERSION: u32 = 1;
/// The envelope's length, bytes.
pub const HEADER_LEN: usize = 32;
/// The largest store read, bytes (1 GiB): larger is refused before any allocation.
pub const MAX_STORE_BYTES: u64 = 1 << 30;

/// A saved test: its settings and how its clashes are grouped.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SavedTest {
    /// The test.
    pub test: ClashTest,
    /// Its grouping (`none`, `a`, `proximity:G`, `prefix:N`).
    #[serde(with = "group_text")]
    pub group: GroupBy,
}

/// What an object was when a run read it: an update or insert gives an
/// object a new id (format-spec/meta.md, `object_ids`), so a key whose id
/// and box are unchanged holds the same object (docs/clash.md, "Re-runs").
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Fingerprint {
    /// The object's key.
    #[serde(with = "super::key_json")]
    pub key: Key,
    /// Its object id.
    pub id: u32,
    /// Its exact box.
    pub aabb: [f64; 6],
}

impl Fingerprint {
    /// The box.
    pub fn aabb(&self) -> Aabb {
        Aabb::from_array(self.aabb)
    }
}

/// The last recorded run of a test.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RecordedRun {
    /// The commit it read.
    pub txn: u64,
    /// The test as it ran.
    pub test: ClashTest,
    /// Every clash found so far, with its status (resolved ones too).
    pub tracked: Vec<Tracked>,
    /// The file's `object_ids` then.
    pub object_ids: u32,
    /// The bits of the file's build time then (a bulk load changes it).
    pub build: u64,
    /// Every object of the file then, in key order.
    pub objects: Vec<Fingerprint>,
}

impl RecordedRun {
    /// The run's clashes, in (a, b, type) order: its tracked clashes that
    /// it found (the resolved ones left out).
    pub fn clashes(&self) -> impl Iterator<Item = &Clash> {
        self.tracked
            .iter()
            .filter(|t| t.last_txn == self.txn && t.status != Status::Resolved)
            .map(|t| &t.clash)
    }
}

/// Saved tests and recorded runs, by test name.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClashStore {
    /// Saved tests by name.
    pub tests: BTreeMap<String, SavedTest>,
    /// The last recorded run of each test, by name.
    pub runs: BTreeMap<String, RecordedRun>,
}

/// The sidecar store's path for the .mkt file `file`: `FILE.mkt.clash`.
pub fn store_path(file: &Path) -> PathBuf {
    let mut s = file.as_os_str().to_owned();
    s.push(".clash");
    PathBuf::from(s)
}

impl ClashStore {
    /// The store's bytes: the envelope, then the body.
    pub fn to_bytes(&self) -> Result<Vec<u8>, ClashError> {
        let mut out = body::encode_after(self, vec![0; HEADER_LEN])
            .map_err(|e| ClashError::Test(format!("the store: {e}")))?;
        let (head, body) = out.split_at_mut(HEADER_LEN);
        head.copy_from_slice(&header(VERSION, body));
        Ok(out)
    }

    /// A store from its bytes; any damage or forgery is an error naming it.
    pub fn from_bytes(bytes: &[u8]) -> Result<ClashStore, String> {
        if bytes.len() < HEADER_LEN {
            return Err(format!("{} bytes: shorter than the {HEADER_LEN}-byte header", bytes.len()));
        }
        if bytes[..8] != MAGIC {
            return Err("not a clash store (magic)".into());
        }
        let u32_at = |i: usize| u32::from_le_bytes([bytes[i], bytes[i + 1], bytes[i + 2], bytes[i + 3]]);
        let version = u32_at(8);
        if !(OLDEST_VERSION..=VERSION).contains(&version) {
            return Err(format!(
                "version {version}; this build reads versions {OLDEST_VERSION} to {VERSION}"
            ));
        }
        if u32_at(12) != 0 || u32_at(28) != 0 {
            return Err("reserved header bytes are not zero".into());
        }
        let mut len = [0u8; 8];
        len.copy_from_slice(&bytes[16..24]);
        let len = u64::from_le_bytes(len);
        if len != (bytes.len() - HEADER_LEN) as u64 {
            return Err(format!(
                "the header says {len} body bytes, the file has {}",
                bytes.len() - HEADER_LEN
            ));
        }
        let body = &bytes[HEADER_LEN..];
        if crc32fast::hash(body) != u32_at(24) {
            return Err("checksum mismatch: the body is damaged".into());
        }
        let store: ClashStore = match version {
            1 => serde_json::from_slice(body).map_err(|e| format!("body: {e}"))?,
            _ => body::decode(body).map_err(|e| format!("body: {e}"))?,
        };
        store.validate()?;
        Ok(store)
    }

    /// Checks what JSON cannot: names, test numbers, keys in order.
    fn validate(&self) -> Result<(), String> {
        for name in self.tests.keys().chain(self.runs.keys()) {
            if name.is_empty() || name.len() > MAX_NAME {
                return Err(format!("a test name of {} bytes (1 ..= {MAX_NAME})", name.len()));
            }
        }
        for (name, t) in &self.tests {
            t.test.validate().map_err(|e| format!("test {name:?}: {e}"))?;
        }
        for (name, r) in &self.runs {
            r.test.validate().map_err(|e| format!("run {name:?}: {e}"))?;
            if !r.objects.windows(2).all(|w| w[0].key < w[1].key) {
                return Err(format!("run {name:?}: objects are not in strictly increasing key order"));
            }
        }
        Ok(())
    }

    /// The store at `path`; an empty store when there is no file.
    pub fn load(path: &Path) -> Result<ClashStore, ClashError> {
        let size = match std::fs::metadata(path) {
            Ok(m) => m.len(),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(ClashStore::default()),
            Err(e) => return Err(ClashError::io(path, e)),
        };
        if size > MAX_STORE_BYTES {
            return Err(ClashError::Store {
                path: path.display().to_string(),
                why: format!("{size} bytes, past the {MAX_STORE_BYTES}-byte limit"),
            });
        }
        let bytes = std::fs::read(path).map_err(|e| ClashError::io(path, e))?;
        ClashStore::from_bytes(&bytes)
            .map_err(|why| ClashError::Store { path: path.display().to_string(), why })
    }

    /// Writes the store to `path`: a new file beside it, synced, renamed
    /// over it, and the folder synced (a crash leaves the old store or this
    /// one). Only through a [`StoreLock`], so that no other writer's
    /// changes are written over.
    fn write_to(&self, path: &Path) -> Result<(), ClashError> {
        let mut tmp = path.as_os_str().to_owned();
        tmp.push(".new");
        let tmp = PathBuf::from(tmp);
        let mut f = std::fs::File::create(&tmp).map_err(|e| ClashError::io(&tmp, e))?;
        // The body streams to the file behind a blank header, which is
        // written once the body's length and checksum are known.
        f.write_all(&[0; HEADER_LEN]).map_err(|e| ClashError::io(&tmp, e))?;
        let (mut crc, mut len, mut failed) = (crc32fast::Hasher::new(), 0u64, None);
        let encoded = body::encode_into(self, &mut |chunk| {
            crc.update(chunk);
            len += chunk.len() as u64;
            f.write_all(chunk).map_err(|e| {
                let why = e.to_string();
                failed = Some(e);
                why
            })
        });
        if let Some(e) = failed {
            return Err(ClashError::io(&tmp, e));
        }
        encoded.map_err(|e| ClashError::Test(format!("the store: {e}")))?;
        f.seek(std::io::SeekFrom::Start(0)).map_err(|e| ClashError::io(&tmp, e))?;
        f.write_all(&header_of(VERSION, len, crc.finalize())).map_err(|e| ClashError::io(&tmp, e))?;
        f.sync_all().map_err(|e| ClashError::io(&tmp, e))?;
        drop(f);
        std::fs::rename(&tmp, path).map_err(|e| ClashError::io(path, e))?;
        #[cfg(unix)]
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()).or(Some(Path::new("."))) {
            std::fs::File::open(dir).and_then(|d| d.sync_all()).map_err(|e| ClashError::io(dir, e))?;
        }
        Ok(())
    }
}

/// The header of a store of `version` around `body`, then the body (for
/// tests and fuzzing: a store is written with its header in front).
#[cfg(any(test, feature = "internals"))]
pub fn envelope(version: u32, body: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(HEADER_LEN + body.len());
    out.extend_from_slice(&header(version, body));
    out.extend_from_slice(body);
    out
}

/// The header of a store of `version` whose body is `body`.
fn header(version: u32, body: &[u8]) -> [u8; HEADER_LEN] {
    header_of(version, body.len() as u64, crc32fast::hash(body))
}

fn header_of(version: u32, body_len: u64, body_crc: u32) -> [u8; HEADER_LEN] {
    let mut h = [0u8; HEADER_LEN];
    h[..8].copy_from_slice(&MAGIC);
    h[8..12].copy_from_slice(&version.to_le_bytes());
    h[16..24].copy_from_slice(&body_len.to_le_bytes());
    h[24..28].copy_from_slice(&body_crc.to_le_bytes());
    h
}

mod group_text {
    use super::GroupBy;
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(g: &GroupBy, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(g)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<GroupBy, D::Error> {
        String::deserialize(d)?.parse().map_err(serde::de::Error::custom)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::clash::test::TestKind;

    fn sample() -> ClashStore {
        let mut s = ClashStore::default();
        let test = ClashTest {
            a: vec!["name:PIPE*".parse().unwrap()],
            b: Some(vec!["class:IfcWall".parse().unwrap()]),
            kind: TestKind::Clearance,
            distance: 50.0,
            ..Default::default()
        };
        s.tests.insert("pipes-walls".into(), SavedTest { test, group: GroupBy::Proximity(500.0) });
        s
    }

    #[test]
    fn a_store_streamed_to_its_file_is_the_bytes_of_to_bytes() {
        // Megabytes of records, so that the body reaches the file in chunks.
        let mut s = sample();
        let tracked = (0..12_000u64)
            .map(|i| Tracked {
                clash: Clash::hard_at(i, i + 1, crate::geom::Point::new(i as f64, 0.5, -2.0)),
                status: Status::Active,
                first_txn: 2,
                last_txn: 3,
            })
            .collect();
        let objects =
            (0..5_000u64).map(|i| Fingerprint { key: Key::Int(i), id: i as u32, aabb: [0.0; 6] }).collect();
        let test = s.tests["pipes-walls"].test.clone();
        s.runs.insert(
            "pipes-walls".into(),
            RecordedRun { txn: 3, test, tracked, object_ids: 9, build: 7, objects },
        );
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.mkt.clash");
        s.write_to(&path).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        assert!(bytes.len() > 2 << 20, "{} bytes", bytes.len());
        assert_eq!(bytes, s.to_bytes().unwrap());
        assert_eq!(ClashStore::load(&path).unwrap(), s);
    }

    #[test]
    fn a_store_reads_back_and_every_damage_is_refused() {
        let s = sample();
        let bytes = s.to_bytes().unwrap();
        assert_eq!(ClashStore::from_bytes(&bytes).unwrap(), s);
        for i in [0, 8, 12, 16, 24, 28, HEADER_LEN, bytes.len() - 1] {
            let mut b = bytes.clone();
            b[i] ^= 0x40;
            assert!(ClashStore::from_bytes(&b).is_err(), "byte {i} flipped");
        }
        assert!(ClashStore::from_bytes(&bytes[..bytes.len() - 1]).is_err());
        assert!(ClashStore::from_bytes(&bytes[..10]).is_err());
    }

    #[test]
    fn a_version_1_store_reads_and_writes_back_as_version_2() {
        let s = sample();
        let v1 = envelope(1, &serde_json::to_vec(&s).unwrap());
        assert_eq!(ClashStore::from_bytes(&v1).unwrap(), s);
        let v2 = s.to_bytes().unwrap();
        assert_eq!(u32::from_le_bytes(v2[8..12].try_into().unwrap()), VERSION);
        assert_eq!(ClashStore::from_bytes(&v2).unwrap(), s);
        for version in [0, VERSION + 1] {
            let e = ClashStore::from_bytes(&envelope(version, &v2[HEADER_LEN..])).unwrap_err();
            assert!(e.contains(&format!("version {version}")), "{e}");
        }
    }

    #[test]
    fn save_replaces_the_file_whole() {
        let dir = std::env::temp_dir().join(format!("mktree-clash-store-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = store_path(&dir.join("m.mkt"));
        assert_eq!(ClashStore::load(&path).unwrap(), ClashStore::default(), "no file: an empty store");
        let s = sample();
        let lock = StoreLock::acquire(&path).unwrap();
        lock.save(&s).unwrap();
        assert_eq!(ClashStore::load(&path).unwrap(), s);
        lock.save(&ClashStore::default()).unwrap();
        assert_eq!(ClashStore::load(&path).unwrap(), ClashStore::default());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
