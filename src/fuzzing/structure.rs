//! Structure-aware targets: each starts from one valid file (built once),
//! lets the input choose fields of one structure and what to write there,
//! re-seals every checksum up the chain as an attacker would
//! ([`Image::reseal`]), and then opens, queries, walks and checks the
//! forgery. Errors are fine; a panic, a hang or an unbounded allocation is
//! a bug, and so is a wrong answer from a file `check` passes: a forged
//! file that `check` accepts is a valid file of other objects, so its
//! answers must be those of brute force over the objects it returns.

use std::collections::{HashMap, HashSet, VecDeque};
use std::hash::{DefaultHasher, Hash, Hasher};
use std::sync::{Arc, Mutex, OnceLock};

use super::edit::{Catalog, Choices, Width, copy_chunk, edit_field, edit_raw};
use super::forge::{Image, Kind, Record, Reference};
use crate::build::{BuildParams, LeafRule, Method};
use crate::db::{CreateOptions, Database, check, read_hierarchy, view};
use crate::geom::{Aabb, Point, Pose};
use crate::lod::{Lattice, LodParams};
use crate::query::{
    ClashOptions, CollideOptions, QueryOptions, Region, Visitor, brute_force_region, clash, collide,
    object_meshes, query_region, walk,
};
use crate::scene::{Key, Mesh, Object, ObjectId, Scene};
use crate::store::device::MemDevice;
use crate::store::format::header::{SLOT_LEN, slot_offset};
use crate::store::format::node::NodeView;
use crate::store::format::quant::QuantBox;
use crate::store::{Block, BlockDevice, StorageError};

/// The structure a target forges.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Structure {
    /// Block 0 (fixed header, both copies of both slots) and the meta block.
    Header,
    Node,
    /// Geometry blocks and the leaves' spans over them.
    Geometry,
    /// The inline bounds (voxel blobs) of leaf records and the lattice.
    Lod,
    FreeList,
    /// The key index (its blocks and the meta block's root) and the leaves' keys areas.
    Keys,
}

const STRUCTURES: [Structure; 6] = [
    Structure::Header,
    Structure::Node,
    Structure::Geometry,
    Structure::Lod,
    Structure::FreeList,
    Structure::Keys,
];

/// Bytes per block of the base file.
const BS: usize = 1024;
/// Levels of detail of the base file: bounds at levels 2 and 3.
const M: u8 = 4;

/// A leaf record of the base file holding bounds: its block, its index
/// among the block's records, and each entry's box as the leaf decodes it.
#[derive(Debug, Clone)]
struct BoundSite {
    block: u32,
    record: usize,
    boxes: Vec<Aabb>,
}

/// The base file and what the forgers need to know of it.
struct Base {
    image: Image,
    catalogs: Vec<Catalog>,
    lattice: Lattice,
    sites: Vec<BoundSite>,
    /// The newest commit slot and its transaction.
    slot: usize,
    txn: u64,
    free_lists: Vec<u32>,
    /// The oracle's box queries, and each one's answer by brute force over
    /// the base objects (what a file of the base meshes must answer).
    boxes: Vec<Aabb>,
    exact: Vec<Vec<ObjectId>>,
    /// The base objects' boxes, which the input's probes split.
    objects: Vec<Aabb>,
    /// The newest tree's node blocks.
    nodes: Vec<u32>,
    /// The key index's blocks: (block, level above the leaves).
    key_blocks: Vec<(u32, u32)>,
    /// Each base object (by id) as a lookup by its key finds it.
    keyed: Vec<Keyed>,
    /// Keys near the base objects' and no object's ([`absent_keys`]).
    absent: Vec<Key>,
}

/// A base object as a lookup by key must find it.
#[derive(Debug, Clone)]
struct Keyed {
    key: Key,
    aabb: Aabb,
    mesh: Mesh,
}

fn mesh(vertices: &[[f64; 3]], triangles: Vec<[u32; 3]>) -> Mesh {
    let points: Vec<Point> = vertices.iter().map(|&v| v.into()).collect();
    Mesh::from_world(&points, triangles).unwrap_or_else(|e| panic!("the base scene's mesh: {e}"))
}

fn slanted(i: usize) -> Mesh {
    let o = [(i % 4) as f64 * 120.0, (i / 4) as f64 * 120.0, (i % 3) as f64 * 40.0];
    mesh(
        &[o, [o[0] + 100.0, o[1] + 10.0, o[2] + 60.0], [o[0] + 20.0, o[1] + 90.0, o[2] + 30.0]],
        vec![[0, 1, 2]],
    )
}

fn cuboid(lo: [f64; 3], hi: [f64; 3]) -> Mesh {
    Mesh::of_box(&Aabb::new(lo.into(), hi.into())).unwrap_or_else(|| panic!("the base scene's box {lo:?}"))
}

/// A wavy strip of 46 triangles: its record (1,168 bytes) is larger than
/// a geometry block's payload, so it is stored as parts.
fn strip() -> Mesh {
    let mut v = Vec::new();
    for j in 0..24 {
        let (x, z) = (j as f64 * 20.0, 20.0 * (j as f64 / 2.0).sin() + 30.0);
        v.push([x, 400.0, z]);
        v.push([x, 430.0, z + 10.0]);
    }
    let t =
        (0..23u32).flat_map(|j| [[2 * j, 2 * j + 1, 2 * j + 2], [2 * j + 1, 2 * j + 3, 2 * j + 2]]).collect();
    mesh(&v, t)
}

/// Long names, some not ASCII, so that the key entries holding them fill several blocks.
fn name(kind: &str, i: usize) -> String {
    format!("{kind}-{i}: größe {}", "name ".repeat(20 + 2 * i))
}

/// The base objects' keys, a mixture in an order unlike the ids': integers
/// (a boundary among them), byte strings (IFC GlobalIds, an empty one).
fn base_key(i: usize) -> Key {
    let bytes = |s: &str| Key::bytes(s).unwrap_or_else(|e| panic!("the base scene's key: {e}"));
    match i {
        0 => Key::Int(42),
        1 => Key::Int(1 << 40),
        2 => bytes("2O2Fr$t4X7Zf8NoEw0Xs9a"),
        3 => bytes(""),
        4 => Key::Int(7),
        5 => bytes("0K7w7JN$T0xOsnq9vT0VbL"),
        6 => bytes("box/6"),
        7 => Key::Int(u64::MAX),
        _ => bytes("strip"),
    }
}

/// The base objects' payloads: none for every third object, else 80 to
/// 400 bytes, so that the key index takes three leaves under a branch.
fn base_payload(i: usize) -> Vec<u8> {
    let n = if i % 3 == 1 { 0 } else { 80 + 40 * i };
    (0..n).map(|j| (31 * i + j) as u8).collect()
}

/// The base scene: slanted triangles, boxes and a strip stored as parts,
/// each with its key and payload.
fn base_scene() -> Scene {
    let mut objects: Vec<Object> = (0..6).map(|i| Object::new(name("triangle", i), slanted(i))).collect();
    objects.push(Object::new(name("box", 6), cuboid([500.0, 0.0, 0.0], [560.0, 40.0, 80.0])));
    objects.push(Object::new(name("box", 7), cuboid([500.0, 100.0, 20.0], [590.0, 150.0, 60.0])));
    objects.push(Object::new(name("strip", 8), strip()));
    let keyed =
        objects.into_iter().enumerate().map(|(i, o)| o.with_key(base_key(i)).with_payload(base_payload(i)));
    Scene::new(keyed.collect())
}

/// Levels of detail of a file of `m` levels on coarse grids, judged by few
/// samples: `check` voxelizes every bound on every run, and a write plans
/// them. One eps per polyhedral level (3 .. M-1).
pub(super) fn cheap_lods(m: u8) -> LodParams {
    LodParams {
        eps: Some(vec![60.0; usize::from(m.saturating_sub(3))]),
        cuberille_bits: 64,
        cuberille_object_bits: 64,
        error_samples: 4,
        model_samples: 4,
        ..LodParams::default()
    }
}

fn commit(db: &Database, scene: &Scene, store_all: bool) {
    let mut w = db.begin_write().unwrap_or_else(|e| panic!("the base file: {e}"));
    w.set_lod_params(LodParams { store_all, ..cheap_lods(M) });
    // A leaf per object: records enough for several node blocks.
    let params = BuildParams { method: Method::Moa, leaf: LeafRule::Objects(1), ..BuildParams::paper() };
    w.bulk_load(scene, &params, &|_| {}).unwrap_or_else(|e| panic!("the base file: {e}"));
    w.commit().unwrap_or_else(|e| panic!("the base file: {e}"));
}

