//! The API-sequence target: the input is a sequence of operations on one
//! file on a device that can crash (`CrashDevice`): bulk loads of small
//! scenes and inserts, updates and removals by key (now and then ending in
//! `optimize`), each committed, aborted
//! or dropped, compactions, readers begun, held and dropped,
//! reopens that arm a crash at the N-th write or sync, and crashes whose
//! unsynced writes are dropped, kept, torn or mixed. A model says which
//! objects are committed, by key. Every answer must be the model's: a held
//! reader's its snapshot's, the file's its committed objects', and after a crash
//! during a commit either the old scene's or the new one's, never a mix
//! (tests/crash_consistency.rs); `check` must pass after every reopen.

use std::collections::BTreeMap;
use std::sync::Arc;

use crate::edit::Choices;
use mktree::bulk::{BuildParams, LeafRule, Method};
use mktree::db::{CreateOptions, Database, ReadTransaction, check};
use mktree::geom::{Aabb, Point};
use mktree::lod::LodParams;
use mktree::query::{QueryOptions, Region, brute_force_region, query_region};
use mktree::scene::{Key, KeyError, Mesh, Object, Scene};
use mktree::store::BlockDevice;
use mktree::store::device::{CrashDevice, CrashImage, MemDevice};

/// The committed objects by key (empty: no tree).
type Committed = Arc<BTreeMap<Key, Object>>;

/// What a file answers: (key and name of every object, each probe's keys at
/// M), all sorted by key; `None` without a tree.
type Answers = Option<(Vec<(Key, String)>, Vec<Vec<Key>>)>;

/// The probes: everything, and two corners of the space scenes are made in.
fn probes() -> [Aabb; 3] {
    [
        Aabb::from_array([-1e4, -1e4, -1e4, 1e4, 1e4, 1e4]),
        Aabb::from_array([0.0, 0.0, 0.0, 150.0, 150.0, 150.0]),
        Aabb::from_array([180.0, 100.0, 60.0, 420.0, 400.0, 300.0]),
    ]
}

fn expected(model: &Committed) -> Answers {
    if model.is_empty() {
        return None;
    }
    let keys: Vec<&Key> = model.keys().collect();
    let scene = Scene::new(model.values().cloned().collect());
    let named = model.iter().map(|(k, o)| (k.clone(), o.name.clone())).collect();
    let hits = probes()
        .iter()
        .map(|p| {
            let mut hit: Vec<Key> = brute_force_region(&scene, &Region::Box(*p))
                .iter()
                .map(|id| keys[id.index()].clone())
                .collect();
            hit.sort();
            hit
        })
        .collect();
    Some((named, hits))
}

/// The answers of `r`, or the error that stopped them.
fn answers(r: &ReadTransaction) -> Result<Answers, String> {
    if r.info().is_none() {
        return Ok(None);
    }
    let names = r.names().map_err(|e| e.to_string())?;
    let mut hits = Vec::new();
    let mut named = Vec::new();
    for (i, p) in probes().into_iter().enumerate() {
        let a =
            query_region(r, &Region::Box(p), &QueryOptions::default(), None).map_err(|e| e.to_string())?;
        if i == 0 {
            // The first probe holds every object: their keys and names.
            for (id, key) in a.objects.iter().zip(&a.keys) {
                let name = names.get(id.index()).ok_or_else(|| format!("object {id} has no name"))?;
                named.push((key.clone(), name.clone()));
            }
            named.sort();
        }
        let mut keys = a.keys;
        keys.sort();
        hits.push(keys);
    }
    Ok(Some((named, hits)))
}

/// A point of the coarse grid scenes are made on (ties and touches are common).
fn point(c: &mut Choices) -> [f64; 3] {
    [0, 1, 2].map(|_| f64::from(c.u8() % 20) * 25.0)
}

