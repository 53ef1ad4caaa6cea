//! The base file the structure-aware targets forge (`structure.rs`): a
//! valid file of every structure (format-spec/), built once, and the
//! catalogs of its fields by structure that the input chooses among.

use std::collections::HashSet;
use std::sync::{Arc, OnceLock};

use crate::edit::{Catalog, Width};
use crate::forge::{Image, Kind, LeafAt, Record, Reference};
use mktree::bulk::{BuildParams, LeafRule, Method};
use mktree::db::{CreateOptions, Database};
use mktree::geom::{Aabb, Point};
use mktree::lod::{Lattice, LodParams};
use mktree::query::{Region, brute_force_region, node_records, object_meshes};
use mktree::scene::{Key, Mesh, Object, ObjectId, Scene};
use mktree::store::Block;
use mktree::store::device::MemDevice;
use mktree::store::format::header::{SLOT_LEN, slot_offset};
use mktree::store::format::node::NodeView;
use mktree::store::format::quant::QuantBox;

/// Bytes per block of the base file.
pub(crate) const BS: usize = 1024;
/// Levels of detail of the base file: bounds at levels 2 and 3.
pub(crate) const M: u8 = 4;

/// A leaf record of the base file holding bounds: its block, its index
/// among the block's records, and each entry's box as the leaf decodes it.
#[derive(Debug, Clone)]
pub(crate) struct BoundSite {
    pub(crate) block: u32,
    pub(crate) record: usize,
    pub(crate) boxes: Vec<Aabb>,
}

/// The base file and what the forgers need to know of it.
pub(crate) struct Base {
    pub(crate) image: Image,
    pub(crate) catalogs: Vec<Catalog>,
    pub(crate) lattice: Lattice,
    pub(crate) sites: Vec<BoundSite>,
    /// The newest commit slot and its transaction.
    pub(crate) slot: usize,
    pub(crate) txn: u64,
    pub(crate) free_lists: Vec<u32>,
    /// The oracle's box queries, and each one's answer by brute force over
    /// the base objects (what a file of the base meshes must answer).
    pub(crate) boxes: Vec<Aabb>,
    pub(crate) exact: Vec<Vec<ObjectId>>,
    /// The base objects' boxes, which the input's probes split.
    pub(crate) objects: Vec<Aabb>,
    /// The newest tree's node blocks.
    pub(crate) nodes: Vec<u32>,
    /// The key index's blocks: (block, level above the leaves).
    pub(crate) key_blocks: Vec<(u32, u32)>,
    /// Each base object (by id) as a lookup by its key finds it.
    pub(crate) keyed: Vec<Keyed>,
    /// Keys near the base objects' and no object's ([`absent_keys`]).
    pub(crate) absent: Vec<Key>,
}

/// A base object as a lookup by key must find it.
#[derive(Debug, Clone)]
pub(crate) struct Keyed {
    pub(crate) key: Key,
    pub(crate) aabb: Aabb,
    pub(crate) mesh: Mesh,
}

fn mesh(vertices: &[[f64; 3]], triangles: Vec<[u32; 3]>) -> Mesh {
    let points: Vec<Point> = vertices.iter().map(|&v| v.into()).collect();
    Mesh::from_world(&points, triangles).unwrap_or_else(|e| panic!("the base scene's mesh: {e}"))
}

pub(crate) fn slanted(i: usize) -> Mesh {
    let o = [(i % 4) as f64 * 120.0, (i / 4) as f64 * 120.0, (i % 3) as f64 * 40.0];
    mesh(
        &[o, [o[0] + 100.0, o[1] + 10.0, o[2] + 60.0], [o[0] + 20.0, o[1] + 90.0, o[2] + 30.0]],
        vec![[0, 1, 2]],
    )
}

