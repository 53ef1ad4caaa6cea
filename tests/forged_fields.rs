//! Claim: a file whose every checksum matches but whose fields were forged
//! (hostile values, every checksum up the chain made to match again) never
//! makes the library panic, abort, or allocate by a count it has not bounded
//! by the bytes that hold it; and it never answers silently wrong: either
//! `check` reports the damage or every query answer, at every level, equals
//! the undamaged file's. Forged here: a voxel word of an inline bound, an
//! object id in a leaf entry or a geometry record (or both), a geometry
//! record's anchor and offsets, and every count field.

mod common;

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::{Arc, OnceLock};

use common::{box_mesh, forge};
use mktree::bulk::{BuildParams, LeafRule, Method};
use mktree::db::{CreateOptions, Database, Piece, check};
use mktree::geom::{Aabb, Point};
use mktree::lod::{LodParams, Voxels};
use mktree::query::{QueryOptions, Region, object_mesh, query_region};
use mktree::scene::{Mesh, Object, ObjectId, Scene};
use mktree::store::device::MemDevice;
use mktree::store::format::frame::BlockType;
use mktree::store::{BlockDevice, ReadStats};
use proptest::prelude::*;

/// The largest single allocation this test binary serves. Its files are a
/// few dozen KiB, so a larger request was sized by a forged count.
const LARGEST_ALLOCATION: usize = 64 << 20;

/// Serves what the system does, but refuses any request larger than
/// [`LARGEST_ALLOCATION`]: the process then aborts with "memory allocation
/// of N bytes failed" (issue 12's symptom) on any machine, not only on one
/// short of memory, and never takes gigabytes from the shared machine.
struct Capped;

// SAFETY: every call is forwarded unchanged to `System` or refused with a
// null pointer, which `GlobalAlloc` allows.
unsafe impl GlobalAlloc for Capped {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if layout.size() > LARGEST_ALLOCATION {
            std::ptr::null_mut()
        } else {
            unsafe { System.alloc(layout) }
        }
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        if layout.size() > LARGEST_ALLOCATION {
            std::ptr::null_mut()
        } else {
            unsafe { System.alloc_zeroed(layout) }
        }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if new_size > LARGEST_ALLOCATION {
            std::ptr::null_mut()
        } else {
            unsafe { System.realloc(ptr, layout, new_size) }
        }
    }
}

#[global_allocator]
static ALLOCATOR: Capped = Capped;

const BS: usize = 1024;
const M: u8 = 4;

/// A long zigzag strip of `n` triangles from `o`: its record is larger than
/// a geometry block, so it is stored as parts.
fn strip(o: [f64; 3], n: u32) -> Mesh {
    let p: Vec<Point> = (0..n + 2)
        .map(|i| {
            Point::new(o[0] + 7.0 * f64::from(i), o[1] + 3.0 * f64::from(i % 2), o[2] + 2.0 * f64::from(i))
        })
        .collect();
    Mesh::from_world(&p, (0..n).map(|i| [i, i + 1, i + 2]).collect()).unwrap()
}

/// Slanted triangles (whose bounds pay), boxes, and two strips stored as parts.
fn scene() -> Scene {
    let mut objects = common::slanted_triangles(18);
    for i in 0..4 {
        let lo = [500.0 + 70.0 * f64::from(i), 40.0 * f64::from(i), 20.0];
        objects.push(Object::new(format!("b{i}"), box_mesh(lo, [lo[0] + 50.0, lo[1] + 30.0, lo[2] + 45.0])));
    }
    objects.push(Object::new("s0", strip([10.0, 600.0, 0.0], 90)));
    objects.push(Object::new("s1", strip([300.0, 640.0, 50.0], 150)));
    Scene::new(objects)
}

/// The undamaged file: 1 KiB blocks, M = 4, every bound stored.
fn base() -> &'static [u8] {
    static FILE: OnceLock<Vec<u8>> = OnceLock::new();
    FILE.get_or_init(|| {
        let dev = Arc::new(MemDevice::new());
        let db = Database::create_on(
            dev.clone() as Arc<dyn BlockDevice>,
            CreateOptions { block_size: BS as u32, lod_levels: M },
        )
        .unwrap();
        let mut w = db.begin_write().unwrap();
        w.set_lod_params(LodParams { store_all: true, ..LodParams::default() });
        let params = BuildParams { method: Method::Moa, leaf: LeafRule::Objects(3), ..BuildParams::paper() };
        w.bulk_load(&scene(), &params, &|_| {}).unwrap();
        w.commit().unwrap();
        drop(db);
        dev.to_bytes()
    })
}