/// The base file: two small trees, each committed while a reader held the
/// one before (so the free list holds ranges freed by two commits), then the
/// base scene with every bound stored.
fn base_file() -> Vec<u8> {
    let dev = Arc::new(MemDevice::new());
    let db = Database::create_on(dev.clone(), CreateOptions { block_size: BS as u32, lod_levels: M })
        .unwrap_or_else(|e| panic!("the base file: {e}"));
    let boxes = Scene::new(
        (0..3)
            .map(|i| {
                Object::new(format!("old{i}"), cuboid([i as f64 * 50.0; 3], [i as f64 * 50.0 + 30.0; 3]))
            })
            .collect(),
    );
    commit(&db, &boxes, false);
    let first = db.begin_read();
    let triangles = Scene::new((0..4).map(|i| Object::new(format!("older{i}"), slanted(i))).collect());
    commit(&db, &triangles, false);
    let second = db.begin_read();
    commit(&db, &base_scene(), true);
    drop((first, second, db));
    dev.to_bytes()
}

/// Records each leaf with its frame: (block, offset, frame).
#[derive(Default)]
struct Leaves(Vec<(u32, u32, Aabb)>);

impl Visitor for Leaves {
    fn node(&mut self, block: &Arc<Block>, offset: u32, frame: &Aabb) -> Result<(), StorageError> {
        if let NodeView::Leaf(_) = view(block, offset)? {
            self.0.push((block.id(), offset, *frame));
        }
        Ok(())
    }
}

/// Fields of the meta block (format-spec/meta.md) at `m`.
fn meta_fields(c: &mut Catalog, m: usize) {
    c.add(m, Width::U32, [16, 24, 28, 32, 36, 40, 44, 124, 144, 448, 452, 456, 460]);
    c.add(m, Width::U64, [48, 56, 64, 136, 736, 744]);
    c.add(m, Width::U64, (0..32).map(|i| 480 + 8 * i));
    c.add(m, Width::F64, (0..6).map(|i| 72 + 8 * i));
    c.add(m, Width::F64, [128, 152, 416, 424, 432, 440, 752, 760, 768]);
    c.add(m, Width::F64, (0..32).map(|i| 160 + 8 * i));
    c.add(m, Width::U8, [120, 121, 122, 123, 904, BS - 1]);
    c.add(m, Width::U8, 464..480);
    c.add(m, Width::F32, (0..32).map(|i| 776 + 4 * i));
}

impl Base {
    fn build() -> Base {
        let image = Image { bytes: base_file(), bs: BS };
        let (slot, at, txn) = image.newest().unwrap_or_else(|| panic!("the base file has a committed slot"));
        let roots = [
            Reference { field: at + 16, target: image.u32(at + 12), kind: Kind::Meta },
            Reference { field: at + 28, target: image.u32(at + 24), kind: Kind::FreeList },
        ];
        let reached = image.postorder(&roots);
        let of = |k: fn(Kind) -> bool| -> Vec<u32> {
            reached.iter().filter(|(_, kind, _)| k(*kind)).map(|(id, _, _)| *id).collect()
        };
        let nodes = of(|k| k == Kind::Node);
        let geometry = of(|k| k == Kind::Geometry);
        let free_lists = of(|k| k == Kind::FreeList);
        let meta = image.u32(at + 12) as usize * BS;
        // The leaves' frames, from the engine's own walk.
        let db = Database::open_on(Arc::new(MemDevice::from_bytes(image.bytes.clone())))
            .unwrap_or_else(|e| panic!("the base file opens: {e}"));
        let r = db.begin_read().unwrap_or_else(|e| panic!("the base file reads: {e}"));
        let mut leaves = Leaves::default();
        let root = r.root().unwrap_or_else(|| panic!("the base file has a tree"));
        walk(
            &r,
            root,
            &crate::query::Everything,
            &QueryOptions { lod: Some(1), ..Default::default() },
            &mut crate::db::Reads::new(None),
            &mut leaves,
        )
        .unwrap_or_else(|e| panic!("the base file walks: {e}"));
        let lattice = r.lattice().unwrap_or_else(|| panic!("the base file has a lattice"));
        let names = r.names().unwrap_or_else(|e| panic!("the base file's names: {e}"));
        assert_eq!(names.len(), base_scene().objects().len(), "the base file's names");
        let ids: Vec<ObjectId> = (0..names.len() as u32).map(ObjectId).collect();
        let meshes = object_meshes(&r, &ids).unwrap_or_else(|e| panic!("the base file's meshes: {e}"));
        let keyed: Vec<Keyed> = meshes
            .iter()
            .enumerate()
            .map(|(i, mesh)| {
                let key = base_key(i);
                let found = r.get(&key).unwrap_or_else(|e| panic!("the base file's key {key}: {e}"));
                let found = found.unwrap_or_else(|| panic!("the base file has no key {key}"));
                assert_eq!(found.id, ObjectId(i as u32), "the base file's key {key}");
                Keyed { key, aabb: found.aabb, mesh: mesh.clone() }
            })
            .collect();
        drop((r, db));

        let mut header = Catalog::default();
        header.add(0, Width::U8, (0..8).chain([16, 17, 300, 507, 1024, BS - 1]));
        header.add(0, Width::U32, [8, 12]);
        for s in 0..2 {
            for copy in 0..2 {
                let o = slot_offset(s, copy);
                header.add(o, Width::U64, [0]);
                header.add(o, Width::U8, [8, 9, 36, SLOT_LEN - 5]);
                header.add(o, Width::U32, [12, 20, 24, 32]);
                header.anchors.push(o);
            }
        }
        meta_fields(&mut header, meta);
        header.ranges = vec![(0, 1024), (meta + 16, BS - 16)];

        let mut node = Catalog::default();
        let mut geo = Catalog::default();
        let mut lod = Catalog::default();
        let mut sites = Vec::new();
        let payload = BS - 16;
        for &b in &nodes {
            let base = b as usize * BS;
            node.add(base, Width::U32, [16]);
            node.add(base, Width::U16, [20]);
            node.add(base, Width::U8, [22, 23]);
            node.ranges.push((base + 16, BS - 16));
            for (index, rec) in image.records(b).into_iter().enumerate() {
                node.anchors.push(rec.at());
                match rec {
                    Record::Internal { at } => {
                        node.add(at, Width::U8, [0, 1, 2, 3]);
                        node.add(at, Width::U32, [4, 8]);
                        node.add(at, Width::F32, [12, 16]);
                        for c in 0..2 {
                            let e = at + 20 + 32 * c;
                            node.anchors.push(e);
                            node.add(e, Width::U16, (0..6).map(|i| 2 * i));
                            node.add(e, Width::U32, [12, 20, 24, 28]);
                        }
                    }
                    Record::Leaf(l) => {
                        node.add(l.at, Width::U8, [0, 1, 14, 15]);
                        node.add(l.at, Width::U16, [2, 12]);
                        node.add(l.at, Width::U32, [4, 8, 16]);
                        node.add(l.end_at, Width::U32, [0]);
                        geo.add(l.at, Width::U32, [8]);
                        geo.add(l.at, Width::U16, [12]);
                        geo.add(l.end_at, Width::U32, [0]);
                        let first = image.u32(l.at + 8) as usize;
                        for i in 0..l.objects {
                            let e = l.objects_at + 20 * i;
                            node.anchors.push(e);
                            node.add(e, Width::U32, [0, 16]);
                            node.add(e, Width::U16, (0..6).map(|j| 4 + 2 * j));
                            geo.add(e, Width::U32, [16]);
                            // The object's record in its span (format-spec/geometry.md).
                            let s = image.u32(e + 16) as usize * 4;
                            let r = (first + s / payload) * BS + 16 + s % payload;
                            let (v, t) = (image.u32(r + 4) as usize, image.u32(r + 8) as usize);
                            if s % payload + 40 + 12 * (v + t) <= payload {
                                geo.anchors.extend([r, r + 16]);
                                geo.add(r, Width::U32, [0, 4, 8, 12]);
                                geo.add(r, Width::F64, [16, 24, 32]);
                                geo.add(r + 40, Width::F32, (0..3 * v).map(|j| 4 * j));
                                geo.add(r + 40 + 12 * v, Width::U32, (0..3 * t).map(|j| 4 * j));
                                geo.anchors.extend((0..v).map(|j| r + 40 + 12 * j));
                                geo.anchors.extend((0..t).map(|j| r + 40 + 12 * (v + j)));
                            }
                        }
                        let bounds = image.bounds(&l);
                        if !bounds.is_empty() {
                            let frame = leaves
                                .0
                                .iter()
                                .find(|x| x.0 == b && x.0 as usize * BS + x.1 as usize == l.at);
                            let boxes = (0..l.objects)
                                .map(|i| {
                                    let e = l.objects_at + 20 * i + 4;
                                    let q = std::array::from_fn(|j| image.u16(e + 2 * j));
                                    frame
                                        .and_then(|f| QuantBox::decode(&f.2, q))
                                        .map_or(Aabb::EMPTY, |q| q.outer)
                                })
                                .collect();
                            sites.push(BoundSite { block: b, record: index, boxes });
                            for i in 0..l.objects {
                                lod.add(l.objects_at + 20 * i, Width::U16, (0..6).map(|j| 4 + 2 * j));
                            }
                        }
                        for bound in bounds {
                            lod.anchors.extend([bound.head, bound.blob]);
                            lod.add(bound.head, Width::U16, [0, 2]);
                            lod.add(bound.blob, Width::U8, 0..bound.len);
                            lod.ranges.push((bound.blob, bound.len));
                        }
                    }
                }
            }
        }
        for &g in &geometry {
            geo.ranges.push((g as usize * BS + 16, payload));
        }
        lod.add(meta, Width::F64, (0..16).map(|k| 160 + 16 * k).chain([416, 424, 432, 440]));
        lod.add(meta, Width::U8, 464..480);
        lod.add(meta, Width::U32, [452, 456]);
        lod.add(0, Width::U8, [16]);

        let mut free = Catalog::default();
        for &b in &free_lists {
            let base = b as usize * BS;
            free.add(base, Width::U32, [16, 24]);
            free.add(base, Width::U8, [28, 31]);
            let per = (BS - 32) / 16;
            free.add(base + 32, Width::U32, (0..per).flat_map(|i| [16 * i, 16 * i + 4]));
            free.add(base + 32, Width::U64, (0..per).map(|i| 16 * i + 8));
            free.anchors.extend((0..per).map(|i| base + 32 + 16 * i));
            free.ranges.push((base + 16, BS - 16));
        }
        for copy in 0..2 {
            free.add(slot_offset(slot, copy), Width::U32, [20, 24, 32]);
        }

        // The key index: the meta block's root, each block's head and
        // entries; and the keys areas of the leaf records.
        let key_blocks: Vec<(u32, u32)> = reached
            .iter()
            .filter_map(|(id, kind, _)| match kind {
                Kind::Key { level } => Some((*id, *level)),
                _ => None,
            })
            .collect();
        let mut keys_c = Catalog::default();
        keys_c.add(meta, Width::U32, [904, 908, 912, 916]);
        keys_c.ranges.push((meta + 904, 16));
        for &(b, level) in &key_blocks {
            let at = b as usize * BS;
            keys_c.add(at, Width::U16, [16, 18]);
            keys_c.add(at, Width::U8, [18, 19]);
            keys_c.add(at, Width::U32, [20]);
            keys_c.ranges.push((at + 16, BS - 16));
            for e in image.key_block_entries(at, level > 0) {
                keys_c.anchors.push(e.at);
                if let Some((k, len)) = e.key {
                    key_fields(&mut keys_c, &image, k, len);
                }
                // The payload's and the name's length words and bytes.
                for p in e.payload.into_iter().chain(e.name) {
                    keys_c.add(p, Width::U16, [0]);
                    let n = usize::from(image.u16(p));
                    if n > 0 {
                        keys_c.add(p + 2, Width::U8, [0, n - 1]);
                        keys_c.ranges.push((p + 2, n));
                    }
                }
                if level == 0 {
                    // Object id, path bits, path length, reserved, box.
                    keys_c.anchors.push(e.fixed);
                    keys_c.add(e.fixed, Width::U32, [0]);
                    keys_c.add(e.fixed, Width::U64, [4]);
                    keys_c.add(e.fixed, Width::U8, [12, 13, 15]);
                    keys_c.add(e.fixed, Width::F64, (0..6).map(|j| 16 + 8 * j));
                } else {
                    keys_c.add(e.fixed, Width::U32, [0, 4]);
                }
            }
        }
        for &b in &nodes {
            for rec in image.records(b) {
                if let Record::Leaf(l) = rec {
                    keys_c.add(l.at, Width::U16, [14]);
                    if l.keys_len > 0 {
                        keys_c.ranges.push((l.keys_at, l.keys_len));
                    }
                    for (k, len) in image.stored_keys(&l) {
                        key_fields(&mut keys_c, &image, k, len);
                    }
                }
            }
        }

        let boxes = oracle_boxes(&meshes);
        let scene = Scene::new(meshes.iter().map(|m| Object::new("", m.clone())).collect());
        let exact = boxes.iter().map(|b| brute_force_region(&scene, &Region::Box(*b))).collect();
        let absent = absent_keys(keyed.iter().map(|o| &o.key));
        Base {
            catalogs: vec![header, node, geo, lod, free, keys_c],
            lattice,
            sites,
            slot,
            txn,
            free_lists,
            boxes,
            exact,
            objects: meshes.iter().map(|m| m.aabb()).collect(),
            nodes,
            key_blocks,
            keyed,
            absent,
            image,
        }
    }
}