/// A small object the input describes: a box, a triangle (maybe
/// degenerate) or a strip, some larger than a block (stored as parts).
fn object(c: &mut Choices, i: usize) -> Option<Object> {
    let lo = point(c);
    let mesh = match c.u8() % 4 {
        0 => {
            let size = [0, 1, 2].map(|_| f64::from(c.u8() % 8) * 10.0);
            let hi = [lo[0] + size[0], lo[1] + size[1], lo[2] + size[2]];
            Mesh::of_box(&Aabb::new(lo.into(), hi.into()))?
        }
        1 | 2 => {
            let (b, d) = (point(c), point(c));
            Mesh::from_world(&[lo.into(), b.into(), d.into()], vec![[0, 1, 2]]).ok()?
        }
        _ => {
            let k = 1 + c.below(150) as u32;
            let v: Vec<Point> = (0..k + 2)
                .map(|j| Point::new(lo[0] + f64::from(j) * 3.0, lo[1] + f64::from(j % 2) * 20.0, lo[2]))
                .collect();
            Mesh::from_world(&v, (0..k).map(|j| [j, j + 1, j + 2]).collect()).ok()?
        }
    };
    let name = if c.u8() & 3 == 0 {
        let n = c.below(40);
        String::from_utf8_lossy(&c.bytes(n)).into_owned()
    } else {
        format!("o{i}")
    };
    Some(Object::new(name, mesh))
}

/// A key the input chooses among a few, so that inserts collide with
/// objects already there: a small integer, or a few bytes.
fn key(c: &mut Choices) -> Option<Key> {
    match c.u8() % 4 {
        0 => None,
        1 => {
            let n = 1 + c.below(3);
            Some(Key::Bytes(c.bytes(n).into()))
        }
        _ => Some(Key::Int(c.below(12) as u64)),
    }
}

/// A small scene the input describes, keyed by id or by the input's keys.
fn scene(c: &mut Choices) -> Scene {
    let n = 1 + c.below(6);
    let keyed = c.u8() & 1 == 1;
    let objects = (0..n)
        .filter_map(|i| {
            let o = object(c, i)?;
            Some(if keyed { o.with_key(Key::Int(100 + c.below(8) as u64)) } else { o })
        })
        .collect();
    Scene::new(objects)
}

/// One life of the file: a device (armed to crash at an event, or not), the
/// database on it, and the readers held with the scene each must see.
struct Life {
    dev: Arc<CrashDevice>,
    db: Database,
    readers: Vec<(ReadTransaction, Committed)>,
}

/// How a write transaction ended.
enum Outcome {
    Committed(Committed),
    /// Aborted, dropped, or refused before its commit.
    Unchanged,
    /// The device crashed: inside `commit` (either state may be durable) or before it.
    Crashed {
        during_commit: Option<Committed>,
    },
}

/// One change by key, with what the model expects of it.
enum Change {
    Insert(Object),
    Remove(Key),
    Update(Object),
}

/// The objects a bulk load of `scene` commits, by key.
fn loaded(scene: &Scene) -> Committed {
    let keyed = scene
        .objects()
        .iter()
        .enumerate()
        .map(|(i, o)| (o.key.clone().unwrap_or(Key::Int(i as u64)), o.clone()));
    Arc::new(keyed.collect())
}

impl Life {
    /// Opens `image` on a device crashing at event `crash_at`. A file a crash
    /// left must open: the commit protocol never leaves it unreadable.
    fn open(image: Vec<u8>, crash_at: u64) -> Life {
        let dev = Arc::new(CrashDevice::new(image, crash_at));
        let db = Database::open_on(dev.clone() as Arc<dyn BlockDevice>)
            .unwrap_or_else(|e| panic!("a file the API and crashes left does not open: {e}"));
        Life { dev, db, readers: Vec::new() }
    }

    /// A write transaction the input chooses on top of `model`: a bulk load,
    /// changes by key, or a compaction.
    fn write(&mut self, c: &mut Choices, model: &Committed) -> Outcome {
        match c.u8() % 4 {
            0 | 1 => self.bulk_load(c),
            2 => self.change(c, model),
            _ => self.compact(model),
        }
    }

