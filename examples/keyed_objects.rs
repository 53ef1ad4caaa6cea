//! An application's objects under its own keys, kept in an mktree file
//! across transactions: bulk load, insert, move, delete; a box query that
//! stops early, the nearest objects, a ray, and a query shape the
//! application defines (a capsule around a pipe run). Then the same file is
//! opened read-only by a second process, as a viewer would.
//!
//! ```sh
//! cargo run --example keyed_objects            # writes keyed_objects.mkt in a temporary directory
//! cargo run --example keyed_objects -- --read FILE.mkt
//! ```

use std::error::Error;
use std::path::{Path, PathBuf};
use std::process::Command;

use mktree::bulk::BuildParams;
use mktree::db::{CreateOptions, Database, ReadTransaction, check};
use mktree::geom::{Aabb, Point, Ray, Vector};
use mktree::lod::Voxels;
use mktree::query::{QueryOptions, Region, Selection};
use mktree::scene::{Key, Mesh, Object, Scene};
use parry3d_f64::math::Isometry;
use parry3d_f64::shape::{Capsule, Triangle};

type Result<T> = std::result::Result<T, Box<dyn Error>>;

/// A box of `size` mm at `at`, keyed by the application's row id.
fn equipment(row: u64, at: [f64; 3], size: f64) -> Result<Object> {
    let b = Aabb::from_array([at[0], at[1], at[2], at[0] + size, at[1] + size, at[2] + size]);
    let mesh = Mesh::of_box(&b).ok_or("a box of no extent")?;
    Ok(Object::new(format!("equipment {row}"), mesh).with_key(row).with_payload(format!("row {row}")))
}

/// Everything within `radius` of the segment `a`-`b`: the clearance around
/// a planned pipe run. The traversal asks three things of it.
struct PipeRun {
    capsule: Capsule,
    bounds: Aabb,
}

impl PipeRun {
    fn new(a: Point, b: Point, radius: f64) -> PipeRun {
        let lo = a.coords.inf(&b.coords).add_scalar(-radius);
        let hi = a.coords.sup(&b.coords).add_scalar(radius);
        PipeRun { capsule: Capsule::new(a, b, radius), bounds: Aabb::new(lo.into(), hi.into()) }
    }
}

impl Selection for PipeRun {
    /// May say yes wrongly, never no wrongly: the capsule's box meets `b`.
    fn may_meet_box(&self, b: &Aabb) -> bool {
        self.bounds.intersects(b)
    }
    /// The capsule is convex: it holds the box when it holds its corners.
    fn holds_box(&self, b: &Aabb) -> bool {
        let seg = self.capsule.segment;
        b.corners().iter().all(|c| {
            let (pa, ab) = (c - seg.a, seg.b - seg.a);
            let t = (pa.dot(&ab) / ab.norm_squared().max(f64::MIN_POSITIVE)).clamp(0.0, 1.0);
            (pa - ab * t).norm() <= self.capsule.radius
        })
    }
    fn may_meet_voxels(&self, v: &Voxels) -> bool {
        v.cell_boxes().any(|c| self.may_meet_box(&c))
    }
    /// Exact at level M: some triangle comes within the radius.
    fn meets_mesh(&self, mesh: &Mesh, tested: &mut u64) -> bool {
        let id = Isometry::identity();
        mesh.triangle_points().any(|[a, b, c]| {
            *tested += 1;
            let t = Triangle::new(a, b, c);
            parry3d_f64::query::distance(&id, &self.capsule, &id, &t).is_ok_and(|d| d <= 0.0)
        })
    }
}