/// Fields of the stored key at `at` of `len` bytes (format-spec/keys.md):
/// its tag; an integer's 8 bytes and its low byte (big-endian: the last);
/// a byte string's length and bytes.
fn key_fields(c: &mut Catalog, image: &Image, at: usize, len: usize) {
    c.anchors.push(at);
    c.add(at, Width::U8, [0]);
    if image.u8(at) == 0 {
        c.add(at + 1, Width::U64, [0]);
        c.add(at, Width::U8, [8]);
    } else {
        c.add(at, Width::U8, 1..len);
    }
}

/// The oracle's queries: the scene's box and its octants, and a cube at
/// each object's centre.
fn oracle_boxes(meshes: &[Mesh]) -> Vec<Aabb> {
    let scene = meshes.iter().fold(Aabb::EMPTY, |b, m| b.union(&m.aabb()));
    let c = scene.center();
    let mut out = vec![scene];
    for i in 0..8 {
        let pick = |a: usize| if i >> a & 1 == 0 { (scene.min[a], c[a]) } else { (c[a], scene.max[a]) };
        let (x, y, z) = (pick(0), pick(1), pick(2));
        out.push(Aabb::from_array([x.0, y.0, z.0, x.1, y.1, z.1]));
    }
    for m in meshes {
        let b = m.aabb();
        let half = crate::geom::Vector::repeat(b.extent().max() * 0.2);
        out.push(Aabb::new(b.center() - half, b.center() + half));
    }
    out
}

fn base() -> &'static Base {
    static BASE: OnceLock<Base> = OnceLock::new();
    BASE.get_or_init(Base::build)
}

/// Opens the forged image and runs what `s` can change: every query kind
/// for the tree's structures, `names` for the key index, a write for the
/// slots and the free list; then `check`, and the oracles when it passes.
fn exercise(s: Structure, bytes: Vec<u8>, probes: &[Aabb]) {
    // Compaction reads and moves every structure of the tree (slots and
    // the free list are its commits' own, exercised by write_after).
    let moved = (!matches!(s, Structure::Header | Structure::FreeList)).then(|| bytes.clone());
    let dev = Arc::new(MemDevice::from_bytes(bytes));
    let Ok(db) = Database::open_on(dev.clone()) else { return };
    if let Ok(r) = db.begin_read() {
        let m = r.pager().lod_levels();
        let levels: Vec<u8> = match s {
            Structure::Header | Structure::Node | Structure::Lod => (1..=m).collect(),
            Structure::Geometry | Structure::Keys => vec![m],
            Structure::FreeList => Vec::new(),
        };
        let corner = Aabb::from_array([0.0, 0.0, 0.0, 150.0, 150.0, 60.0]);
        for &k in &levels {
            let _ = query_region(
                &r,
                &Region::Box(corner),
                &QueryOptions { lod: Some(k), ..Default::default() },
                None,
            );
            let _ = r.fetch_level(0, k, true, &mut Default::default());
        }
        if !levels.is_empty() {
            let budget = QueryOptions { budget: Some(3), ..Default::default() };
            let _ = query_region(&r, &Region::Box(corner), &budget, None);
            let probe = cuboid([90.0, 90.0, 20.0], [130.0, 130.0, 50.0]);
            let opts = CollideOptions { clearance: 5.0, ..Default::default() };
            let _ = collide(&r, &probe, &Pose::default(), &opts, None);
            let k = if s == Structure::Lod { 2.min(m) } else { m };
            let _ = clash(&r, &ClashOptions { lod: Some(k), clearance: 1.0 }, None);
        }
        if matches!(s, Structure::Header | Structure::Node) {
            let _ = read_hierarchy(&r);
            let _ = r.fetch_level(0, 1, false, &mut Default::default());
            if let Some(info) = r.info() {
                let _ = r.fetch_level(info.nodes.saturating_sub(1), m, true, &mut Default::default());
            }
        }
        if matches!(s, Structure::Header | Structure::Keys) {
            let _ = r.names();
        }
    }
    let sound = check(&db).is_ok_and(|r| r.ok());
    if sound
        && matches!(
            s,
            Structure::Header | Structure::Node | Structure::Geometry | Structure::Lod | Structure::Keys
        )
    {
        answers_match_brute_force(&db, probes);
    }
    match s {
        Structure::Keys => lookups(&db, sound),
        // Forged slots, meta or node records move what the index points at.
        Structure::Header | Structure::Node => lookups(&db, false),
        _ => {}
    }
    if matches!(s, Structure::Header | Structure::FreeList) {
        write_after(&dev, db, sound, s);
    }
    if let Some(bytes) = moved {
        compact_after(bytes, sound, probes);
    }
}