fn open(bytes: &[u8]) -> Result<Database, mktree::store::StorageError> {
    Database::open_on(Arc::new(MemDevice::from_bytes(bytes.to_vec())) as Arc<dyn BlockDevice>)
}

/// Box queries: the whole scene, a 4 x 4 x 2 grid over it, and each
/// object's box and the middle half of it.
fn queries() -> Vec<Aabb> {
    let s = scene();
    let b = s.aabb();
    let e = b.extent();
    let mut out = vec![b];
    let cell = [e.x / 4.0, e.y / 4.0, e.z / 2.0];
    for i in 0..32 {
        let c = [f64::from(i % 4), f64::from(i / 4 % 4), f64::from(i / 16)];
        let lo: [f64; 3] = std::array::from_fn(|a| b.min[a] + cell[a] * c[a]);
        out.push(Aabb::from_array([lo[0], lo[1], lo[2], lo[0] + cell[0], lo[1] + cell[1], lo[2] + cell[2]]));
    }
    for o in s.objects() {
        let a = o.mesh.aabb();
        let q = a.extent() / 4.0;
        out.extend([a, Aabb::new(a.min + q, a.max - q)]);
    }
    out
}

/// Every query's answer (sorted ids) at every level 1 ..= M, or the first error.
fn answers(db: &Database, qs: &[Aabb]) -> Result<Vec<Vec<u32>>, String> {
    let r = db.begin_read().map_err(|e| e.to_string())?;
    let mut out = Vec::new();
    for q in qs {
        for k in 1..=M {
            let opts = QueryOptions { lod: Some(k), ..Default::default() };
            let a = query_region(&r, &Region::Box(*q), &opts, None).map_err(|e| e.to_string())?;
            out.push(a.objects.iter().map(|o| o.0).collect());
        }
    }
    Ok(out)
}

/// The rule: the fuzz target's body runs on `forged` without a panic; then
/// either `check` reports damage (a fault, or an error) or every answer to
/// [`queries`] and `extra` equals the undamaged file's.
fn never_silently_wrong(forged: &[u8], extra: &[Aabb], what: &str) -> Result<(), TestCaseError> {
    mktree_fuzz::open_and_query(forged);
    let Ok(db) = open(forged) else { return Ok(()) };
    let clean = check(&db).is_ok_and(|r| r.ok());
    if !clean {
        return Ok(());
    }
    let qs = [queries(), extra.to_vec()].concat();
    let want = answers(&open(base()).unwrap(), &qs).unwrap();
    let got = answers(&db, &qs);
    prop_assert!(got.as_ref() == Ok(&want), "{what}: check is clean but the answers differ: {got:?}");
    Ok(())
}

/// The object `id`'s voxel bounds at level k (its parts' too) in leaf node
/// `node` of `bytes`, or nothing when they cannot be read.
fn voxels_of(bytes: &[u8], node: u32, k: u8, id: u32) -> Vec<Voxels> {
    let Ok(db) = open(bytes) else { return Vec::new() };
    let Ok(r) = db.begin_read() else { return Vec::new() };
    let Ok(level) = r.fetch_level(node, k, true, &mut ReadStats::default()) else { return Vec::new() };
    level
        .pieces
        .into_iter()
        .flat_map(|p| match p {
            Piece::ObjectVoxels(v) => v,
            _ => Vec::new(),
        })
        .filter(|(o, _)| o.0 == id)
        .map(|(_, v)| v)
        .collect()
}

/// The cells (grown by their tolerance) of `a` that `b` lacks.
fn cells_not_in(a: &[Voxels], b: &[Voxels]) -> Vec<Aabb> {
    let theirs: Vec<Aabb> = b.iter().flat_map(|v| v.cell_boxes()).collect();
    a.iter().flat_map(|v| v.cell_boxes()).filter(|c| !theirs.contains(c)).collect()
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(b[at..at + 4].try_into().unwrap())
}

fn image() -> forge::Image {
    forge::Image { bytes: base().to_vec(), bs: BS }
}

