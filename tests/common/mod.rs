//! Helpers shared by the integration tests: small random scenes and an
//! in-memory database built from them.
#![allow(dead_code)]

pub mod crash;
pub mod forge;
#[cfg(feature = "object-store")]
pub mod remote;
#[cfg(feature = "object-store")]
pub mod servers;

use std::sync::Arc;

use mktree::bulk::BuildParams;
use mktree::db::{CreateOptions, Database};
use mktree::geom::Aabb;
use mktree::scene::{Mesh, Object, Scene};
use mktree::store::BlockDevice;
use mktree::store::device::MemDevice;
use proptest::prelude::*;

/// A closed box mesh (12 triangles) from `lo` to `hi`.
pub fn box_mesh(lo: [f64; 3], hi: [f64; 3]) -> Mesh {
    Mesh::of_box(&Aabb::new(lo.into(), hi.into())).expect("a box is a valid mesh")
}

/// A single triangle (an open, thin object).
pub fn triangle(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> Mesh {
    Mesh::from_world(&[a.into(), b.into(), c.into()], vec![[0, 1, 2]]).expect("valid")
}

/// Random scenes of boxes and triangles in a 1000 mm cube.
pub fn arb_scene(max_objects: usize) -> impl Strategy<Value = Scene> {
    let obj = (prop::array::uniform3(0.0f64..1000.0), prop::array::uniform3(0.0f64..150.0), any::<bool>());
    prop::collection::vec(obj, 1..max_objects).prop_map(|v| {
        Scene::new(
            v.into_iter()
                .enumerate()
                .map(|(i, (lo, size, is_box))| {
                    let hi = [lo[0] + size[0], lo[1] + size[1], lo[2] + size[2]];
                    let mesh = if is_box {
                        box_mesh(lo, hi)
                    } else {
                        triangle(lo, [hi[0], lo[1], hi[2]], [lo[0], hi[1], hi[2]])
                    };
                    Object::new(format!("o{i}"), mesh)
                })
                .collect(),
        )
    })
}

/// Random object boxes, from 1 to `max` of them: on a coarse integer grid
/// (many ties, shared faces, identical boxes) or with continuous coordinates.
pub fn arb_boxes(min: usize, max: usize) -> impl Strategy<Value = Vec<Aabb>> {
    let grid = (prop::array::uniform3(0u8..12), prop::array::uniform3(0u8..4)).prop_map(|(lo, ext)| {
        let lo = lo.map(f64::from);
        let ext = ext.map(f64::from);
        Aabb::from_array([lo[0], lo[1], lo[2], lo[0] + ext[0], lo[1] + ext[1], lo[2] + ext[2]])
    });
    let free =
        (prop::array::uniform3(-1e3f64..1e3), prop::array::uniform3(0f64..50.0)).prop_map(|(lo, ext)| {
            Aabb::from_array([lo[0], lo[1], lo[2], lo[0] + ext[0], lo[1] + ext[1], lo[2] + ext[2]])
        });
    prop_oneof![prop::collection::vec(grid, min..max), prop::collection::vec(free, min..max)]
}

/// `n` slanted triangles on a grid, named `t0`, `t1`, ...: their levels of
/// detail below M are worth storing.
pub fn slanted_triangles(n: usize) -> Vec<Object> {
    (0..n)
        .map(|i| {
            let o = [(i % 4) as f64 * 120.0, (i / 4) as f64 * 120.0, (i % 3) as f64 * 40.0];
            let m = triangle(
                o,
                [o[0] + 100.0, o[1] + 10.0, o[2] + 60.0],
                [o[0] + 20.0, o[1] + 90.0, o[2] + 30.0],
            );
            Object::new(format!("t{i}"), m)
        })
        .collect()
}

/// A deterministic scene of `n` boxes on a jittered grid.
pub fn grid_scene(n: usize) -> Scene {
    let side = (n as f64).cbrt().ceil() as usize;
    Scene::new(
        (0..n)
            .map(|i| {
                let (x, y, z) = ((i % side) as f64, ((i / side) % side) as f64, (i / side / side) as f64);
                let j = ((i * 7919) % 13) as f64;
                let lo = [x * 100.0 + j, y * 100.0, z * 100.0 + j / 2.0];
                Object::new(format!("b{i}"), box_mesh(lo, [lo[0] + 60.0 + j, lo[1] + 40.0, lo[2] + 80.0]))
            })
            .collect(),
    )
}

/// A fresh database on `device` with `scene` bulk-loaded by `params` and committed.
pub fn load_on(
    device: Arc<dyn BlockDevice>,
    scene: &Scene,
    params: &BuildParams,
    options: CreateOptions,
) -> Database {
    let db = Database::create_on(device, options).expect("create");
    let mut w = db.begin_write().expect("begin_write");
    w.bulk_load(scene, params, &|_| {}).expect("bulk_load");
    w.commit().expect("commit");
    db
}

/// `scene` bulk-loaded with `params` into a fresh in-memory database.
pub fn mem_db(scene: &Scene, params: &BuildParams, options: CreateOptions) -> (Database, Arc<MemDevice>) {
    let dev = Arc::new(MemDevice::new());
    (load_on(dev.clone(), scene, params, options), dev)
}

/// The bytes of a file holding `scene` bulk-loaded by `params`.
pub fn image(scene: &Scene, params: &BuildParams, options: CreateOptions) -> Vec<u8> {
    let (db, dev) = mem_db(scene, params, options);
    drop(db);
    dev.to_bytes()
}

/// `scene` in a fresh in-memory database with M = `m` levels of detail,
/// MOA leaves of at most `cap` objects, and `lod` as its level parameters.
pub fn lod_db(scene: &Scene, m: u8, block_size: u32, cap: u32, lod: mktree::lod::LodParams) -> Database {
    let db = Database::create_on(Arc::new(MemDevice::new()), CreateOptions { block_size, lod_levels: m })
        .expect("create");
    let mut w = db.begin_write().expect("begin_write");
    w.set_lod_params(lod);
    let params = BuildParams {
        method: mktree::bulk::Method::Moa,
        leaf: mktree::bulk::LeafRule::Objects(cap),
        ..BuildParams::paper()
    };
    w.bulk_load(scene, &params, &|_| {}).expect("bulk_load");
    w.commit().expect("commit");
    db
}

/// Change `i` of a stream over `grid_scene(200)`, one per commit: inserts
/// around one place (their leaves split), moves of keys below 150 and
/// removals from key 199 down (leaves, and at the end a key leaf, empty).
pub fn stream_change(w: &mut mktree::db::WriteTransaction, i: u64) {
    match i % 3 {
        0 => {
            let x = (i / 3) as f64 * 0.7;
            let mesh = box_mesh([x, 1.0, 1.0], [x + 0.5, 1.5, 1.5]);
            w.insert(Object::new("n", mesh).with_key(10_000 + i)).unwrap();
        }
        1 => {
            w.move_by(&mktree::scene::Key::Int(i % 150), mktree::geom::Vector::new(3.0, 0.0, 0.0)).unwrap();
        }
        _ => {
            w.remove(&mktree::scene::Key::Int(199 - i / 3)).unwrap();
        }
    }
}