/// A compaction of the forged file moves its tree as it is: over a file
/// `check` passed it succeeds, and the file reopens, passes `check` and
/// answers as brute force; over any file it fails with a typed error or
/// leaves a file that reopens.
fn compact_after(bytes: Vec<u8>, sound: bool, probes: &[Aabb]) {
    let dev = Arc::new(MemDevice::from_bytes(bytes));
    let Ok(db) = Database::open_on(dev.clone()) else { return };
    let compacted = db.compact();
    if sound && let Err(e) = &compacted {
        panic!("compact fails on a file check passed: {e}");
    }
    drop(db);
    let db = Database::open_on(dev as Arc<dyn BlockDevice>)
        .unwrap_or_else(|e| panic!("a forged file does not reopen after compact: {e}"));
    if sound {
        let report = check(&db).unwrap_or_else(|e| panic!("check after compact: {e}"));
        assert!(report.ok(), "compact over a file check passed leaves faults: {:?}", report.faults);
        answers_match_brute_force(&db, probes);
    }
}

/// The "never silently wrong" oracle for a file `check` passed: its box
/// queries (the base file's and the input's `probes`) answer at level M as
/// brute force over the objects the file returns, and below M with a superset.
fn answers_match_brute_force(db: &Database, probes: &[Aabb]) {
    let base = base();
    let Ok(r) = db.begin_read() else { return };
    let Some(info) = r.info() else { return };
    let ids: Vec<ObjectId> = (0..info.objects).map(ObjectId).collect();
    let Ok(meshes) = object_meshes(&r, &ids) else { return };
    // Most files that pass hold the base objects: their answers to the base
    // boxes are known.
    let known = meshes.len() == base.keyed.len() && meshes.iter().zip(&base.keyed).all(|(m, o)| *m == o.mesh);
    let scene = Scene::new(meshes.into_iter().map(|m| Object::new("", m)).collect());
    let m = info.lod_levels;
    for (i, b) in base.boxes.iter().chain(probes).enumerate() {
        let exact = match base.exact.get(i) {
            Some(exact) if known => exact.clone(),
            _ => brute_force_region(&scene, &Region::Box(*b)),
        };
        // Level 2 uses the voxel bounds (when M > 2), M the geometry too.
        for k in [2.min(m), m] {
            let opts = QueryOptions { lod: Some(k), ..Default::default() };
            let Ok(a) = query_region(&r, &Region::Box(*b), &opts, None) else { continue };
            if k == m {
                assert_eq!(
                    a.objects, exact,
                    "a file check passes answers {b:?} unlike brute force over its objects"
                );
            } else {
                assert!(
                    exact.iter().all(|o| a.objects.binary_search(o).is_ok()),
                    "a file check passes answers {b:?} at level {k} without {:?} of the exact {exact:?}",
                    a.objects
                );
            }
        }
    }
}

/// Each leaf's objects' keys, as the leaf stores them: id -> key.
#[derive(Default)]
struct LeafKeys(HashMap<u32, Key>);

impl Visitor for LeafKeys {
    fn node(&mut self, block: &Arc<Block>, offset: u32, _: &Aabb) -> Result<(), StorageError> {
        if let NodeView::Leaf(l) = view(block, offset)? {
            for i in 0..l.len() {
                if let (Some(o), Some(k)) = (l.object(i), l.key(i)) {
                    self.0.entry(o.object_id).or_insert(k);
                }
            }
        }
        Ok(())
    }
}

/// Keys near `keys` and at the ends of the order, none of them in `keys`:
/// an integer one off, a byte string cut, extended or with its last byte
/// one up, the least and greatest keys.
fn absent_keys<'a>(keys: impl IntoIterator<Item = &'a Key>) -> Vec<Key> {
    let keys: HashSet<Key> = keys.into_iter().cloned().collect();
    let mut out: Vec<Key> =
        vec![Key::Int(0), Key::Int(u64::MAX), Key::Bytes(Box::new([])), Key::Bytes(Box::new([0]))];
    out.push(Key::Bytes(vec![0xff; Key::MAX_BYTES].into()));
    for k in &keys {
        match k {
            Key::Int(x) => out.extend([x.wrapping_sub(1), x.wrapping_add(1)].map(Key::Int)),
            Key::Bytes(b) => {
                let mut longer = b.to_vec();
                longer.push(0);
                out.push(Key::Bytes(longer.into()));
                if let Some((&last, head)) = b.split_last() {
                    out.push(Key::Bytes(head.into()));
                    let mut up = b.to_vec();
                    up[head.len()] = last.wrapping_add(1);
                    out.push(Key::Bytes(up.into()));
                }
            }
        }
    }
    out.sort();
    out.dedup();
    out.retain(|k| !keys.contains(k));
    out
}

/// Lookups by key (`get`, `aabb`, `mesh`) of every base object's key and
/// of keys no object has. They must return (an error is fine) unless the
/// file is `sound` (check passed); then each object of the base scene is
/// found by the key its leaf stores (the base scene's, unless a forgery
/// moved keys between objects everywhere, which makes a valid file of
/// other keys) with its id, box and mesh as in the base file, and every
/// other key finds nothing.
fn lookups(db: &Database, sound: bool) {
    let base = base();
    let Ok(r) = db.begin_read() else { return };
    if !sound {
        for k in base.keyed.iter().map(|o| &o.key).chain(&base.absent) {
            let _ = (r.get(k), r.aabb(k), r.mesh(k));
        }
        return;
    }
    let root = r.root().unwrap_or_else(|| panic!("a file check passes has no tree"));
    let mut stored = LeafKeys::default();
    let everything = QueryOptions { lod: Some(1), ..Default::default() };
    walk(&r, root, &crate::query::Everything, &everything, &mut crate::db::Reads::new(None), &mut stored)
        .unwrap_or_else(|e| panic!("a file check passes does not walk: {e}"));
    assert_eq!(stored.0.len(), base.keyed.len(), "a file check passes keys other objects than the base's");
    for (i, o) in base.keyed.iter().enumerate() {
        let id = ObjectId(i as u32);
        let key =
            stored.0.get(&id.0).unwrap_or_else(|| panic!("a file check passes stores no key for {id:?}"));
        let found = match r.get(key) {
            Ok(Some(found)) => found,
            other => panic!("a file check passes looks up {key} (object {i}) as {other:?}"),
        };
        assert_eq!((found.id, &found.key, found.aabb), (id, key, o.aabb), "a file check passes: get({key})");
        match r.aabb(key) {
            Ok(Some(b)) if b == o.aabb => {}
            other => panic!("a file check passes: aabb({key}) of object {i} is {other:?}, not {:?}", o.aabb),
        }
        match r.mesh(key) {
            Ok(Some(m)) if m == o.mesh => {}
            Ok(Some(_)) => panic!("a file check passes: mesh({key}) is not object {i}'s"),
            other => panic!("a file check passes: mesh({key}) of object {i} is {other:?}"),
        }
    }
    for k in absent_keys(stored.0.values()) {
        match (r.get(&k), r.aabb(&k), r.mesh(&k)) {
            (Ok(None), Ok(None), Ok(None)) => {}
            other => panic!("a file check passes finds key {k}, which no object has: {other:?}"),
        }
    }
}

/// Three boxes, the tree a write puts over a forged file.
fn small_scene() -> Scene {
    Scene::new(
        (0..3)
            .map(|i| {
                let lo = [i as f64 * 70.0, 10.0, 5.0];
                Object::new(format!("n{i}"), cuboid(lo, [lo[0] + 50.0, 60.0, 45.0]))
            })
            .collect(),
    )
}

/// A write over the forged file: if it commits, the file reopens at the new
/// tree, which answers as brute force does, and `check` passes if it passed
/// before (the writer reuses only what the file says is free).
fn write_after(dev: &Arc<MemDevice>, db: Database, sound: bool, s: Structure) {
    let scene = small_scene();
    {
        // Beginning recovers and repairs slot copies; a tree's commit writes
        // a free list from the file's. A forged free list is worth a tree
        // whatever check says; forged slots or meta only when it passes.
        let Ok(mut w) = db.begin_write() else { return };
        if !sound && s != Structure::FreeList {
            let _ = w.abort();
            return;
        }
        w.set_lod_params(LodParams { store_all: true, ..cheap_lods(db.lod_levels()) });
        let params = BuildParams { leaf: LeafRule::Objects(2), ..BuildParams::paper() };
        if w.bulk_load(&scene, &params, &|_| {}).is_err() || w.commit().is_err() {
            return;
        }
    }
    drop(db);
    let db = Database::open_on(dev.clone() as Arc<dyn BlockDevice>)
        .unwrap_or_else(|e| panic!("a committed write over a forged file does not reopen: {e}"));
    let r = db.begin_read().unwrap_or_else(|e| panic!("{e}"));
    let everything = Region::Box(Aabb::from_array([-1e3, -1e3, -1e3, 1e3, 1e3, 1e3]));
    let a = query_region(&r, &everything, &QueryOptions::default(), None)
        .unwrap_or_else(|e| panic!("the tree written over a forged file: {e}"));
    assert_eq!(a.objects, brute_force_region(&scene, &everything), "the tree written over a forged file");
    drop(r);
    if sound {
        let report = check(&db).unwrap_or_else(|e| panic!("check after a write over a sound file: {e}"));
        assert!(report.ok(), "a write over a file check passed leaves faults: {:?}", report.faults);
    }
}