#[test]
fn the_undamaged_file_checks_clean_and_has_parts_and_bounds() {
    let db = open(base()).unwrap();
    let report = check(&db).unwrap();
    assert!(report.ok(), "{:?}", report.faults);
    let img = image();
    let leaves = img.leaves();
    assert!(leaves.iter().any(|&(_, r)| !img.leaf_bounds(r).is_empty()), "bounds are stored");
    let ids: Vec<u32> =
        leaves.iter().flat_map(|&(_, r)| img.leaf_entries(r)).map(|e| u32_at(&img.bytes, e)).collect();
    assert!(ids.windows(2).any(|w| w[0] == w[1]), "some object is stored as parts");
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, max_shrink_iters: 0, ..ProptestConfig::default() })]

    /// One bit of an inline bound's blob flipped (a cell set or cleared,
    /// or the head changed).
    #[test]
    fn a_forged_voxel_word_is_caught_or_changes_nothing(
        pick in any::<prop::sample::Index>(), byte in any::<prop::sample::Index>(), bit in 0u8..8,
    ) {
        let mut img = image();
        let bounds: Vec<_> = img
            .leaves()
            .into_iter()
            .flat_map(|(b, r)| img.leaf_bounds(r).into_iter().map(move |x| (b, r, x)))
            .collect();
        let (block, r, (target, k, blob, len)) = bounds[pick.index(bounds.len())];
        img.bytes[blob + byte.index(len)] ^= 1 << bit;
        img.reseal(block, BlockType::Node);
        // The cells the forgery set or cleared are the queries that would see it.
        let (node, id) = (u32_at(&img.bytes, r + 4), u32_at(&img.bytes, img.leaf_entries(r)[target]));
        let (was, is) = (voxels_of(base(), node, k, id), voxels_of(&img.bytes, node, k, id));
        let extra = [cells_not_in(&is, &was), cells_not_in(&was, &is)].concat();
        never_silently_wrong(&img.bytes, &extra, &format!("bound {target} at level {k} of leaf {node}"))?;
    }

    /// A leaf entry's object id, its geometry record's id, or both set to
    /// another id: a random one, a neighbour entry's (as if a part), or
    /// the id with a bit flipped.
    #[test]
    fn a_forged_object_id_is_caught_or_changes_nothing(
        pick in any::<prop::sample::Index>(),
        how in 0u8..4,
        other in any::<u32>(),
        (in_leaf, in_record) in prop_oneof![Just((true, false)), Just((false, true)), Just((true, true))],
    ) {
        let mut img = image();
        let entries: Vec<(usize, usize, usize)> = img
            .leaves()
            .into_iter()
            .flat_map(|(b, r)| img.leaf_entries(r).into_iter().map(move |e| (b, r, e)))
            .collect();
        let i = pick.index(entries.len());
        let (block, r, e) = entries[i];
        let objects = scene().objects().len() as u32;
        let id = u32_at(&img.bytes, e);
        let new = match how {
            0 => other % objects,
            1 => u32_at(&img.bytes, entries[i.saturating_sub(1)].2),
            2 => u32_at(&img.bytes, entries[(i + 1) % entries.len()].2),
            _ => id ^ 1 << (other % 5),
        };
        prop_assume!(new != id);
        if in_record {
            let (g, at) = img.record_of(r, e);
            img.bytes[at..at + 4].copy_from_slice(&new.to_le_bytes());
            img.reseal(g, BlockType::Geometry);
        }
        if in_leaf {
            img.bytes[e..e + 4].copy_from_slice(&new.to_le_bytes());
            img.reseal(block, BlockType::Node);
        }
        never_silently_wrong(&img.bytes, &[], &format!("object {id} as {new} (leaf {in_leaf}, record {in_record})"))?;
    }

    /// A geometry record's anchor moved on one axis: far out of range, just
    /// past the format's range, or by a little.
    #[test]
    fn a_forged_anchor_is_caught_or_changes_nothing(
        pick in any::<prop::sample::Index>(), axis in 0usize..3, how in 0usize..8,
    ) {
        let mut img = image();
        let entries: Vec<(usize, usize)> =
            img.leaves().into_iter().flat_map(|(_, r)| img.leaf_entries(r).into_iter().map(move |e| (r, e))).collect();
        let (r, e) = entries[pick.index(entries.len())];
        let (g, at) = img.record_of(r, e);
        let at = at + 16 + 8 * axis;
        let anchor = f64::from_le_bytes(img.bytes[at..at + 8].try_into().unwrap());
        let value = [1e300, -1e300, f64::MAX, 1e39, 2f64.powi(53) + 2.0, anchor + 1.0, anchor - 1e-6, -anchor][how];
        prop_assume!(value != anchor);
        img.bytes[at..at + 8].copy_from_slice(&value.to_le_bytes());
        img.reseal(g, BlockType::Geometry);
        never_silently_wrong(&img.bytes, &[], &format!("anchor {axis} {anchor} as {value}"))?;
    }
}

