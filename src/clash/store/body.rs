//! The clash store's version 2 body (format-spec/clash-store.md, "Body,
//! version 2"): the saved tests as JSON, and each recorded run's objects
//! and tracked clashes as fixed little-endian records, so that a re-run
//! after a few changes does not spend its time parsing and printing a run
//! of 10^5 clashes as text. Every count is bounded by the bytes left
//! before it sizes an allocation, and every number must be finite.

use std::collections::BTreeMap;

use super::{ClashStore, Fingerprint, RecordedRun, SavedTest};
use crate::clash::status::{Status, Tracked};
use crate::clash::test::{Clash, ClashKind, ClashTest};
use crate::geom::{Aabb, Point};
use crate::scene::Key;

/// The fewest bytes a key takes: an empty byte string (tag and length).
const MIN_KEY: usize = 2;
/// The fewest bytes an object's fingerprint takes: a key, its id, its box.
const MIN_FINGERPRINT: usize = MIN_KEY + 4 + 48;
/// The fewest bytes a tracked clash takes: two keys, type, depth,
/// distance, point, two absent options, two boxes, status, two commits.
const MIN_TRACKED: usize = 2 * MIN_KEY + 1 + 8 + 8 + 24 + 2 + 96 + 1 + 16;

/// The body of `store`.
#[cfg(test)]
pub(super) fn encode(store: &ClashStore) -> Result<Vec<u8>, String> {
    encode_after(store, Vec::new())
}

/// `head` followed by the body of `store` (the caller's header goes in
/// front without copying a body of hundreds of megabytes).
pub(super) fn encode_after(store: &ClashStore, mut head: Vec<u8>) -> Result<Vec<u8>, String> {
    // Reserved up front: a run of 10^5 clashes is tens of megabytes.
    let records: usize = store.runs.values().map(|r| r.objects.len() * 64 + r.tracked.len() * 256).sum();
    head.reserve(records + 4096);
    encode_into(store, &mut |chunk| {
        head.extend_from_slice(chunk);
        Ok(())
    })?;
    Ok(head)
}

/// The body of `store`, given to `sink` a chunk of about a megabyte at a
/// time: a store of 10^6 clashes is written to its file without the
/// hundreds of megabytes of a body in memory.
pub(super) fn encode_into(
    store: &ClashStore,
    sink: &mut dyn FnMut(&[u8]) -> Result<(), String>,
) -> Result<(), String> {
    const CHUNK: usize = 1 << 20;
    let mut w = Writer(Vec::with_capacity(CHUNK + 4096));
    let mut flush = |w: &mut Writer, at_least: usize| {
        if w.0.len() >= at_least {
            sink(&w.0)?;
            w.0.clear();
        }
        Ok::<(), String>(())
    };
    w.json(&store.tests)?;
    w.u32(count(store.runs.len())?);
    for (name, run) in &store.runs {
        w.u8(u8::try_from(name.len()).map_err(|_| format!("a test name of {} bytes", name.len()))?);
        w.0.extend_from_slice(name.as_bytes());
        w.json(&run.test)?;
        w.u64(run.txn);
        w.u32(run.object_ids);
        w.u64(run.build);
        w.u32(count(run.objects.len())?);
        for f in &run.objects {
            w.key(&f.key);
            w.u32(f.id);
            w.f64s(&f.aabb);
            flush(&mut w, CHUNK)?;
        }
        w.u32(count(run.tracked.len())?);
        for t in &run.tracked {
            w.clash(&t.clash);
            w.u8(status_code(t.status));
            w.u64(t.first_txn);
            w.u64(t.last_txn);
            flush(&mut w, CHUNK)?;
        }
    }
    flush(&mut w, 1)
}

/// The store a body holds; the store's own checks (names, tests, key
/// order) are the caller's.
pub(super) fn decode(body: &[u8]) -> Result<ClashStore, String> {
    let mut r = Reader { bytes: body, at: 0 };
    let tests: BTreeMap<String, SavedTest> = r.json("the tests")?;
    let runs_count = r.count(1)?;
    let mut runs = BTreeMap::new();
    for _ in 0..runs_count {
        let len = usize::from(r.u8()?);
        let name =
            std::str::from_utf8(r.take(len)?).map_err(|_| "a test name that is not UTF-8".to_string())?;
        let name = name.to_string();
        let test: ClashTest = r.json("a run's test")?;
        let (txn, object_ids, build) = (r.u64()?, r.u32()?, r.u64()?);
        let objects_count = r.count(MIN_FINGERPRINT)?;
        let mut objects = Vec::with_capacity(objects_count);
        for _ in 0..objects_count {
            objects.push(Fingerprint { key: r.key()?, id: r.u32()?, aabb: r.f64s()? });
        }
        let tracked_count = r.count(MIN_TRACKED)?;
        let mut tracked = Vec::with_capacity(tracked_count);
        for _ in 0..tracked_count {
            let clash = r.clash()?;
            let status = status_of(r.u8()?)?;
            tracked.push(Tracked { clash, status, first_txn: r.u64()?, last_txn: r.u64()? });
        }
        let run = RecordedRun { txn, test, tracked, object_ids, build, objects };
        if runs.insert(name.clone(), run).is_some() {
            return Err(format!("run {name:?} is recorded twice"));
        }
    }
    if r.at != body.len() {
        return Err(format!("{} bytes past the last run", body.len() - r.at));
    }
    Ok(ClashStore { tests, runs })
}

