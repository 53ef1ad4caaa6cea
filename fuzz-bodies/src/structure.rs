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
use std::sync::{Arc, Mutex};

use crate::base::{BS, Base, absent_keys, base, cheap_lods, cuboid, record};
use crate::edit::{Choices, copy_chunk, edit_field, edit_raw};

use crate::forgeries::special;
use mktree::bulk::{BuildParams, LeafRule};
use mktree::db::{Database, check, read_hierarchy};
use mktree::geom::{Aabb, Pose};
use mktree::lod::LodParams;
use mktree::query::{
    ClashOptions, CollideOptions, QueryOptions, RecordAt, Region, brute_force_region, clash, collide,
    node_records, object_meshes, query_region,
};
use mktree::scene::{Key, Object, ObjectId, Scene};
use mktree::store::BlockDevice;
use mktree::store::device::MemDevice;
use mktree::store::format::node::NodeView;

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
        let m = db.lod_levels();
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

/// Each leaf's objects' keys, as the leaves of `records` store them: id -> key.
fn leaf_keys(records: &[RecordAt]) -> HashMap<u32, Key> {
    let mut keys = HashMap::new();
    for (block, offset, _) in records {
        if let NodeView::Leaf(l) = record(block, *offset) {
            for i in 0..l.len() {
                if let (Some(o), Some(k)) = (l.object(i), l.key(i)) {
                    keys.entry(o.object_id).or_insert(k);
                }
            }
        }
    }
    keys
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
    let records = node_records(&r, root).unwrap_or_else(|e| panic!("a file check passes does not walk: {e}"));
    let stored = leaf_keys(&records);
    assert_eq!(stored.len(), base.keyed.len(), "a file check passes keys other objects than the base's");
    for (i, o) in base.keyed.iter().enumerate() {
        let id = ObjectId(i as u32);
        let key = stored.get(&id.0).unwrap_or_else(|| panic!("a file check passes stores no key for {id:?}"));
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
    for k in absent_keys(stored.values()) {
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
    let at = mktree::geom::Vector::new(c.below(n) as f64, c.below(n) as f64, c.below(n) as f64);
    let min = lo + step.component_mul(&at);
    let grow = f64::from(c.u8()) / 8.0;
    Some(Aabb::new(min, min + step).grown(grow))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::base::base_key;
    use crate::forge::{Kind, Record, Reference};
    use crate::forgeries::{
        free_op, leaf_records, raw_entries, rewrite_bounds, rewrite_keys, write_key_block,
    };
    use mktree::db::Warning;
    use mktree::store::format::header::slot_offset;

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
        let stored42 = base_key(0).stored();
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
        assert!(b.keyed.iter().all(|o| raw.iter().any(|e| e.0 == o.key.stored())), "every key is in a leaf");
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
        assert_eq!((raw[i].0.clone(), raw[j].0.clone()), (Key::Int(7).stored(), Key::Int(42).stored()));
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
                    k if *k == Key::Int(7).stored() => Key::Int(42).stored(),
                    k if *k == Key::Int(42).stored() => Key::Int(7).stored(),
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
            mktree::lod::decode(&entries[finest].2, &b.lattice, &site.boxes[0]).expect("the bound decodes");
        let d = v.grid().dims().map(|x| x as usize);
        let cell_at = |i: usize| [i % d[0], i / d[0] % d[1], i / (d[0] * d[1])].map(|x| x as u32);
        let empty = (0..v.grid().cells() as usize)
            .find(|&i| !v.is_set(cell_at(i)))
            .expect("a cell the surface misses");
        let cell = cell_at(empty);
        v.set_cell(cell);
        let query = v.grid().cell_box(cell).grown(4.0 * v.grid().tolerance());
        entries[finest].2 = mktree::lod::encode(&v);
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