/// The golden-style store-all file with the first leaf's first object's
/// record changed by `forge` (given the record's bytes), resealed; and that
/// object's id.
fn forged_record(forge: impl FnOnce(&mut [u8])) -> (Vec<u8>, ObjectId) {
    let mut img = image();
    let (_, r) = img.leaves()[0];
    let e = img.leaf_entries(r)[0];
    let (g, at) = img.record_of(r, e);
    forge(&mut img.bytes[at..(g + 1) * BS]);
    img.reseal(g, BlockType::Geometry);
    (img.bytes, ObjectId(u32_at(base(), e)))
}

#[test]
fn a_far_anchor_or_vertex_is_corruption_where_the_record_is_read() {
    // Finite, but out of the format's range, 2^53 mm (geometry.md): the
    // anchor itself, or a vertex of an anchor just inside it.
    let edge = 2f64.powi(53);
    for (far, field) in [
        (1e300, "anchor"),
        (-1e300, "anchor"),
        (f64::MAX, "anchor"),
        (-edge - 2.0, "anchor"),
        (edge - 1.0, "offsets"),
    ] {
        let (f, id) = forged_record(|rec| rec[16..24].copy_from_slice(&far.to_le_bytes()));
        let db = open(&f).unwrap();
        let err = object_mesh(&db.begin_read().unwrap(), id).expect_err("a far anchor reads as corrupt");
        assert!(err.to_string().contains(field), "{far}: {err}");
        let report = check(&db).unwrap();
        assert!(report.faults.iter().any(|f| f.contains(field)), "{far}: {:?}", report.faults);
        mktree_fuzz::open_and_query(&f);
    }
}

#[test]
fn a_vertex_below_its_anchor_is_corruption_where_the_record_is_read() {
    // The anchor is the lower corner of the object's vertices: no offset is negative.
    let (f, id) = forged_record(|rec| rec[40..44].copy_from_slice(&(-0.5f32).to_le_bytes()));
    let db = open(&f).unwrap();
    let err = object_mesh(&db.begin_read().unwrap(), id).expect_err("a negative offset reads as corrupt");
    assert!(err.to_string().contains("offsets"), "{err}");
    mktree_fuzz::open_and_query(&f);
}

#[test]
fn a_bound_forged_to_no_cell_is_corruption_not_a_lost_object() {
    // An object's finest bound, a bitmap, with every cell cleared: the query,
    // a speck on the object's surface that holds no face slab of its box,
    // would be ruled out by the bound alone.
    let mut img = image();
    let (block, blob, len, id) = img
        .leaves()
        .into_iter()
        .flat_map(|(b, r)| {
            let bounds = img.leaf_bounds(r);
            let entries = img.leaf_entries(r);
            let finest: Vec<_> = bounds
                .iter()
                .filter(|x| bounds.iter().all(|y| y.0 != x.0 || y.1 <= x.1))
                .map(|&(t, _, blob, len)| (b, blob, len, u32_at(&img.bytes, entries[t])))
                .collect();
            finest
        })
        .find(|&(_, blob, _, id)| img.bytes[blob + 1] == 1 && (id as usize) < 18)
        .expect("a triangle whose finest bound is a bitmap");
    img.bytes[blob + 2..blob + len].fill(0);
    img.reseal(block, BlockType::Node);
    let p = scene().objects()[id as usize].mesh.vertex(1);
    let speck = Aabb::new(p, p).grown(1e-3);
    let db = open(&img.bytes).unwrap();
    let answer = db.begin_read().unwrap().query_box(&speck);
    assert!(
        answer.as_ref().is_err() || answer.as_ref().is_ok_and(|a| a.objects.contains(&ObjectId(id))),
        "object {id} lost silently: {answer:?}"
    );
    let undamaged = open(base()).unwrap().begin_read().unwrap().query_box(&speck).unwrap();
    assert!(undamaged.objects.contains(&ObjectId(id)));
}