fn count(n: usize) -> Result<u32, String> {
    u32::try_from(n).map_err(|_| format!("{n} entries: more than a store lists"))
}

fn status_code(s: Status) -> u8 {
    match s {
        Status::New => 0,
        Status::Active => 1,
        Status::Reviewed => 2,
        Status::Approved => 3,
        Status::Resolved => 4,
    }
}

fn status_of(code: u8) -> Result<Status, String> {
    Ok(match code {
        0 => Status::New,
        1 => Status::Active,
        2 => Status::Reviewed,
        3 => Status::Approved,
        4 => Status::Resolved,
        _ => return Err(format!("status {code}")),
    })
}

fn kind_code(k: ClashKind) -> u8 {
    match k {
        ClashKind::Hard => 0,
        ClashKind::Clearance => 1,
        ClashKind::Touch => 2,
        ClashKind::Duplicate => 3,
    }
}

fn kind_of(code: u8) -> Result<ClashKind, String> {
    Ok(match code {
        0 => ClashKind::Hard,
        1 => ClashKind::Clearance,
        2 => ClashKind::Touch,
        3 => ClashKind::Duplicate,
        _ => return Err(format!("clash type {code}")),
    })
}

struct Writer(Vec<u8>);

impl Writer {
    fn u8(&mut self, v: u8) {
        self.0.push(v);
    }

    fn u32(&mut self, v: u32) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }

    fn u64(&mut self, v: u64) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }

    fn f64s(&mut self, v: &[f64]) {
        for x in v {
            self.0.extend_from_slice(&x.to_le_bytes());
        }
    }

    fn json<T: serde::Serialize>(&mut self, v: &T) -> Result<(), String> {
        let text = serde_json::to_vec(v).map_err(|e| e.to_string())?;
        self.u32(count(text.len())?);
        self.0.extend_from_slice(&text);
        Ok(())
    }

    fn key(&mut self, k: &Key) {
        match k {
            Key::Int(i) => {
                self.u8(0);
                self.u64(*i);
            }
            Key::Bytes(b) => {
                self.u8(1);
                // Key::bytes holds a key to Key::MAX_BYTES (255).
                self.u8(b.len() as u8);
                self.0.extend_from_slice(b);
            }
        }
    }

    fn option(&mut self, v: Option<[f64; 6]>) {
        self.u8(u8::from(v.is_some()));
        if let Some(v) = v {
            self.f64s(&v);
        }
    }

    fn clash(&mut self, c: &Clash) {
        self.key(&c.a);
        self.key(&c.b);
        self.u8(kind_code(c.kind));
        self.f64s(&[c.depth, c.distance, c.point.x, c.point.y, c.point.z]);
        self.option(c.closest.map(|[p, q]| [p.x, p.y, p.z, q.x, q.y, q.z]));
        self.option(c.overlap.map(|b| b.to_array()));
        self.f64s(&c.a_box.to_array());
        self.f64s(&c.b_box.to_array());
    }
}

struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8], String> {
        let end = self.at.checked_add(n).filter(|&e| e <= self.bytes.len());
        let end = end.ok_or_else(|| format!("cut short at byte {} (wants {n} more)", self.at))?;
        let s = &self.bytes[self.at..end];
        self.at = end;
        Ok(s)
    }

    fn array<const N: usize>(&mut self) -> Result<[u8; N], String> {
        let mut a = [0u8; N];
        a.copy_from_slice(self.take(N)?);
        Ok(a)
    }

    fn u8(&mut self) -> Result<u8, String> {
        Ok(self.array::<1>()?[0])
    }

    fn u32(&mut self) -> Result<u32, String> {
        Ok(u32::from_le_bytes(self.array()?))
    }

    fn u64(&mut self) -> Result<u64, String> {
        Ok(u64::from_le_bytes(self.array()?))
    }

    /// A count of entries of at least `min_len` bytes each, no more than
    /// the bytes left can hold.
    fn count(&mut self, min_len: usize) -> Result<usize, String> {
        let n = self.u32()? as usize;
        let left = self.bytes.len() - self.at;
        if n > left / min_len {
            return Err(format!("{n} entries in {left} bytes"));
        }
        Ok(n)
    }

    fn f64(&mut self) -> Result<f64, String> {
        let v = f64::from_le_bytes(self.array()?);
        if !v.is_finite() {
            return Err(format!("a number that is not finite before byte {}", self.at));
        }
        Ok(v)
    }

    fn f64s<const N: usize>(&mut self) -> Result<[f64; N], String> {
        let mut a = [0.0; N];
        for x in &mut a {
            *x = self.f64()?;
        }
        Ok(a)
    }

    fn json<T: serde::de::DeserializeOwned>(&mut self, what: &str) -> Result<T, String> {
        let len = self.u32()? as usize;
        serde_json::from_slice(self.take(len)?).map_err(|e| format!("{what}: {e}"))
    }

    fn key(&mut self) -> Result<Key, String> {
        match self.u8()? {
            0 => Ok(Key::Int(self.u64()?)),
            1 => {
                let len = usize::from(self.u8()?);
                Key::bytes(self.take(len)?).map_err(|e| e.to_string())
            }
            tag => Err(format!("key tag {tag}")),
        }
    }

    fn option(&mut self) -> Result<Option<[f64; 6]>, String> {
        match self.u8()? {
            0 => Ok(None),
            1 => Ok(Some(self.f64s()?)),
            flag => Err(format!("an option flag {flag}")),
        }
    }

    fn clash(&mut self) -> Result<Clash, String> {
        let (a, b) = (self.key()?, self.key()?);
        let kind = kind_of(self.u8()?)?;
        let [depth, distance, x, y, z] = self.f64s()?;
        let closest = self.option()?.map(|c| [Point::new(c[0], c[1], c[2]), Point::new(c[3], c[4], c[5])]);
        let overlap = self.option()?.map(Aabb::from_array);
        let (a_box, b_box) = (Aabb::from_array(self.f64s()?), Aabb::from_array(self.f64s()?));
        Ok(Clash { a, b, kind, depth, distance, point: Point::new(x, y, z), closest, overlap, a_box, b_box })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::clash::group::GroupBy;
    use crate::clash::test::TestKind;

    fn sample() -> ClashStore {
        let mut s = ClashStore::default();
        let test = ClashTest {
            a: vec!["all".parse().unwrap()],
            kind: TestKind::Clearance,
            distance: 5.0,
            ..Default::default()
        };
        s.tests.insert("t".into(), SavedTest { test: test.clone(), group: GroupBy::None });
        let mut hard = Clash::hard_at(1, 2, Point::new(1.0, 2.0, 3.0));
        hard.b = Key::bytes(*b"2O2Fr$t4X7Zf8NOew3FLOH").unwrap();
        hard.overlap = Some(Aabb::from_array([0.5, 1.5, 2.5, 1.5, 2.5, 3.5]));
        let mut near = Clash::hard_at(3, 4, Point::new(0.5, 0.0, -1.0));
        near.kind = ClashKind::Clearance;
        near.overlap = None;
        near.closest = Some([Point::new(0.0, 0.0, 0.0), Point::new(1.0, 0.0, 0.0)]);
        let tracked = vec![
            Tracked { clash: hard, status: Status::Approved, first_txn: 3, last_txn: 9 },
            Tracked { clash: near, status: Status::Resolved, first_txn: 4, last_txn: 4 },
        ];
        let objects = vec![
            Fingerprint { key: Key::Int(1), id: 0, aabb: [0.0, 0.0, 0.0, 1.0, 1.0, 1.0] },
            Fingerprint { key: Key::bytes(Vec::new()).unwrap(), id: 5, aabb: [0.0; 6] },
            Fingerprint { key: Key::bytes(*b"a").unwrap(), id: 7, aabb: [-1.0, 0.0, 0.0, 1.0, 2.0, 3.0] },
        ];
        s.runs.insert("t".into(), RecordedRun { txn: 9, test, tracked, object_ids: 8, build: 42, objects });
        s
    }

    #[test]
    fn a_body_decodes_to_the_store_it_encodes() {
        let s = sample();
        assert_eq!(decode(&encode(&s).unwrap()).unwrap(), s);
        let empty = ClashStore::default();
        assert_eq!(decode(&encode(&empty).unwrap()).unwrap(), empty);
    }

    #[test]
    fn every_cut_and_a_forged_count_are_refused() {
        let body = encode(&sample()).unwrap();
        for end in 0..body.len() {
            assert!(decode(&body[..end]).is_err(), "cut at {end}");
        }
        let mut long = body.clone();
        long.push(0);
        assert!(decode(&long).is_err(), "a byte past the last run");
        // The runs' count, just after the tests' JSON: a count past what the
        // bytes can hold is refused before anything is allocated.
        let at = 4 + u32::from_le_bytes(body[..4].try_into().unwrap()) as usize;
        let mut forged = body.clone();
        forged[at..at + 4].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(decode(&forged).unwrap_err().contains("entries"));
    }

    #[test]
    fn a_number_that_is_not_finite_is_refused() {
        let body = encode(&sample()).unwrap();
        // Every 3.0 in the body is a number a reader checks (a box's or a point's).
        let three = 3.0f64.to_le_bytes();
        let at = body.windows(8).rposition(|w| w == three).unwrap();
        let mut bad = body.clone();
        bad[at..at + 8].copy_from_slice(&f64::NAN.to_le_bytes());
        assert!(decode(&bad).unwrap_err().contains("not finite"));
    }
}
