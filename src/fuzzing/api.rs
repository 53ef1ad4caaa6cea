//! The API-sequence target: the input is a sequence of operations on one
//! file on a device that can crash (`CrashDevice`): writes of small scenes
//! that commit, abort or are dropped, readers begun, held and dropped,
//! reopens that arm a crash at the N-th write or sync, and crashes whose
//! unsynced writes are dropped, kept, torn or mixed. A model says which
//! scene is committed. Every answer must be the model's: a held reader's
//! its snapshot's, the file's its committed scene's, and after a crash
//! during a commit either the old scene's or the new one's, never a mix
//! (tests/crash_consistency.rs); `check` must pass after every reopen.

use std::sync::Arc;

use super::edit::Choices;
use crate::build::{BuildParams, LeafRule, Method};
use crate::db::{CreateOptions, Database, ReadTransaction, check};
use crate::geom::{Aabb, Point};
use crate::lod::LodParams;
use crate::query::{QueryOptions, Region, brute_force_region, query_region};
use crate::scene::{Mesh, Object, ObjectId, Scene};
use crate::store::BlockDevice;
use crate::store::device::{CrashDevice, CrashImage, MemDevice};

/// The committed scene (`None`: no tree yet).
type Committed = Option<Arc<Scene>>;

/// What a file answers: (objects, names, each probe's objects at M).
type Answers = Option<(u32, Vec<String>, Vec<Vec<ObjectId>>)>;

/// The probes: everything, and two corners of the space scenes are made in.
fn probes() -> [Aabb; 3] {
    [
        Aabb::from_array([-1e4, -1e4, -1e4, 1e4, 1e4, 1e4]),
        Aabb::from_array([0.0, 0.0, 0.0, 150.0, 150.0, 150.0]),
        Aabb::from_array([180.0, 100.0, 60.0, 420.0, 400.0, 300.0]),
    ]
}

fn expected(scene: &Committed) -> Answers {
    let s = scene.as_ref()?;
    let names = s.objects().iter().map(|o| o.name.clone()).collect();
    let hits = probes().iter().map(|p| brute_force_region(s, &Region::Box(*p))).collect();
    Some((s.len() as u32, names, hits))
}

/// The answers of `r`, or the error that stopped them.
fn answers(r: &ReadTransaction) -> Result<Answers, String> {
    let Some(info) = r.info() else { return Ok(None) };
    let names = r.names().map_err(|e| e.to_string())?;
    let mut hits = Vec::new();
    for p in probes() {
        let a =
            query_region(r, &Region::Box(p), &QueryOptions::default(), None).map_err(|e| e.to_string())?;
        hits.push(a.objects);
    }
    Ok(Some((info.objects, names, hits)))
}

/// A point of the coarse grid scenes are made on (ties and touches are common).
fn point(c: &mut Choices) -> [f64; 3] {
    [0, 1, 2].map(|_| f64::from(c.u8() % 20) * 25.0)
}