    fn bulk_load(&mut self, c: &mut Choices) -> Outcome {
        let s = scene(c);
        let params = BuildParams {
            method: Method::ALL[c.below(Method::ALL.len())],
            leaf: LeafRule::Objects(1 + c.below(4) as u32),
            ..BuildParams::paper()
        };
        let lods = self.lods(c);
        let finish = c.u8() % 4;
        let mut in_commit = false;
        let result = (|| -> Result<bool, mktree::Error> {
            let mut w = self.db.begin_write()?;
            w.set_lod_params(lods);
            w.bulk_load(&s, &params, &|_| {})?;
            finish_write(w, finish, &mut in_commit)
        })();
        match result {
            Ok(true) => Outcome::Committed(loaded(&s)),
            _ if self.dev.crashed() => Outcome::Crashed { during_commit: in_commit.then(|| loaded(&s)) },
            Ok(false) => Outcome::Unchanged,
            Err(e) if in_commit => panic!("a commit failed with no crash: {e}"),
            // A scene the builder refuses (a leaf too large for a block, say).
            Err(_) => Outcome::Unchanged,
        }
    }

    /// Inserts, removals and updates by key in one transaction; a refused
    /// change (a key taken, a key missing) is a typed error that leaves the
    /// transaction as it was.
    fn change(&mut self, c: &mut Choices, model: &Committed) -> Outcome {
        let changes: Vec<Change> = (0..1 + c.below(5))
            .filter_map(|i| match c.u8() % 3 {
                0 => {
                    let o = object(c, 50 + i)?;
                    Some(Change::Insert(match key(c) {
                        Some(k) => o.with_key(k),
                        None => o,
                    }))
                }
                1 => Some(Change::Remove(key(c).unwrap_or(Key::Int(0)))),
                _ => Some(Change::Update(object(c, 80 + i)?.with_key(key(c).unwrap_or(Key::Int(1))))),
            })
            .collect();
        let lods = self.lods(c);
        let finish = c.u8() % 4;
        // Now and then the changes end with `optimize`: the same objects, laid out anew.
        let optimize = c.u8().is_multiple_of(8);
        let mut next = (**model).clone();
        let mut in_commit = false;
        let result = (|| -> Result<bool, mktree::Error> {
            let mut w = self.db.begin_write()?;
            w.set_lod_params(lods);
            for change in changes {
                match change {
                    Change::Insert(o) => match w.insert(o.clone()) {
                        Ok(k) => {
                            assert!(o.key.as_ref().is_none_or(|want| *want == k), "insert gave key {k}");
                            assert!(next.insert(k.clone(), o).is_none(), "insert took key {k} twice");
                        }
                        Err(mktree::Error::Key(KeyError::Exists { key })) => {
                            assert!(next.contains_key(&key), "insert refused key {key}, which is free")
                        }
                        Err(e) => return Err(e),
                    },
                    Change::Remove(k) => {
                        let gone = w.remove(&k)?;
                        assert_eq!(gone.is_some(), next.remove(&k).is_some(), "remove of key {k}");
                    }
                    Change::Update(o) => {
                        let k = o.key.clone().unwrap_or(Key::Int(1));
                        match w.update(o.clone()) {
                            Ok(_) => assert!(next.insert(k.clone(), o).is_some(), "update of absent key {k}"),
                            Err(mktree::Error::Key(KeyError::NotFound { key })) => {
                                assert!(!next.contains_key(&key), "update missed key {key}")
                            }
                            Err(e) => return Err(e),
                        }
                    }
                }
            }
            if optimize {
                w.optimize()?;
            }
            finish_write(w, finish, &mut in_commit)
        })();
        let next = Arc::new(next);
        match result {
            Ok(true) => Outcome::Committed(next),
            _ if self.dev.crashed() => Outcome::Crashed { during_commit: in_commit.then_some(next) },
            Ok(false) => Outcome::Unchanged,
            Err(e) if in_commit && e.to_string().contains("the changed tree") => {
                panic!("a change left a tree that fails validation: {e}")
            }
            // A changed tree the writer refuses (a leaf record too large for
            // a block, say): the committed state must stay.
            Err(_) => {
                self.verify(model);
                Outcome::Unchanged
            }
        }
    }