fn write(path: &Path) -> Result<()> {
    let (db, created) = Database::open_or_create(path, CreateOptions::default())?;
    assert!(created, "{} exists", path.display());

    // Load: a 10 x 10 grid of equipment, keyed by row ids 1000..1100.
    let grid = (0..100u64)
        .map(|i| equipment(1000 + i, [(i % 10) as f64 * 500.0, (i / 10) as f64 * 500.0, 0.0], 300.0));
    let scene = Scene::new(grid.collect::<Result<_>>()?);
    let mut w = db.begin_write()?;
    w.bulk_load(&scene, &BuildParams::default(), &|_| {})?;
    w.commit()?;

    // A design revision: one pump added, one moved, one removed, in one commit.
    let mut w = db.begin_write()?;
    w.insert(equipment(2000, [2350.0, 2350.0, 0.0], 100.0)?)?;
    w.update(equipment(1005, [2600.0, 2600.0, 800.0], 300.0)?)?;
    let gone = w.remove(&Key::Int(1099))?.ok_or("row 1099 was loaded")?;
    println!("removed {}", gone.name);
    // A key already taken is a typed error, and the transaction goes on.
    assert!(w.insert(equipment(1000, [0.0; 3], 10.0)?).is_err());
    w.commit()?;

    let report = check(&db)?;
    assert!(report.ok(), "{:?}", report.faults);
    let r = db.begin_read()?;
    let info = r.info().ok_or("the file holds a tree")?;
    println!("{} objects in {} blocks ({} free)", info.objects, info.file_blocks, info.free_blocks);
    assert_eq!(info.objects, 100);
    assert!(r.get(&Key::Int(1099))?.is_none());
    let moved = r.get(&Key::Int(1005))?.ok_or("row 1005 is there")?;
    assert_eq!(moved.aabb.min.z, 800.0);
    assert_eq!(moved.payload, b"row 1005");
    query(&r)?;
    Ok(())
}

fn query(r: &ReadTransaction) -> Result<()> {
    // The first three objects in a box, then stop: only the blocks read so far are read.
    let region = Region::Box(Aabb::from_array([0.0, 0.0, 0.0, 3000.0, 3000.0, 1500.0]));
    let mut hits = r.select(&region, &QueryOptions::default(), None)?;
    let first: Vec<_> = hits.by_ref().take(3).collect::<std::result::Result<_, _>>()?;
    println!("first {} hits for {} block reads", first.len(), hits.stats().reads.total());
    assert_eq!(first.len(), 3);

    // The three nearest to a point, by exact distance, and the first hit along a ray.
    let near: Vec<_> =
        r.nearest(Point::new(2400.0, 2400.0, 150.0), None)?.take(3).collect::<std::result::Result<_, _>>()?;
    println!("nearest: {:?}", near.iter().map(|n| (&n.key, n.distance)).collect::<Vec<_>>());
    assert_eq!(near[0].key, Key::Int(2000));
    let ray = Ray::new(Point::new(-100.0, 150.0, 150.0), Vector::new(1.0, 0.0, 0.0), None)?;
    let hit = r.first_hit(&ray, None)?.ok_or("the ray meets row 1000")?;
    println!("ray: key {} at t = {} mm", hit.key, hit.t);
    assert_eq!((hit.key, hit.t), (Key::Int(1000), 100.0));

    // The application's own shape, through the same traversal.
    let pipe = PipeRun::new(Point::new(-200.0, 700.0, 150.0), Point::new(5000.0, 700.0, 150.0), 100.0);
    let mut keys = Vec::new();
    for hit in r.select(&pipe, &QueryOptions::default(), None)? {
        keys.push(hit?.key);
    }
    keys.sort();
    println!("the pipe run passes within 100 mm of {} objects", keys.len());
    assert_eq!(keys, (1010..1020).map(Key::Int).collect::<Vec<_>>());
    Ok(())
}

/// The second process: opens the file read-only, as a viewer would.
fn read(path: &Path) -> Result<()> {
    let db = Database::open_read_only(path)?;
    assert!(db.begin_write().is_err(), "a read-only open cannot write");
    query(&db.begin_read()?)
}

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().collect();
    if let [_, flag, file] = &args[..]
        && flag == "--read"
    {
        return read(Path::new(file));
    }
    let dir = tempfile::tempdir()?;
    let path: PathBuf = dir.path().join("keyed_objects.mkt");
    write(&path)?;
    let status = Command::new(std::env::current_exe()?).arg("--read").arg(&path).status()?;
    if !status.success() {
        return Err(format!("the reading process failed: {status}").into());
    }
    println!("a second process read the same answers");
    Ok(())
}