/// A count field: (what, its block, the block's type, its absolute offset,
/// its width in bytes), after format-spec/meta.md, node.md and
/// geometry.md.
type CountField = (&'static str, usize, BlockType, usize, usize);

fn count_fields() -> Vec<CountField> {
    let img = image();
    let meta = img.meta();
    let m = meta * BS;
    let (leaf_block, leaf) = img.leaves()[0];
    let (g, record) = img.record_of(leaf, img.leaf_entries(leaf)[0]);
    let (_, _, blob, _) = img.leaf_bounds(leaf)[0];
    let node = img.blocks_of(BlockType::Node)[0];
    vec![
        ("meta object_count", meta, BlockType::Meta, m + 28, 4),
        ("meta node_count", meta, BlockType::Meta, m + 32, 4),
        ("meta leaf_count", meta, BlockType::Meta, m + 36, 4),
        ("meta node_blocks", meta, BlockType::Meta, m + 44, 4),
        ("node used_bytes", node, BlockType::Node, node * BS + 16, 4),
        ("node record_count", node, BlockType::Node, node * BS + 20, 2),
        ("leaf object_count", leaf_block, BlockType::Node, leaf + 2, 2),
        ("leaf span", leaf_block, BlockType::Node, leaf + 12, 2),
        ("leaf bounds_bytes", leaf_block, BlockType::Node, leaf + 16, 4),
        ("blob level", leaf_block, BlockType::Node, blob, 1),
        ("geometry vertex_count", g, BlockType::Geometry, record + 4, 4),
        ("geometry triangle_count", g, BlockType::Geometry, record + 8, 4),
    ]
}

/// The undamaged file with `writes` ((offset, value, width): `value`'s low
/// `width` bytes, little-endian) made in block `b` of type `t`, resealed.
fn forge_counts(b: usize, t: BlockType, writes: &[(usize, u32, usize)]) -> Vec<u8> {
    let mut f = image();
    for &(at, value, width) in writes {
        f.bytes[at..at + width].copy_from_slice(&value.to_le_bytes()[..width]);
    }
    f.reseal(b, t);
    f.bytes
}

#[test]
fn forged_counts_are_bounded_by_the_bytes_that_hold_them() {
    let huge = i32::MAX as u32;
    let mut cases: Vec<(String, Vec<u8>)> = count_fields()
        .into_iter()
        .flat_map(|(what, b, t, at, width)| {
            let max = if width == 4 { u32::MAX } else { (1 << (8 * width)) - 1 };
            [max, huge.min(max)].map(|v| (format!("{what} = {v}"), forge_counts(b, t, &[(at, v, width)])))
        })
        .collect();
    // Counts with the id bound raised to match (so that only the tree can
    // contradict them), which would let a traversal run long: object,
    // node, leaf counts.
    let m = image().meta();
    let at = m * BS;
    cases.push((
        "meta object_count and object_ids".into(),
        forge_counts(m, BlockType::Meta, &[(at + 28, huge, 4), (at + 144, huge, 4)]),
    ));
    cases.push((
        "meta object, node and leaf counts and object_ids".into(),
        forge_counts(
            m,
            BlockType::Meta,
            &[(at + 28, 1 << 30, 4), (at + 32, huge, 4), (at + 36, 1 << 30, 4), (at + 144, 1 << 30, 4)],
        ),
    ));
    for (what, f) in cases {
        mktree_fuzz::open_and_query(&f);
        let Ok(db) = open(&f) else { continue };
        let report = check(&db);
        assert!(!report.as_ref().is_ok_and(|r| r.ok()), "{what}: check is clean");
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, max_shrink_iters: 0, ..ProptestConfig::default() })]

    /// Any value in any count field.
    #[test]
    fn a_forged_count_is_caught_or_changes_nothing(pick in any::<prop::sample::Index>(), value in any::<u32>()) {
        let fields = count_fields();
        let (what, b, t, at, width) = fields[pick.index(fields.len())];
        let f = forge_counts(b, t, &[(at, value, width)]);
        never_silently_wrong(&f, &[], &format!("{what} = {value}"))?;
    }
}

#[test]
fn a_looping_child_link_under_a_forged_node_count_is_an_error_not_an_abort() {
    // The meta block claims 2^31 - 1 nodes: a bound from the meta block
    // alone would let the walk grow until memory runs out.
    let f = forge::golden_with_looping_root(Some(i32::MAX as u32));
    let err = open(&f).unwrap_err();
    assert!(err.is_corruption() && err.to_string().contains("node_count"), "{err}");
    mktree_fuzz::open_and_query(&f);
}