    /// Compacts: the same objects, in fewer blocks.
    fn compact(&mut self, model: &Committed) -> Outcome {
        match self.db.compact() {
            Ok(_) => Outcome::Committed(model.clone()),
            Err(_) if self.dev.crashed() => Outcome::Crashed { during_commit: Some(model.clone()) },
            Err(e) => panic!("compact failed with no crash: {e}"),
        }
    }

    /// Cheap levels of detail (all stored, or only those that pay).
    fn lods(&self, c: &mut Choices) -> LodParams {
        LodParams { store_all: c.u8() & 1 == 1, ..crate::base::cheap_lods(self.db.lod_levels()) }
    }

    /// Every held reader still answers its snapshot's scene.
    fn check_readers(&self) {
        for (r, scene) in &self.readers {
            let got = answers(r).unwrap_or_else(|e| panic!("a held reader fails: {e}"));
            assert_eq!(got, expected(scene), "a held reader's snapshot changed");
        }
    }

    /// The file answers `model`'s scene, and `check` passes.
    fn verify(&self, model: &Committed) {
        let r = self.db.begin_read().unwrap_or_else(|e| panic!("begin_read: {e}"));
        let got = answers(&r).unwrap_or_else(|e| panic!("the committed tree fails: {e}"));
        assert_eq!(got, expected(model), "the file does not answer its committed scene");
        drop(r);
        let report = check(&self.db).unwrap_or_else(|e| panic!("check fails: {e}"));
        assert!(report.ok(), "check: {:?}", report.faults);
    }
}

/// Commits (`finish` 0 or 1), aborts (2) or drops (3) `w`; true when committed.
fn finish_write(
    w: mktree::db::WriteTransaction<'_>,
    finish: u8,
    in_commit: &mut bool,
) -> Result<bool, mktree::Error> {
    match finish {
        0 | 1 => {
            *in_commit = true;
            w.commit()?;
            Ok(true)
        }
        2 => w.abort().map(|_| false).map_err(Into::into),
        _ => {
            drop(w);
            Ok(false)
        }
    }
}

/// The crash point a reopen arms: none, or an early write or sync.
fn crash_point(c: &mut Choices) -> u64 {
    if c.u8() & 1 == 0 { u64::MAX } else { c.below(200) as u64 }
}

fn image_mode(c: &mut Choices) -> CrashImage {
    match c.u8() % 4 {
        0 => CrashImage::DropAll,
        1 => CrashImage::KeepAll,
        2 => CrashImage::TearLast,
        _ => CrashImage::Mask(c.u64()),
    }
}