/// A small scene the input describes: boxes, triangles (some degenerate)
/// and strips, some larger than a block (stored as parts).
fn scene(c: &mut Choices) -> Scene {
    let n = 1 + c.below(6);
    let objects = (0..n)
        .filter_map(|i| {
            let lo = point(c);
            let mesh = match c.u8() % 4 {
                0 => {
                    let size = [0, 1, 2].map(|_| f64::from(c.u8() % 8) * 10.0);
                    let hi = [lo[0] + size[0], lo[1] + size[1], lo[2] + size[2]];
                    Mesh::of_box(&Aabb::new(lo.into(), hi.into()))
                }
                1 | 2 => {
                    let (b, d) = (point(c), point(c));
                    Mesh::from_world(&[lo.into(), b.into(), d.into()], vec![[0, 1, 2]]).ok()
                }
                _ => {
                    let k = 1 + c.below(150) as u32;
                    let v: Vec<Point> = (0..k + 2)
                        .map(|j| {
                            Point::new(lo[0] + f64::from(j) * 3.0, lo[1] + f64::from(j % 2) * 20.0, lo[2])
                        })
                        .collect();
                    Mesh::from_world(&v, (0..k).map(|j| [j, j + 1, j + 2]).collect()).ok()
                }
            };
            let name = if c.u8() & 3 == 0 {
                let n = c.below(40);
                String::from_utf8_lossy(&c.bytes(n)).into_owned()
            } else {
                format!("o{i}")
            };
            mesh.map(|m| Object::new(name, m))
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
    Committed(Arc<Scene>),
    /// Aborted, dropped, or refused before its commit.
    Unchanged,
    /// The device crashed: inside `commit` (either scene may be durable) or before it.
    Crashed {
        during_commit: Option<Arc<Scene>>,
    },
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

    fn write(&mut self, c: &mut Choices) -> Outcome {
        let s = Arc::new(scene(c));
        let params = BuildParams {
            method: Method::ALL[c.below(Method::ALL.len())],
            leaf: LeafRule::Objects(1 + c.below(4) as u32),
            ..BuildParams::default()
        };
        let lods =
            LodParams { store_all: c.u8() & 1 == 1, ..super::structure::cheap_lods(self.db.lod_levels()) };
        let finish = c.u8() % 4;
        let mut in_commit = false;
        let result = (|| -> Result<bool, crate::Error> {
            let mut w = self.db.begin_write()?;
            w.set_lod_params(lods);
            w.bulk_load(&s, &params, &|_| {})?;
            match finish {
                0 | 1 => {
                    in_commit = true;
                    w.commit()?;
                    Ok(true)
                }
                2 => w.abort().map(|_| false).map_err(Into::into),
                _ => {
                    drop(w);
                    Ok(false)
                }
            }
        })();
        match result {
            Ok(true) => Outcome::Committed(s),
            _ if self.dev.crashed() => Outcome::Crashed { during_commit: in_commit.then_some(s) },
            Ok(false) => Outcome::Unchanged,
            Err(e) if in_commit => panic!("a commit failed with no crash: {e}"),
            // A scene the builder refuses (a leaf too large for a block, say).
            Err(_) => Outcome::Unchanged,
        }
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
    let mut model: Committed = None;
    while !c.is_empty() {
        let crashed_during = match c.u8() % 8 {
            0..=2 => match life.write(&mut c) {
                Outcome::Committed(s) => {
                    model = Some(s);
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
                let now = Some(new);
                if got == expected(&now) {
                    model = now;
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
            // Two boxes; MOA; leaves of one object; no stored bounds; commit.
            let choices = [1, 0, 1, 1, 1, 2, 2, 2, 1, 0, 4, 4, 4, 0, 2, 2, 2, 1, 0, 0, 0, 0];
            match life.write(&mut Choices::new(&choices)) {
                Outcome::Committed(s) => life.verify(&Some(s)),
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
            let choices = [1, 0, 1, 1, 1, 2, 2, 2, 1, 0, 4, 4, 4, 0, 2, 2, 2, 1, 0, 0, 0, 0];
            let during = match life.write(&mut Choices::new(&choices)) {
                Outcome::Crashed { during_commit } => during_commit,
                _ => continue,
            };
            let after = Life::open(life.dev.image(CrashImage::TearLast), u64::MAX);
            let got = answers(&after.db.begin_read().expect("reads")).expect("answers");
            let new = during.map(Some);
            let side = usize::from(new.as_ref().is_some_and(|n| got == expected(n)));
            assert!(side == 1 || got == expected(&None), "crash at {crash_at}: neither side");
            sides[side] += 1;
            after.verify(&if side == 1 { new.unwrap_or_default() } else { None });
        }
        assert!(sides[0] > 0 && sides[1] > 0, "both sides occur: {sides:?}");
    }
}