/// Forges `s` in a copy of the base file as `data` chooses, and exercises it.
pub fn forge(s: Structure, data: &[u8]) {
    let (img, probes) = forgery(s, data);
    // Edits that changed nothing (or were undone) forge the base file, which
    // is sound; and many inputs forge a file already run. The same bytes
    // (and probes) take the same paths: only a new file is run.
    if let Some(key) = digest(s, &img, &probes)
        && first_seen(key)
    {
        exercise(s, img, &probes);
    }
}

/// A 64-bit digest of the structure, the probes and how `bytes` differs
/// from the base file (its length and the blocks that differ, which a
/// forgery makes few: hashing those, not the whole file, is cheap); `None`
/// when `bytes` is the base file.
fn digest(s: Structure, bytes: &[u8], probes: &[Aabb]) -> Option<u64> {
    let base = &base().image.bytes;
    let mut h = DefaultHasher::new();
    (s as u8, bytes.len()).hash(&mut h);
    let mut same = bytes.len() == base.len();
    for (i, block) in bytes.chunks(BS).enumerate() {
        if base.get(i * BS..i * BS + block.len()) != Some(block) {
            same = false;
            (i, block).hash(&mut h);
        }
    }
    if same {
        return None;
    }
    for x in probes.iter().flat_map(|p| p.to_array()) {
        x.to_bits().hash(&mut h);
    }
    Some(h.finish())
}

/// Files run lately, remembered by their [`digest`].
const REMEMBERED: usize = 1 << 14;

/// True unless a file of digest `key` was among the last [`REMEMBERED`] run.
fn first_seen(key: u64) -> bool {
    type Memory = (HashSet<u64>, VecDeque<u64>);
    static SEEN: Mutex<Option<Memory>> = Mutex::new(None);
    let mut guard = SEEN.lock().unwrap_or_else(|e| e.into_inner());
    let (set, order) = guard.get_or_insert_with(Memory::default);
    if !set.insert(key) {
        return false;
    }
    order.push_back(key);
    if order.len() > REMEMBERED
        && let Some(old) = order.pop_front()
    {
        set.remove(&old);
    }
    true
}

/// The file the target of `s` exercises for input `data`: the base file
/// with the structure forged as `data` chooses, every checksum re-sealed.
pub fn forged(s: Structure, data: &[u8]) -> Vec<u8> {
    forgery(s, data).0
}

/// The forged file for `data`, and the box queries it adds to the oracle's.
fn forgery(s: Structure, data: &[u8]) -> (Vec<u8>, Vec<Aabb>) {
    let base = base();
    let mut img = base.image.clone();
    let catalog = &base.catalogs[STRUCTURES.iter().position(|&x| x == s).unwrap_or(0)];
    let mut c = Choices::new(data);
    let (mut tears, mut probes) = (Vec::new(), Vec::new());
    while !c.is_empty() {
        match c.u8() % 13 {
            0..=5 => edit_field(&mut img, catalog, &mut c),
            6 | 7 => edit_raw(&mut img, catalog, &mut c),
            8 => copy_chunk(&mut img, catalog, &mut c),
            12 => probes.extend(probe(base, &mut c)),
            op => special(s, base, &mut img, op - 9, &mut c, &mut tears),
        }
    }
    img.reseal();
    for (at, x) in tears {
        if let Some(b) = img.bytes.get_mut(at) {
            *b ^= x;
        }
    }
    (img.bytes, probes)
}

/// A box query for the oracle: one of an n x n x n split of a base
/// object's box (n <= 4: about a voxel cell of a bound), grown a little. A
/// forged bound or box that check accepts yet answers wrongly shows only
/// in a query that holds or meets part of it, so the input aims one.
fn probe(base: &Base, c: &mut Choices) -> Option<Aabb> {
    let b = base.objects.get(c.below(base.objects.len()))?;
    let n = 1 + c.below(4);
    let (lo, step) = (b.min, b.extent() / n as f64);
    let at = crate::geom::Vector::new(c.below(n) as f64, c.below(n) as f64, c.below(n) as f64);
    let min = lo + step.component_mul(&at);
    let grow = f64::from(c.u8()) / 8.0;
    Some(Aabb::new(min, min + step).grown(grow))
}

/// The structure's own forgeries (`op` in 0 ..= 2).
fn special(
    s: Structure,
    base: &Base,
    img: &mut Image,
    op: u8,
    c: &mut Choices,
    tears: &mut Vec<(usize, u8)>,
) {
    match s {
        Structure::Header => match op {
            // A copy moved over another (and re-signed for its new place).
            0 => {
                let (from, to) = (slot_offset(c.below(2), c.below(2)), slot_offset(c.below(2), c.below(2)));
                img.bytes.copy_within(from..from + SLOT_LEN, to);
            }
            // A copy torn after sealing: the other copy must hold the slot.
            1 => tears.push((slot_offset(c.below(2), c.below(2)) + c.below(SLOT_LEN), c.u8() | 1)),
            _ => {
                let at = slot_offset(c.below(2), c.below(2));
                img.bytes[at..at + SLOT_LEN].fill(0);
            }
        },
        Structure::Node => node_op(img, op, c),
        Structure::Geometry => {
            // Two vertices or triangles of records swapped.
            let catalog = &base.catalogs[2];
            let (a, b) = (
                catalog.anchors.get(c.below(catalog.anchors.len())),
                catalog.anchors.get(c.below(catalog.anchors.len())),
            );
            if let (Some(&a), Some(&b)) = (a, b)
                && a.abs_diff(b) >= 12
            {
                let x: Vec<u8> = img.bytes[a..a + 12].to_vec();
                img.bytes.copy_within(b..b + 12, a);
                img.put(b, &x);
            }
        }
        Structure::Lod => lod_op(base, img, op, c),
        Structure::FreeList => free_op(base, img, op, c),
        Structure::Keys => keys_op(base, img, op, c),
    }
}

/// A key block's entries as bytes: (key, the rest), a branch's first child
/// with an empty key.
type RawEntries = Vec<(Vec<u8>, Vec<u8>)>;

/// The entries of key block `block` (level `level`) as they fit its used bytes.
fn raw_entries(img: &Image, block: u32, level: u32) -> RawEntries {
    let Some(at) = img.base(block) else { return Vec::new() };
    img.key_block_entries(at, level > 0)
        .into_iter()
        .map(|e| {
            let (k, len) = e.key.unwrap_or((e.at, 0));
            (img.bytes[k..k + len].to_vec(), img.bytes[k + len..e.end].to_vec())
        })
        .collect()
}

/// Writes `entries` as key block `block`'s: count, used bytes, entries, the
/// rest zero. False (and nothing written) when they do not fit.
fn write_key_block(img: &mut Image, block: u32, entries: &RawEntries) -> bool {
    let bytes: Vec<u8> = entries.iter().flat_map(|(k, rest)| k.iter().chain(rest)).copied().collect();
    let (Some(at), Ok(count)) = (img.base(block), u16::try_from(entries.len())) else { return false };
    if 24 + bytes.len() > BS {
        return false;
    }
    img.put(at + 16, &count.to_le_bytes());
    img.put_u32(at + 20, bytes.len() as u32);
    img.bytes[at + 24..at + BS].fill(0);
    img.put(at + 24, &bytes);
    true
}

/// Replaces the keys area of leaf `record` of node block `block` by `keys`
/// (stored forms), padded, resizing the record. False when it cannot be written.
fn rewrite_keys(img: &mut Image, block: u32, record: usize, keys: &[Vec<u8>]) -> bool {
    let Some(Record::Leaf(l)) = img.records(block).get(record).copied() else { return false };
    let mut area = keys.concat();
    area.resize(area.len().next_multiple_of(4), 0);
    let Ok(len) = u16::try_from(area.len()) else { return false };
    let (old, new) = (l.keys_len, area.len());
    let done = match new.cmp(&old) {
        std::cmp::Ordering::Greater => img.splice(block, l.at, l.keys_at + old, (new - old) as isize),
        std::cmp::Ordering::Less => img.splice(block, l.at, l.keys_at + new, -((old - new) as isize)),
        std::cmp::Ordering::Equal => true,
    };
    if done {
        img.put(l.keys_at, &area);
        img.put(l.at + 14, &len.to_le_bytes());
    }
    done
}

/// The fixed parts of the key leaves' entries (absolute offsets).
fn key_leaf_entries(base: &Base, img: &Image) -> Vec<usize> {
    let leaves = base.key_blocks.iter().filter(|b| b.1 == 0).filter_map(|b| img.base(b.0));
    leaves.flat_map(|at| img.key_block_entries(at, false)).map(|e| e.fixed).collect()
}

