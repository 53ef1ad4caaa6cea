//! The structure-aware targets' own forgeries (`structure.rs`), beyond
//! field edits: records swapped, entries moved, key blocks cut, bounds
//! added, removed or flipped, free-list chains split, slot copies moved or
//! torn, each over the base file (`base.rs`, format-spec/).

use crate::base::{BS, Base};
use crate::edit::Choices;
use crate::forge::{Image, LeafAt, Record};
use crate::structure::Structure;
use mktree::lod::Voxels;
use mktree::store::format::header::{SLOT_LEN, slot_offset};

/// The structure's own forgeries (`op` in 0 ..= 2).
pub(crate) fn special(
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
pub(crate) fn raw_entries(img: &Image, block: u32, level: u32) -> RawEntries {
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
pub(crate) fn write_key_block(img: &mut Image, block: u32, entries: &RawEntries) -> bool {
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
pub(crate) fn rewrite_keys(img: &mut Image, block: u32, record: usize, keys: &[Vec<u8>]) -> bool {
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
pub(crate) fn leaf_records(base: &Base, img: &Image) -> Vec<(u32, usize, LeafAt)> {
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
        (0, 0) => swap_keys(base, img, c),
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
        _ => cut_key_block(base, img, how, c),
    }
}

/// Two key entries' keys swapped, in one key block or across two; nothing
/// written unless both blocks still fit.
fn swap_keys(base: &Base, img: &mut Image, c: &mut Choices) {
    let keyed: Vec<(usize, usize)> = (0..base.key_blocks.len())
        .flat_map(|b| {
            let raw = raw_entries(img, base.key_blocks[b].0, base.key_blocks[b].1);
            (0..raw.len()).filter(move |&i| !raw[i].0.is_empty()).map(move |i| (b, i))
        })
        .collect();
    let (Some(&x), Some(&y)) = (keyed.get(c.below(keyed.len())), keyed.get(c.below(keyed.len()))) else {
        return;
    };
    if x == y {
        return;
    }
    let blocks = if x.0 == y.0 { vec![x.0] } else { vec![x.0, y.0] };
    let mut raws: Vec<RawEntries> =
        blocks.iter().map(|&b| raw_entries(img, base.key_blocks[b].0, base.key_blocks[b].1)).collect();
    let (rx, ry) = (usize::from(x.0 != blocks[0]), usize::from(y.0 != blocks[0]));
    let kx = std::mem::take(&mut raws[rx][x.1].0);
    let ky = std::mem::replace(&mut raws[ry][y.1].0, kx);
    raws[rx][x.1].0 = ky;
    // Both blocks or neither: check each fits before writing.
    let mut copy = img.clone();
    if blocks.iter().zip(&raws).all(|(&b, raw)| write_key_block(&mut copy, base.key_blocks[b].0, raw)) {
        *img = copy;
    }
}

/// A key block's used bytes cut at an entry (`how`'s bits 1-2 = 0) or a
/// byte (1), or extended (else); its entry count kept or made to match.
fn cut_key_block(base: &Base, img: &mut Image, how: u8, c: &mut Choices) {
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
pub(crate) fn rewrite_bounds(
    img: &mut Image,
    block: u32,
    record: usize,
    entries: &[(u16, u8, Vec<u8>)],
) -> bool {
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

/// `v` with each cell of linear index in `flips` (x fastest, then y, then
/// z) flipped once per listing.
fn flipped(v: &Voxels, flips: &[usize]) -> Voxels {
    let [dx, dy, _] = v.grid().dims().map(|d| d as usize);
    let mut out = Voxels::empty(v.grid().clone());
    for i in 0..v.grid().cells() as usize {
        let cell = [i % dx, i / dx % dy, i / (dx * dy)].map(|x| x as u32);
        let odd = flips.iter().filter(|&&f| f == i).count() % 2 == 1;
        if v.is_set(cell) != odd {
            out.set_cell(cell);
        }
    }
    out
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
            let Ok(v) = mktree::lod::decode(blob, &base.lattice, outer) else { return };
            let cells = v.grid().cells() as usize;
            let flips: Vec<usize> = (0..1 + c.below(4)).map(|_| c.below(cells)).collect();
            *blob = mktree::lod::encode(&flipped(&v, &flips));
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
pub(crate) fn free_op(base: &Base, img: &mut Image, op: u8, c: &mut Choices) {
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