/// Runs the sequence the input describes against the model.
pub fn api_sequence(data: &[u8]) {
    let mut c = Choices::new(data);
    let options = CreateOptions { block_size: [1024, 4096][c.below(2)], lod_levels: 1 + c.below(4) as u8 };
    let fresh = Arc::new(MemDevice::new());
    Database::create_on(fresh.clone() as Arc<dyn BlockDevice>, options)
        .unwrap_or_else(|e| panic!("create: {e}"));
    let mut life = Life::open(fresh.to_bytes(), crash_point(&mut c));
    let mut model = Committed::default();
    while !c.is_empty() {
        let crashed_during = match c.u8() % 8 {
            0..=2 => match life.write(&mut c, &model) {
                Outcome::Committed(s) => {
                    model = s;
                    None
                }
                Outcome::Unchanged => None,
                Outcome::Crashed { during_commit } => Some(during_commit),
            },
            3 => {
                if let Ok(r) = life.db.begin_read() {
                    life.readers.push((r, model.clone()));
                }
                None
            }
            4 => {
                let n = life.readers.len();
                if n > 0 {
                    life.readers.remove(c.below(n));
                }
                None
            }
            5 => {
                life.check_readers();
                None
            }
            6 => {
                // A clean close and reopen, arming the next crash.
                let image = life.dev.image(CrashImage::KeepAll);
                drop(life);
                life = Life::open(image, crash_point(&mut c));
                life.verify(&model);
                None
            }
            _ => {
                life.verify(&model);
                None
            }
        };
        if let Some(new) = crashed_during {
            let image = life.dev.image(image_mode(&mut c));
            drop(life);
            life = Life::open(image, crash_point(&mut c));
            if let Some(new) = new {
                // A crash inside a commit: either side of it, never a mix.
                let r = life.db.begin_read().unwrap_or_else(|e| panic!("begin_read after a crash: {e}"));
                let got = answers(&r).unwrap_or_else(|e| panic!("the tree after a crash fails: {e}"));
                if got == expected(&new) {
                    model = new;
                } else {
                    assert_eq!(got, expected(&model), "a crash during a commit left neither side of it");
                }
            }
            life.verify(&model);
        }
    }
    if !life.dev.crashed() {
        life.check_readers();
        life.verify(&model);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fresh file of `m` levels, opened on a device that never crashes.
    fn fresh(m: u8) -> Life {
        let dev = Arc::new(MemDevice::new());
        Database::create_on(
            dev.clone() as Arc<dyn BlockDevice>,
            CreateOptions { block_size: 1024, lod_levels: m },
        )
        .expect("create");
        Life::open(dev.to_bytes(), u64::MAX)
    }

    #[test]
    fn a_write_commits_a_scene_at_every_number_of_levels() {
        for m in 1..=4 {
            let mut life = fresh(m);
            // A bulk load of two boxes keyed by id; MOA; leaves of one object; no stored bounds; commit.
            let choices = [0, 1, 0, 0, 1, 1, 1, 2, 2, 2, 1, 0, 4, 4, 4, 0, 2, 2, 2, 1, 0, 0, 0, 0];
            match life.write(&mut Choices::new(&choices), &Committed::default()) {
                Outcome::Committed(s) => life.verify(&s),
                _ => panic!("M = {m}: the write did not commit"),
            }
        }
    }

    #[test]
    fn a_crash_inside_a_commit_reopens_at_one_side_of_it() {
        // Crash at each early event of a commit: each reopens at no tree or the new one.
        let mut sides = [0; 2];
        for crash_at in 0..40 {
            let dev = Arc::new(MemDevice::new());
            Database::create_on(
                dev.clone() as Arc<dyn BlockDevice>,
                CreateOptions { block_size: 1024, lod_levels: 2 },
            )
            .expect("create");
            let mut life = Life::open(dev.to_bytes(), crash_at);
            let choices = [0, 1, 0, 0, 1, 1, 1, 2, 2, 2, 1, 0, 4, 4, 4, 0, 2, 2, 2, 1, 0, 0, 0, 0];
            let during = match life.write(&mut Choices::new(&choices), &Committed::default()) {
                Outcome::Crashed { during_commit } => during_commit,
                _ => continue,
            };
            let after = Life::open(life.dev.image(CrashImage::TearLast), u64::MAX);
            let got = answers(&after.db.begin_read().expect("reads")).expect("answers");
            let side = usize::from(during.as_ref().is_some_and(|n| got == expected(n)));
            assert!(side == 1 || got == expected(&Committed::default()), "crash at {crash_at}: neither side");
            sides[side] += 1;
            after.verify(&if side == 1 { during.unwrap_or_default() } else { Committed::default() });
        }
        assert!(sides[0] > 0 && sides[1] > 0, "both sides occur: {sides:?}");
    }

    #[test]
    fn random_sequences_of_loads_changes_and_compactions_keep_the_model() {
        // Inputs from a fixed xorshift stream: loads, changes by key,
        // compactions, readers and crashes mixed as the fuzzer would.
        let mut x = 0x9e37_79b9_7f4a_7c15u64;
        for _ in 0..60 {
            let data: Vec<u8> = (0..400)
                .map(|_| {
                    x ^= x << 13;
                    x ^= x >> 7;
                    x ^= x << 17;
                    x as u8
                })
                .collect();
            api_sequence(&data);
        }
    }
}