/// The leaf records of the base tree's node blocks: (block, record index, layout).
fn leaf_records(base: &Base, img: &Image) -> Vec<(u32, usize, super::forge::LeafAt)> {
    let mut out = Vec::new();
    for &b in &base.nodes {
        for (i, rec) in img.records(b).into_iter().enumerate() {
            if let Record::Leaf(l) = rec {
                out.push((b, i, l));
            }
        }
    }
    out
}

/// Key index forgeries. Op 0: two entries' keys swapped (order broken, or
/// keys moved between objects, between leaves or into a branch's
/// separators), or two entries' object ids. Op 1: an entry pointed at
/// another entry's leaf record, or at any leaf record and entry; or a leaf
/// record's stored key made another's. Op 2: a key block's used bytes cut
/// at an entry or a byte, or extended, its entry count kept or made to match.
fn keys_op(base: &Base, img: &mut Image, op: u8, c: &mut Choices) {
    let how = c.u8();
    match (op, how & 1) {
        (0, 0) => {
            let keyed: Vec<(usize, usize)> = (0..base.key_blocks.len())
                .flat_map(|b| {
                    let raw = raw_entries(img, base.key_blocks[b].0, base.key_blocks[b].1);
                    (0..raw.len()).filter(move |&i| !raw[i].0.is_empty()).map(move |i| (b, i))
                })
                .collect();
            let (Some(&x), Some(&y)) = (keyed.get(c.below(keyed.len())), keyed.get(c.below(keyed.len())))
            else {
                return;
            };
            if x == y {
                return;
            }
            let blocks = if x.0 == y.0 { vec![x.0] } else { vec![x.0, y.0] };
            let mut raws: Vec<RawEntries> = blocks
                .iter()
                .map(|&b| raw_entries(img, base.key_blocks[b].0, base.key_blocks[b].1))
                .collect();
            let (rx, ry) = (usize::from(x.0 != blocks[0]), usize::from(y.0 != blocks[0]));
            let kx = std::mem::take(&mut raws[rx][x.1].0);
            let ky = std::mem::replace(&mut raws[ry][y.1].0, kx);
            raws[rx][x.1].0 = ky;
            // Both blocks or neither: check each fits before writing.
            let mut copy = img.clone();
            if blocks.iter().zip(&raws).all(|(&b, raw)| write_key_block(&mut copy, base.key_blocks[b].0, raw))
            {
                *img = copy;
            }
        }
        (0, _) => {
            let entries = key_leaf_entries(base, img);
            let (Some(&x), Some(&y)) =
                (entries.get(c.below(entries.len())), entries.get(c.below(entries.len())))
            else {
                return;
            };
            let (a, b) = (img.u32(x), img.u32(y));
            img.put_u32(x, b);
            img.put_u32(y, a);
        }
        (1, 0) => {
            let entries = key_leaf_entries(base, img);
            let Some(&e) = entries.get(c.below(entries.len())) else { return };
            if c.u8() & 1 == 0 {
                // Another entry's leaf record and entry.
                let Some(&f) = entries.get(c.below(entries.len())) else { return };
                let (block, offset, entry) = (img.u32(f + 4), img.u32(f + 12), img.u16(f + 16));
                img.put_u32(e + 4, block);
                img.put_u32(e + 12, offset);
                img.put(e + 16, &entry.to_le_bytes());
            } else {
                // Any leaf record of the tree, any entry of it (or one past).
                let leaves = leaf_records(base, img);
                let Some(&(block, _, l)) = leaves.get(c.below(leaves.len())) else { return };
                let entry = c.below(l.objects + 1) as u16;
                img.put_u32(e + 4, block);
                img.put_u32(e + 12, (l.at - block as usize * BS) as u32);
                img.put(e + 16, &entry.to_le_bytes());
            }
        }
        (1, _) => {
            let leaves = leaf_records(base, img);
            let Some(&(block, record, l)) = leaves.get(c.below(leaves.len())) else { return };
            let mut keys: Vec<Vec<u8>> =
                img.stored_keys(&l).iter().map(|&(k, n)| img.bytes[k..k + n].to_vec()).collect();
            // Another key: one a leaf stores or one the index holds.
            let mut pool: Vec<Vec<u8>> = leaves
                .iter()
                .flat_map(|(_, _, other)| img.stored_keys(other))
                .map(|(k, n)| img.bytes[k..k + n].to_vec())
                .collect();
            for &(b, level) in &base.key_blocks {
                pool.extend(raw_entries(img, b, level).into_iter().map(|e| e.0).filter(|k| !k.is_empty()));
            }
            let j = c.below(keys.len());
            let (Some(slot), Some(other)) = (keys.get_mut(j), pool.get(c.below(pool.len()))) else { return };
            *slot = other.clone();
            rewrite_keys(img, block, record, &keys);
        }
        _ => {
            let Some(&(block, level)) = base.key_blocks.get(c.below(base.key_blocks.len())) else { return };
            let Some(at) = img.base(block) else { return };
            let (used, count) = (img.u32(at + 20) as usize, img.u16(at + 16));
            let (new_used, new_count) = match how >> 1 & 3 {
                0 => {
                    // Cut at an entry: the entries before it kept.
                    let entries = img.key_block_entries(at, level > 0);
                    let k = c.below(entries.len());
                    let Some(e) = entries.get(k) else { return };
                    (e.at - (at + 24), k as u16)
                }
                1 => (c.below(used + 1), count),
                _ => (used + 1 + c.below(128), count.wrapping_add(1)),
            };
            let count = if c.u8() & 1 == 0 { count } else { new_count };
            if new_used < used {
                let end = (at + 24 + used).min(at + BS);
                img.bytes[(at + 24 + new_used).min(end)..end].fill(0);
            }
            img.put_u32(at + 20, new_used as u32);
            img.put(at + 16, &count.to_le_bytes());
        }
    }
}

/// Node forgeries: children swapped, an object entry duplicated or removed.
fn node_op(img: &mut Image, op: u8, c: &mut Choices) {
    let nodes = img.node_blocks();
    let Some(&b) = nodes.get(c.below(nodes.len())) else { return };
    let records = img.records(b);
    let Some(&rec) = records.get(c.below(records.len())) else { return };
    match (rec, op) {
        (Record::Leaf(l), _) if l.objects == 0 => {}
        (Record::Internal { at }, _) => {
            let first: Vec<u8> = img.bytes[at + 20..at + 52].to_vec();
            img.bytes.copy_within(at + 52..at + 84, at + 20);
            img.put(at + 52, &first);
        }
        (Record::Leaf(l), 0) => {
            // A copy of entry j appended to the leaf's entries.
            let j = c.below(l.objects);
            let entry: Vec<u8> = img.bytes[l.objects_at + 20 * j..l.objects_at + 20 * j + 20].to_vec();
            if img.splice(b, l.at, l.end_at, 20) {
                img.put(l.end_at, &entry);
                let n = img.u16(l.at + 2).wrapping_add(1);
                img.put(l.at + 2, &n.to_le_bytes());
            }
        }
        (Record::Leaf(l), _) => {
            let j = c.below(l.objects);
            if img.splice(b, l.at, l.objects_at + 20 * j, -20) {
                let n = img.u16(l.at + 2).wrapping_sub(1);
                img.put(l.at + 2, &n.to_le_bytes());
            }
        }
    }
}

/// Replaces the bounds area of leaf `record` of block `block` by `entries`
/// (target, level, blob), resizing the record. False when it cannot be written.
fn rewrite_bounds(img: &mut Image, block: u32, record: usize, entries: &[(u16, u8, Vec<u8>)]) -> bool {
    let Some(Record::Leaf(l)) = img.records(block).get(record).copied() else { return false };
    let mut area = Vec::new();
    for (t, k, blob) in entries {
        let Ok(len) = u16::try_from(blob.len()) else { return false };
        if len > 4095 {
            return false;
        }
        area.extend_from_slice(&t.to_le_bytes());
        area.extend_from_slice(&(u16::from(k & 0xf) | len << 4).to_le_bytes());
        area.extend_from_slice(blob);
    }
    area.resize(area.len().next_multiple_of(4), 0);
    let (old, new) = (l.bounds_len, area.len());
    let done = match new.cmp(&old) {
        std::cmp::Ordering::Greater => img.splice(block, l.at, l.bounds_at + old, (new - old) as isize),
        std::cmp::Ordering::Less => img.splice(block, l.at, l.bounds_at + new, -((old - new) as isize)),
        std::cmp::Ordering::Equal => true,
    };
    if done {
        img.put(l.bounds_at, &area);
        img.put_u32(l.at + 16, new as u32);
    }
    done
}