pub(crate) fn cuboid(lo: [f64; 3], hi: [f64; 3]) -> Mesh {
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
pub(crate) fn base_key(i: usize) -> Key {
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
pub(crate) fn cheap_lods(m: u8) -> LodParams {
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

/// Fields of the meta block (format-spec/meta.md) at `m`.
fn meta_fields(c: &mut Catalog, m: usize) {
    c.add(m, Width::U32, [16, 24, 28, 32, 36, 40, 44, 124, 144, 448, 452, 456, 460, 928, 932]);
    c.add(m, Width::U64, [48, 56, 64, 136, 736, 744, 920]);
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
        let key_blocks: Vec<(u32, u32)> = reached
            .iter()
            .filter_map(|(id, kind, _)| match kind {
                Kind::Key { level } => Some((*id, *level)),
                _ => None,
            })
            .collect();
        let meta = image.u32(at + 12) as usize * BS;
        let back = read_back(&image);
        let tree = TreeCatalogs::of(&image, &nodes, &geometry, &back.leaves, meta);
        let keys = keys_catalog(&image, &key_blocks, &nodes, meta);

        let boxes = oracle_boxes(&back.meshes);
        let scene = Scene::new(back.meshes.iter().map(|m| Object::new("", m.clone())).collect());
        let exact = boxes.iter().map(|b| brute_force_region(&scene, &Region::Box(*b))).collect();
        let absent = absent_keys(back.keyed.iter().map(|o| &o.key));
        Base {
            catalogs: vec![
                header_catalog(meta),
                tree.node,
                tree.geo,
                tree.lod,
                free_catalog(&free_lists, slot),
                keys,
            ],
            lattice: back.lattice,
            sites: tree.sites,
            slot,
            txn,
            free_lists,
            boxes,
            exact,
            objects: back.meshes.iter().map(|m| m.aabb()).collect(),
            nodes,
            key_blocks,
            keyed: back.keyed,
            absent,
            image,
        }
    }
}

/// What the engine reads of the base file.
struct ReadBack {
    /// Each leaf with its frame: (block, offset, frame).
    leaves: Vec<(u32, u32, Aabb)>,
    lattice: Lattice,
    /// Each object's mesh, by id.
    meshes: Vec<Mesh>,
    keyed: Vec<Keyed>,
}

/// Reads the base file through the engine: the leaves' frames from its own
/// walk, and each object as a lookup by its key finds it.
fn read_back(image: &Image) -> ReadBack {
    let db = Database::open_on(Arc::new(MemDevice::from_bytes(image.bytes.clone())))
        .unwrap_or_else(|e| panic!("the base file opens: {e}"));
    let r = db.begin_read().unwrap_or_else(|e| panic!("the base file reads: {e}"));
    let root = r.root().unwrap_or_else(|| panic!("the base file has a tree"));
    let records = node_records(&r, root).unwrap_or_else(|e| panic!("the base file walks: {e}"));
    let leaves = records
        .iter()
        .filter(|(block, offset, _)| matches!(record(block, *offset), NodeView::Leaf(_)))
        .map(|(block, offset, frame)| (block.id(), *offset, *frame))
        .collect();
    let lattice = r.lattice().unwrap_or_else(|| panic!("the base file has a lattice"));
    let names = r.names().unwrap_or_else(|e| panic!("the base file's names: {e}"));
    assert_eq!(names.len(), base_scene().objects().len(), "the base file's names");
    let ids: Vec<ObjectId> = (0..names.len() as u32).map(ObjectId).collect();
    let meshes = object_meshes(&r, &ids).unwrap_or_else(|e| panic!("the base file's meshes: {e}"));
    let keyed = meshes
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
    ReadBack { leaves, lattice, meshes, keyed }
}

/// Record `offset` of `block`, one the engine's walk met: it validated the
/// block, so the record reads.
pub(crate) fn record(block: &Block, offset: u32) -> NodeView<'_> {
    NodeView::at(block.bytes(), offset)
        .unwrap_or_else(|e| panic!("record {offset} of walked block {} does not read: {e}", block.id()))
}

/// Fields of block 0 (the fixed header, both copies of both slots) and of
/// the meta block at `meta`.
fn header_catalog(meta: usize) -> Catalog {
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
    header
}

/// Payload bytes of a block, after its frame.
const PAYLOAD: usize = BS - 16;

/// The fields of the tree's node blocks by structure (format-spec/node.md,
/// geometry.md, lod.md), and the leaf records that hold bounds.
#[derive(Default)]
struct TreeCatalogs {
    node: Catalog,
    geo: Catalog,
    lod: Catalog,
    sites: Vec<BoundSite>,
}

impl TreeCatalogs {
    /// The catalogs of node blocks `nodes` (`leaves` holds each leaf's
    /// frame), geometry blocks `geometry` and the meta block at `meta`.
    fn of(image: &Image, nodes: &[u32], geometry: &[u32], leaves: &[(u32, u32, Aabb)], meta: usize) -> Self {
        let mut t = TreeCatalogs::default();
        for &b in nodes {
            let base = b as usize * BS;
            t.node.add(base, Width::U32, [16]);
            t.node.add(base, Width::U16, [20]);
            t.node.add(base, Width::U8, [22, 23]);
            t.node.ranges.push((base + 16, BS - 16));
            for (index, rec) in image.records(b).into_iter().enumerate() {
                t.node.anchors.push(rec.at());
                match rec {
                    Record::Internal { at } => {
                        t.node.add(at, Width::U8, [0, 1, 2, 3]);
                        t.node.add(at, Width::U32, [4, 8]);
                        t.node.add(at, Width::F32, [12, 16]);
                        for c in 0..2 {
                            let e = at + 20 + 32 * c;
                            t.node.anchors.push(e);
                            t.node.add(e, Width::U16, (0..6).map(|i| 2 * i));
                            t.node.add(e, Width::U32, [12, 20, 24, 28]);
                        }
                    }
                    Record::Leaf(l) => {
                        t.leaf(image, &l);
                        t.bounds(image, b, index, &l, leaves);
                    }
                }
            }
        }
        for &g in geometry {
            t.geo.ranges.push((g as usize * BS + 16, PAYLOAD));
        }
        t.lod.add(meta, Width::F64, (0..16).map(|k| 160 + 16 * k).chain([416, 424, 432, 440]));
        t.lod.add(meta, Width::U8, 464..480);
        t.lod.add(meta, Width::U32, [452, 456]);
        t.lod.add(0, Width::U8, [16]);
        t
    }

    /// A leaf record's node fields, and its span and objects' records in
    /// the span as geometry fields.
    fn leaf(&mut self, image: &Image, l: &LeafAt) {
        let (node, geo) = (&mut self.node, &mut self.geo);
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
            let r = (first + s / PAYLOAD) * BS + 16 + s % PAYLOAD;
            let (v, t) = (image.u32(r + 4) as usize, image.u32(r + 8) as usize);
            if s % PAYLOAD + 40 + 12 * (v + t) <= PAYLOAD {
                geo.anchors.extend([r, r + 16]);
                geo.add(r, Width::U32, [0, 4, 8, 12]);
                geo.add(r, Width::F64, [16, 24, 32]);
                geo.add(r + 40, Width::F32, (0..3 * v).map(|j| 4 * j));
                geo.add(r + 40 + 12 * v, Width::U32, (0..3 * t).map(|j| 4 * j));
                geo.anchors.extend((0..v).map(|j| r + 40 + 12 * j));
                geo.anchors.extend((0..t).map(|j| r + 40 + 12 * (v + j)));
            }
        }
    }

    /// The inline bounds of leaf record `index` of block `b`, as LOD
    /// fields; a leaf holding bounds becomes a [`BoundSite`].
    fn bounds(&mut self, image: &Image, b: u32, index: usize, l: &LeafAt, leaves: &[(u32, u32, Aabb)]) {
        let bounds = image.bounds(l);
        if !bounds.is_empty() {
            let frame = leaves.iter().find(|x| x.0 == b && x.0 as usize * BS + x.1 as usize == l.at);
            let boxes = (0..l.objects)
                .map(|i| {
                    let e = l.objects_at + 20 * i + 4;
                    let q = std::array::from_fn(|j| image.u16(e + 2 * j));
                    frame.and_then(|f| QuantBox::decode(&f.2, q)).map_or(Aabb::EMPTY, |q| q.outer)
                })
                .collect();
            self.sites.push(BoundSite { block: b, record: index, boxes });
            for i in 0..l.objects {
                self.lod.add(l.objects_at + 20 * i, Width::U16, (0..6).map(|j| 4 + 2 * j));
            }
        }
        for bound in bounds {
            self.lod.anchors.extend([bound.head, bound.blob]);
            self.lod.add(bound.head, Width::U16, [0, 2]);
            self.lod.add(bound.blob, Width::U8, 0..bound.len);
            self.lod.ranges.push((bound.blob, bound.len));
        }
    }
}