/// LOD forgeries: cells of a bound flipped (re-encoded, so the blob stays
/// well formed), a blob replaced by the input's bytes, a bound added (a copy
/// of another, retargeted) or removed.
fn lod_op(base: &Base, img: &mut Image, op: u8, c: &mut Choices) {
    let Some(site) = base.sites.get(c.below(base.sites.len())) else { return };
    let Some(Record::Leaf(l)) = img.records(site.block).get(site.record).copied() else { return };
    let mut entries: Vec<(u16, u8, Vec<u8>)> = img
        .bounds(&l)
        .iter()
        .map(|b| (b.target, b.level, img.bytes[b.blob..b.blob + b.len].to_vec()))
        .collect();
    let j = c.below(entries.len());
    match op {
        0 => {
            let Some((t, _, blob)) = entries.get_mut(j) else { return };
            let Some(outer) = site.boxes.get(usize::from(*t)) else { return };
            let Ok(mut v) = crate::lod::decode(blob, &base.lattice, outer) else { return };
            let cells = v.grid().cells() as usize;
            for _ in 0..1 + c.below(4) {
                let i = c.below(cells);
                if let Some(w) = v.bits.get_mut(i / 64) {
                    *w ^= 1 << (i % 64);
                }
            }
            *blob = crate::lod::encode(&v);
        }
        1 => {
            let Some((_, _, blob)) = entries.get_mut(j) else { return };
            let n = c.below(64);
            *blob = c.bytes(n);
        }
        _ if c.u8() & 1 == 0 => {
            let Some(mut e) = entries.get(j).cloned() else { return };
            e.0 = c.below(l.objects + 1) as u16;
            e.1 = c.u8() % 16;
            let at = c.below(entries.len() + 1);
            entries.insert(at, e);
        }
        _ => {
            if j < entries.len() {
                entries.remove(j);
            }
        }
    }
    rewrite_bounds(img, site.block, site.record, &entries);
}