/// Fields of the free list blocks `free_lists` (format-spec/freelist.md)
/// and the free list's fields of both copies of commit slot `slot`.
fn free_catalog(free_lists: &[u32], slot: usize) -> Catalog {
    let mut free = Catalog::default();
    for &b in free_lists {
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
    free
}

/// Fields of the key index (format-spec/keys.md): the meta block's root,
/// each block's head and entries (`key_blocks`: block, level); and the
/// keys areas of the leaf records of node blocks `nodes`.
fn keys_catalog(image: &Image, key_blocks: &[(u32, u32)], nodes: &[u32], meta: usize) -> Catalog {
    let mut keys_c = Catalog::default();
    keys_c.add(meta, Width::U32, [904, 908, 912, 916]);
    keys_c.ranges.push((meta + 904, 16));
    for &(b, level) in key_blocks {
        let at = b as usize * BS;
        keys_c.add(at, Width::U16, [16, 18]);
        keys_c.add(at, Width::U8, [18, 19]);
        keys_c.add(at, Width::U32, [20]);
        keys_c.ranges.push((at + 16, BS - 16));
        for e in image.key_block_entries(at, level > 0) {
            keys_c.anchors.push(e.at);
            if let Some((k, len)) = e.key {
                key_fields(&mut keys_c, image, k, len);
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
    for &b in nodes {
        for rec in image.records(b) {
            if let Record::Leaf(l) = rec {
                keys_c.add(l.at, Width::U16, [14]);
                if l.keys_len > 0 {
                    keys_c.ranges.push((l.keys_at, l.keys_len));
                }
                for (k, len) in image.stored_keys(&l) {
                    key_fields(&mut keys_c, image, k, len);
                }
            }
        }
    }
    keys_c
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
        let half = mktree::geom::Vector::repeat(b.extent().max() * 0.2);
        out.push(Aabb::new(b.center() - half, b.center() + half));
    }
    out
}

pub(crate) fn base() -> &'static Base {
    static BASE: OnceLock<Base> = OnceLock::new();
    BASE.get_or_init(Base::build)
}

/// Keys near `keys` and at the ends of the order, none of them in `keys`:
/// an integer one off, a byte string cut, extended or with its last byte
/// one up, the least and greatest keys.
pub(crate) fn absent_keys<'a>(keys: impl IntoIterator<Item = &'a Key>) -> Vec<Key> {
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