/// Free-list forgeries: the list split into a chain of two blocks (the
/// second taken from a free range), or blocks appended to the file as free.
fn free_op(base: &Base, img: &mut Image, op: u8, c: &mut Choices) {
    let Some(&list) = base.free_lists.first() else { return };
    let at = list as usize * BS;
    let n = (img.u32(at + 24) as usize).min((BS - 32) / 16);
    let mut ranges: Vec<(u32, u32, u64)> = (0..n)
        .map(|i| (img.u32(at + 32 + 16 * i), img.u32(at + 36 + 16 * i), img.u64(at + 40 + 16 * i)))
        .collect();
    let slots = [slot_offset(base.slot, 0), slot_offset(base.slot, 1)];
    let frame = |img: &mut Image, id: u32| {
        if let Some(b) = img.base(id) {
            img.bytes[b..b + BS].fill(0);
            img.put(b + 4, &[5]);
            img.put(b + 8, &base.txn.to_le_bytes());
        }
    };
    let write = |img: &mut Image, id: u32, next: u32, ranges: &[(u32, u32, u64)]| {
        let Some(b) = img.base(id) else { return };
        img.put_u32(b + 16, next);
        img.put_u32(b + 24, ranges.len() as u32);
        for (i, r) in ranges.iter().enumerate() {
            img.put_u32(b + 32 + 16 * i, r.0);
            img.put_u32(b + 36 + 16 * i, r.1);
            img.put(b + 40 + 16 * i, &r.2.to_le_bytes());
        }
    };
    match op {
        0 | 1 => {
            // The second block: the first block of a free range, which leaves the range.
            let i = c.below(ranges.len());
            let Some(&(second, count, freed)) = ranges.get(i).filter(|r| r.1 > 0) else { return };
            ranges[i] = (second.wrapping_add(1), count - 1, freed);
            if count == 1 {
                ranges.remove(i);
            }
            let cut = c.below(ranges.len() + 1);
            let next = img.u32(at + 16);
            img.bytes[at + 16..at + BS].fill(0);
            write(img, list, second, &ranges[..cut]);
            frame(img, second);
            write(img, second, next, &ranges[cut..]);
            for s in slots {
                let free = img.u32(s + 32).wrapping_sub(1);
                img.put_u32(s + 32, free);
            }
        }
        _ => {
            let k = 1 + c.below(4) as u32;
            let end = img.blocks();
            img.bytes.resize(img.bytes.len() + k as usize * BS, 0);
            for id in end..end + k {
                if let Some(b) = img.base(id) {
                    img.put(b + 4, &[7]);
                    img.put(b + 8, &base.txn.to_le_bytes());
                    img.seal(id);
                }
            }
            if n < (BS - 32) / 16 {
                ranges.push((end, k, base.txn));
                let next = img.u32(at + 16);
                write(img, list, next, &ranges);
            }
            for s in slots {
                let (count, free) = (img.u32(s + 20).wrapping_add(k), img.u32(s + 32).wrapping_add(k));
                img.put_u32(s + 20, count);
                img.put_u32(s + 32, free);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::db::Warning;

    /// Opens `bytes` and checks it: it must be sound.
    fn sound(bytes: Vec<u8>) -> Database {
        let db = Database::open_on(Arc::new(MemDevice::from_bytes(bytes))).expect("the forgery opens");
        let report = check(&db).expect("check runs");
        assert!(report.ok(), "{:?}", report.faults);
        db
    }

    #[test]
    fn the_base_file_has_every_structure_the_targets_forge() {
        let b = base();
        let img = &b.image;
        let (_, at, _) = img.newest().expect("a committed slot");
        let meta = img.u32(at + 12) as usize * BS;
        let reached = img.reachable();
        let nodes = reached.iter().filter(|r| r.1 == Kind::Node).count();
        assert!(nodes >= 2, "several node blocks: {nodes}");
        let key_leaves = b.key_blocks.iter().filter(|k| k.1 == 0).count();
        assert!(key_leaves >= 2, "the key entries with their names take {key_leaves} blocks");
        let entries: usize = img
            .node_blocks()
            .iter()
            .filter(|&&n| reached.iter().any(|r| r.0 == n))
            .flat_map(|&n| img.records(n))
            .map(|r| if let Record::Leaf(l) = r { l.objects } else { 0 })
            .sum();
        assert!(entries > img.u32(meta + 28) as usize, "an object is stored as parts");
        assert!(b.sites.len() >= 2 && b.catalogs[3].ranges.len() >= 4, "leaves hold bounds");
        let list = b.free_lists[0] as usize * BS;
        let freed: HashSet<u64> =
            (0..img.u32(list + 24) as usize).map(|i| img.u64(list + 40 + 16 * i)).collect();
        assert!(freed.len() >= 2, "free ranges freed by two commits: {freed:?}");
        assert!(b.catalogs.iter().all(|c| !c.fields.is_empty() && !c.ranges.is_empty()));
    }

    #[test]
    fn resealing_the_base_file_changes_nothing() {
        let mut img = base().image.clone();
        img.reseal();
        assert!(img == base().image);
    }

    #[test]
    fn a_harmless_edit_resealed_passes_every_checksum_and_unsealed_does_not() {
        let mut img = base().image.clone();
        let (_, at, _) = img.newest().expect("a committed slot");
        let meta = img.u32(at + 12) as usize * BS;
        // The root record's split overlap: any finite value >= 0 is sound.
        let root = img.u32(meta + 16) as usize * BS + img.u32(meta + 24) as usize;
        img.put(root + 12, &1.5f32.to_le_bytes());
        let unsealed = img.bytes.clone();
        img.reseal();
        sound(img.bytes);
        let db = Database::open_on(Arc::new(MemDevice::from_bytes(unsealed))).expect("opens");
        assert!(!check(&db).is_ok_and(|r| r.ok()), "the edit breaks the block's checksum");
    }

    #[test]
    fn a_bound_removed_leaves_a_sound_file_that_answers_as_brute_force() {
        let b = base();
        let mut img = b.image.clone();
        let site = &b.sites[0];
        let Some(Record::Leaf(l)) = img.records(site.block).get(site.record).copied() else {
            panic!("a leaf")
        };
        let kept: Vec<(u16, u8, Vec<u8>)> = img
            .bounds(&l)
            .iter()
            .skip(1)
            .map(|x| (x.target, x.level, img.bytes[x.blob..x.blob + x.len].to_vec()))
            .collect();
        assert!(rewrite_bounds(&mut img, site.block, site.record, &kept));
        img.reseal();
        assert!(img != b.image, "the leaf lost a bound");
        answers_match_brute_force(&sound(img.bytes), &[]);
    }

    #[test]
    fn the_free_list_split_into_a_chain_of_two_blocks_is_sound() {
        let b = base();
        let mut img = b.image.clone();
        // Range 0 gives the second block; the first block keeps one range.
        free_op(b, &mut img, 0, &mut Choices::new(&[0, 1]));
        img.reseal();
        let at = slot_offset(b.slot, 0);
        let first = Reference { field: at + 28, target: img.u32(at + 24), kind: Kind::FreeList };
        assert_eq!(img.postorder(&[first]).len(), 2, "the newest commit's list is a chain of two blocks");
        sound(img.bytes);
    }

    #[test]
    fn a_name_rewritten_in_its_key_entry_is_read_back() {
        let b = base();
        let mut img = b.image.clone();
        // Object 0's name (key 42) gets an X for its first byte.
        let stored42 = stored(&base_key(0));
        let entry = b
            .key_blocks
            .iter()
            .filter(|k| k.1 == 0)
            .flat_map(|&(block, _)| img.key_block_entries(block as usize * BS, false))
            .find(|e| e.key.is_some_and(|(k, len)| img.bytes[k..k + len] == stored42[..]))
            .expect("key 42 has an entry");
        let name = entry.name.expect("a leaf entry has a name");
        img.put(name + 2, b"X");
        img.reseal();
        let db = sound(img.bytes);
        let names = db.begin_read().expect("reads").names().expect("names");
        assert!(names[0].starts_with('X'), "{}", names[0]);
        assert_eq!(names.len(), b.keyed.len());
    }

    /// The stored form of `key`.
    fn stored(key: &Key) -> Vec<u8> {
        let mut out = Vec::new();
        key.encode(&mut out);
        out
    }

    #[test]
    fn the_base_files_key_index_has_a_branch_over_leaves_of_both_kinds_of_keys() {
        let b = base();
        let leaves = b.key_blocks.iter().filter(|k| k.1 == 0).count();
        let branches = b.key_blocks.iter().filter(|k| k.1 == 1).count();
        assert!(leaves >= 3 && branches == 1, "{:?}", b.key_blocks);
        let meta = b.image.meta().expect("a meta block");
        assert_eq!(b.image.u32(meta + 912), 2, "the index has two levels");
        let raw: Vec<_> = b.key_blocks.iter().flat_map(|&(k, l)| raw_entries(&b.image, k, l)).collect();
        assert!(raw.iter().any(|e| e.0.first() == Some(&0)) && raw.iter().any(|e| e.0.first() == Some(&1)));
        assert!(b.keyed.iter().all(|o| raw.iter().any(|e| e.0 == stored(&o.key))), "every key is in a leaf");
        // The oracle holds of the base file itself.
        lookups(&sound(b.image.bytes.clone()), true);
    }

    #[test]
    fn an_untouched_key_index_resealed_stays_sound() {
        let b = base();
        assert!(forged(Structure::Keys, &[]) == b.image.bytes);
        // A field edit that writes the value it read: entry_count of the first key block.
        let mut img = b.image.clone();
        let at = img.base(b.key_blocks[0].0).expect("a key block");
        let count = img.u16(at + 16);
        img.put(at + 16, &count.to_le_bytes());
        img.reseal();
        assert!(img == b.image);
        lookups(&sound(img.bytes), true);
    }

    /// The forged file for the Keys target's `input`; it must differ from the base file.
    fn forged_keys(input: &[u8]) -> Database {
        let bytes = forged(Structure::Keys, input);
        assert!(bytes != base().image.bytes, "{input:?} changes the file");
        Database::open_on(Arc::new(MemDevice::from_bytes(bytes))).expect("the forgery opens")
    }

    fn fails_check(input: &[u8]) {
        let db = forged_keys(input);
        assert!(!check(&db).expect("check runs").ok(), "{input:?} is a fault");
        lookups(&db, false);
    }

    #[test]
    fn a_key_swap_or_an_id_swap_fails_check() {
        // Op 9 (special 0), variant 0: entries 0 and 1 (one leaf) swap keys.
        fails_check(&[9, 0, 0, 1]);
        // Entries of two leaves swap keys: order holds in neither leaf.
        fails_check(&[9, 0, 0, 5]);
        // A leaf entry's key and a branch's separator.
        fails_check(&[9, 0, 1, 10]);
        // Variant 1: two entries swap object ids.
        fails_check(&[9, 1, 0, 4]);
    }

    #[test]
    fn an_entry_pointed_elsewhere_or_a_leafs_key_changed_fails_check() {
        // Op 10 (special 1), variant 0: entry 2 takes entry 3's leaf record and entry.
        fails_check(&[10, 0, 2, 0, 3]);
        // Entry 2 points at leaf record 4, entry 1 (one past its objects).
        fails_check(&[10, 0, 2, 1, 4, 1]);
        // Variant 1: leaf record 0's key becomes the 6th key of the pool.
        fails_check(&[10, 1, 0, 0, 5]);
    }

    #[test]
    fn a_key_blocks_used_bytes_cut_or_extended_fail_check() {
        // Op 11 (special 2): used bytes cut at entry 1 of block 0, count kept, then made to match.
        fails_check(&[11, 0, 0, 1, 0]);
        fails_check(&[11, 0, 0, 1, 1]);
        // Cut at a byte; extended by 79 bytes with one entry more.
        fails_check(&[11, 2, 1, 100, 0]);
        fails_check(&[11, 4, 0, 78, 1]);
    }

    #[test]
    fn keys_moved_between_two_objects_everywhere_make_a_sound_file_that_finds_them() {
        let b = base();
        let mut img = b.image.clone();
        // Objects 4 and 0 hold keys 7 and 42, adjacent in the first key leaf:
        // the entries keep their keys and swap the rest (id, place, box, payload).
        let (leaf, _) = b.key_blocks.iter().copied().find(|k| k.1 == 0).expect("a key leaf");
        let mut raw = raw_entries(&img, leaf, 0);
        let (i, j) = (0, 1);
        assert_eq!((raw[i].0.clone(), raw[j].0.clone()), (stored(&Key::Int(7)), stored(&Key::Int(42))));
        let rest = raw[i].1.clone();
        raw[i].1 = raw[j].1.clone();
        raw[j].1 = rest;
        assert!(write_key_block(&mut img, leaf, &raw));
        // And the leaves store each other's key.
        for (block, record, l) in leaf_records(b, &img.clone()) {
            let keys: Vec<Vec<u8>> =
                img.stored_keys(&l).iter().map(|&(k, n)| img.bytes[k..k + n].to_vec()).collect();
            let swapped: Vec<Vec<u8>> = keys
                .iter()
                .map(|k| match k {
                    k if *k == stored(&Key::Int(7)) => stored(&Key::Int(42)),
                    k if *k == stored(&Key::Int(42)) => stored(&Key::Int(7)),
                    k => k.clone(),
                })
                .collect();
            if swapped != keys {
                assert!(rewrite_keys(&mut img, block, record, &swapped));
            }
        }
        img.reseal();
        let db = sound(img.bytes);
        let r = db.begin_read().expect("reads");
        assert_eq!(r.get(&Key::Int(42)).expect("a lookup").expect("found").id, ObjectId(4));
        lookups(&db, true);
    }

    #[test]
    fn a_torn_slot_copy_loses_nothing() {
        let b = base();
        // Op 10: tear copy 0 of the newest slot at byte 5 after sealing.
        let torn = forged(Structure::Header, &[10, b.slot as u8, 0, 5, 1]);
        let db = sound(torn);
        assert_eq!(db.warnings(), &[Warning::DamagedSlotCopy { slot: b.slot as u8, copy: 0 }]);
        answers_match_brute_force(&db, &[]);
    }

    #[test]
    fn a_bound_with_a_cell_its_surface_does_not_touch_fails_check_or_answers_right() {
        let b = base();
        let site = &b.sites[0];
        let mut img = b.image.clone();
        let Some(Record::Leaf(l)) = img.records(site.block).get(site.record).copied() else {
            panic!("a leaf")
        };
        let mut entries: Vec<(u16, u8, Vec<u8>)> = img
            .bounds(&l)
            .iter()
            .map(|x| (x.target, x.level, img.bytes[x.blob..x.blob + x.len].to_vec()))
            .collect();
        // Object 0's finest bound (the one queries use) gains its first empty cell.
        let finest = entries.iter().rposition(|e| e.0 == 0).expect("a bound of entry 0");
        let mut v =
            crate::lod::decode(&entries[finest].2, &b.lattice, &site.boxes[0]).expect("the bound decodes");
        let empty = (0..v.grid().cells() as usize).find(|&i| !v.get(i)).expect("a cell the surface misses");
        v.set(empty);
        let d = v.grid().dims().map(|x| x as usize);
        let cell = [empty % d[0], empty / d[0] % d[1], empty / (d[0] * d[1])].map(|x| x as u32);
        let query = v.grid().cell_box(cell).grown(4.0 * v.grid().tolerance());
        entries[finest].2 = crate::lod::encode(&v);
        assert!(rewrite_bounds(&mut img, site.block, site.record, &entries));
        img.reseal();
        let db = Database::open_on(Arc::new(MemDevice::from_bytes(img.bytes))).expect("opens");
        let report = check(&db).expect("check runs");
        let r = db.begin_read().expect("reads");
        let got =
            query_region(&r, &Region::Box(query), &QueryOptions::default(), None).expect("answers").objects;
        let ids: Vec<ObjectId> = (0..r.info().expect("a tree").objects).map(ObjectId).collect();
        let meshes = object_meshes(&r, &ids).expect("meshes");
        let scene = Scene::new(meshes.into_iter().map(|m| Object::new("", m)).collect());
        let exact = brute_force_region(&scene, &Region::Box(query));
        assert!(
            !report.ok() || got == exact,
            "check passes, yet {query:?} answers {got:?}, brute force {exact:?}"
        );
    }
}
