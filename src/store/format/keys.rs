//! The key index (format-spec/keys.md): a B+tree from each object's key to
//! its id, its exact box, its name and payload, and the path from the root
//! to the leaf holding it. Entries name no block of the MKtree, so a change
//! that moves node blocks leaves the index alone. Written bottom-up by a
//! bulk load and path by path by a change commit; a block is validated
//! whole when read.

use super::all_zero;
use super::frame::FRAME_LEN;
use crate::geom::Aabb;
use crate::scene::{Key, KeyRef, Object};
use crate::store::StorageError;

/// Bytes of a key block's head after the frame: entry count, reserved, used bytes.
const HEAD_LEN: usize = 8;
/// Entries start here.
pub const ENTRIES_START: usize = FRAME_LEN + HEAD_LEN;
/// Bytes of an entry after its key, payload and name: id, path bits, path
/// length, reserved, box.
const FIXED_LEN: usize = 4 + 8 + 1 + 3 + 48;
/// The longest name an entry holds, bytes.
pub const MAX_NAME: usize = u16::MAX as usize;
/// Bytes of a branch's child reference: block and checksum.
const CHILD_LEN: usize = 8;
/// The deepest key index a file may claim (a bulk load's branches have at
/// least two children, so 2^64 keys need fewer levels; a change commit adds
/// a level only when the top one holds two blocks).
pub const MAX_HEIGHT: u32 = 64;

/// The path from the root to the leaf holding an object: bit `i` of `bits`
/// is the child taken at depth `i` (0 the first child), for `len` levels.
/// A path deeper than 64 levels keeps its first 64; a lookup goes on below
/// by the object's box.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
pub struct TreePath {
    /// The steps, bit `i` the child taken at depth `i`.
    pub bits: u64,
    /// The number of steps, 0 ..= [`TreePath::MAX_LEN`] (0: the root).
    pub len: u8,
}

impl TreePath {
    /// The deepest path held.
    pub const MAX_LEN: u8 = 64;

    /// The child taken at depth `depth`, if the path goes that deep.
    pub fn step(&self, depth: usize) -> Option<usize> {
        (depth < usize::from(self.len)).then(|| (self.bits >> depth) as usize & 1)
    }

    /// Whether this path leads to `other`'s node or to an ancestor of it.
    pub fn is_prefix_of(&self, other: &TreePath) -> bool {
        let mask = if self.len >= 64 { u64::MAX } else { (1u64 << self.len) - 1 };
        self.len <= other.len && (other.bits & mask) == self.bits
    }

    /// The first `len` steps of this path (all of it when shorter).
    pub fn truncated(&self, len: usize) -> TreePath {
        if len >= usize::from(self.len) {
            return *self;
        }
        TreePath { bits: self.bits & ((1u64 << len) - 1), len: len as u8 }
    }

    /// This path, one level deeper through child `child`; a path already
    /// at its longest stays as it is.
    pub fn child(&self, child: usize) -> TreePath {
        if self.len >= Self::MAX_LEN {
            return *self;
        }
        TreePath { bits: self.bits | ((child as u64 & 1) << self.len), len: self.len + 1 }
    }
}

/// One key's entry.
#[derive(Debug, Clone, PartialEq)]
pub struct KeyEntry {
    /// The application's key.
    pub key: Key,
    /// The application's opaque bytes kept with the key (at most
    /// [`Object::MAX_PAYLOAD`](crate::scene::Object::MAX_PAYLOAD)).
    pub payload: Vec<u8>,
    /// The object's name (empty for none).
    pub name: String,
    /// The object's id.
    pub object_id: u32,
    /// The path to the leaf holding the object.
    pub path: TreePath,
    /// The object's exact box.
    pub aabb: Aabb,
}

impl KeyEntry {
    fn encode(&self, out: &mut Vec<u8>) {
        self.key.encode(out);
        out.extend_from_slice(&(self.payload.len() as u16).to_le_bytes());
        out.extend_from_slice(&self.payload);
        out.extend_from_slice(&(self.name.len() as u16).to_le_bytes());
        out.extend_from_slice(self.name.as_bytes());
        out.extend_from_slice(&self.object_id.to_le_bytes());
        out.extend_from_slice(&self.path.bits.to_le_bytes());
        out.extend_from_slice(&[self.path.len, 0, 0, 0]);
        for x in self.aabb.to_array() {
            out.extend_from_slice(&x.to_le_bytes());
        }
    }
}

/// A branch's reference to a child block, with the least key below it
/// (none for the first child).
#[derive(Debug, Clone, PartialEq)]
pub struct ChildRef {
    /// The least key in the child's subtree (not stored for the first child).
    pub first_key: Key,
    /// The child's key block.
    pub block: u32,
    /// The checksum that block must carry.
    pub checksum: u32,
}

/// A key block, decoded and validated.
#[derive(Debug, Clone, PartialEq)]
pub enum KeyBlock {
    /// A leaf block: entries in key order.
    Leaf(Vec<KeyEntry>),
    /// Children in key order; child i >= 1 holds keys from its `first_key`.
    Branch(Vec<ChildRef>),
}

/// Bytes of entries a key block holds.
pub fn capacity(block_size: u32) -> usize {
    block_size as usize - ENTRIES_START
}

/// Bytes of a branch's reference to a child whose least key is `key`.
pub fn child_len(key: &Key, first: bool) -> usize {
    CHILD_LEN + if first { 0 } else { key.encoded_len() }
}

/// Encodes a leaf's entries (in key order) into `block`'s payload.
pub fn encode_leaf(entries: &[KeyEntry], block: &mut [u8]) -> Result<(), String> {
    let mut bytes = Vec::with_capacity(capacity(block.len() as u32));
    for e in entries {
        if e.payload.len() > Object::MAX_PAYLOAD {
            return Err(format!("a payload of {} bytes (at most {})", e.payload.len(), Object::MAX_PAYLOAD));
        }
        if e.name.len() > MAX_NAME {
            return Err(format!("a name of {} bytes (at most {MAX_NAME})", e.name.len()));
        }
        e.encode(&mut bytes);
    }
    put(block, entries.len(), &bytes)
}

/// Encodes a branch's children (in key order, at least one) into `block`'s payload.
pub fn encode_branch(children: &[ChildRef], block: &mut [u8]) -> Result<(), String> {
    let mut bytes = Vec::with_capacity(capacity(block.len() as u32));
    for (i, c) in children.iter().enumerate() {
        if i > 0 {
            c.first_key.encode(&mut bytes);
        }
        bytes.extend_from_slice(&c.block.to_le_bytes());
        bytes.extend_from_slice(&c.checksum.to_le_bytes());
    }
    put(block, children.len(), &bytes)
}

fn put(block: &mut [u8], count: usize, bytes: &[u8]) -> Result<(), String> {
    let end = ENTRIES_START + bytes.len();
    if end > block.len() || count == 0 || count > usize::from(u16::MAX) {
        return Err(format!("{count} entries in {} bytes do not fit a key block", bytes.len()));
    }
    block[FRAME_LEN..FRAME_LEN + 2].copy_from_slice(&(count as u16).to_le_bytes());
    block[FRAME_LEN + 2..FRAME_LEN + 4].fill(0);
    block[FRAME_LEN + 4..ENTRIES_START].copy_from_slice(&(bytes.len() as u32).to_le_bytes());
    block[ENTRIES_START..end].copy_from_slice(bytes);
    block[end..].fill(0);
    Ok(())
}

/// Reads `n` bytes from the front of `at`.
fn take<'a>(at: &mut &'a [u8], n: usize) -> Option<&'a [u8]> {
    let (x, rest) = at.split_at_checked(n)?;
    *at = rest;
    Some(x)
}

fn u32_of(at: &mut &[u8]) -> Option<u32> {
    take(at, 4).and_then(|b| b.try_into().ok()).map(u32::from_le_bytes)
}

fn u64_of(at: &mut &[u8]) -> Option<u64> {
    take(at, 8).and_then(|b| b.try_into().ok()).map(u64::from_le_bytes)
}

fn u16_of(at: &mut &[u8]) -> Option<u16> {
    take(at, 2).and_then(|b| b.try_into().ok()).map(u16::from_le_bytes)
}

fn key_of<'a>(at: &mut &'a [u8]) -> Option<KeyRef<'a>> {
    let (k, n) = KeyRef::decode(at)?;
    *at = &at[n..];
    Some(k)
}

/// A key leaf's entry in place.
struct EntryRef<'a> {
    key: KeyRef<'a>,
    payload: &'a [u8],
    name: &'a str,
    object_id: u32,
    path: TreePath,
    aabb: Aabb,
}

impl EntryRef<'_> {
    fn to_entry(&self) -> KeyEntry {
        KeyEntry {
            key: self.key.to_key(),
            payload: self.payload.to_vec(),
            name: self.name.to_string(),
            object_id: self.object_id,
            path: self.path,
            aabb: self.aabb,
        }
    }
}

/// The entries area of key block `id` and its entry count, its head, zero
/// tail and count bounded by its bytes checked.
fn entries_area(id: u32, block: &[u8]) -> Result<(&[u8], usize), StorageError> {
    let bad = |field, detail: String| StorageError::corrupt(id, field, detail);
    let head = block.get(FRAME_LEN..ENTRIES_START).ok_or_else(|| bad("key_block", "too small".into()))?;
    let count = usize::from(u16::from_le_bytes([head[0], head[1]]));
    let used = u32::from_le_bytes([head[4], head[5], head[6], head[7]]) as usize;
    if head[2..4] != [0, 0] {
        return Err(bad("reserved", "reserved bytes are not zero".into()));
    }
    let area = block
        .get(ENTRIES_START..ENTRIES_START.saturating_add(used))
        .ok_or_else(|| bad("used_bytes", format!("{used} bytes overrun the block")))?;
    if !all_zero(&block[ENTRIES_START + used..]) {
        return Err(bad("used_bytes", "bytes past the entries are not zero".into()));
    }
    if count == 0 {
        return Err(bad("entry_count", format!("{count} entries")));
    }
    // Every entry takes at least 9 bytes, so `count` entries are bounded by
    // the block before anything is allocated for them.
    if count > area.len() / 9 + 1 {
        return Err(bad("entry_count", format!("{count} entries in {used} bytes")));
    }
    Ok((area, count))
}

/// Parses the key leaf entry at the front of `at` (of block `id`),
/// checking its fields but not its order among the others.
fn entry_of<'a>(id: u32, at: &mut &'a [u8]) -> Result<EntryRef<'a>, StorageError> {
    let bad = |field, detail: String| StorageError::corrupt(id, field, detail);
    let short = || bad("entries", "an entry overruns the used bytes".into());
    let key = key_of(at).ok_or_else(short)?;
    let n = usize::from(u16_of(at).ok_or_else(short)?);
    if n > Object::MAX_PAYLOAD {
        return Err(bad("payload", format!("{n} bytes (at most {})", Object::MAX_PAYLOAD)));
    }
    let payload = take(at, n).ok_or_else(short)?;
    let n = usize::from(u16_of(at).ok_or_else(short)?);
    let name = std::str::from_utf8(take(at, n).ok_or_else(short)?)
        .map_err(|_| bad("name", "a name is not UTF-8".into()))?;
    let object_id = u32_of(at).ok_or_else(short)?;
    let bits = u64_of(at).ok_or_else(short)?;
    let tail = take(at, 4).ok_or_else(short)?;
    let len = tail[0];
    if len > TreePath::MAX_LEN || (len < 64 && bits >> len != 0) {
        return Err(bad("path", format!("{len} levels with bits {bits:#x}")));
    }
    if tail[1..] != [0, 0, 0] {
        return Err(bad("reserved", "an entry's reserved bytes are not zero".into()));
    }
    let mut b = [0f64; 6];
    for x in &mut b {
        *x = f64::from_le_bytes(take(at, 8).ok_or_else(short)?.try_into().map_err(|_| short())?);
    }
    if b.iter().any(|x| !x.is_finite()) || (0..3).any(|i| b[i] > b[i + 3]) {
        return Err(bad("box", format!("{b:?} is not a box")));
    }
    Ok(EntryRef { key, payload, name, object_id, path: TreePath { bits, len }, aabb: Aabb::from_array(b) })
}

/// A branch's child reference at the front of `at`: its least key (none
/// for the first child), block and checksum.
fn child_of<'a>(id: u32, at: &mut &'a [u8], first: bool) -> Result<(Option<KeyRef<'a>>, u32, u32), StorageError> {
    let short = || StorageError::corrupt(id, "entries", "an entry overruns the used bytes");
    let key = if first { None } else { Some(key_of(at).ok_or_else(short)?) };
    let block = u32_of(at).ok_or_else(short)?;
    let checksum = u32_of(at).ok_or_else(short)?;
    Ok((key, block, checksum))
}

/// Validates key block `id` whole (a leaf when `leaf`, else a branch):
/// entries fill its used bytes exactly, keys strictly increase, and each
/// entry's fields are in range. Returns where each entry starts, so that
/// lookups search it in place afterwards ([`search_leaf`], [`search_branch`]).
pub fn validate(id: u32, block: &[u8], leaf: bool) -> Result<Vec<u32>, StorageError> {
    let bad = |field, detail: String| StorageError::corrupt(id, field, detail);
    let (area, count) = entries_area(id, block)?;
    let mut at = area;
    let mut offsets = Vec::with_capacity(count);
    let mut last: Option<KeyRef> = None;
    for i in 0..count {
        offsets.push((ENTRIES_START + area.len() - at.len()) as u32);
        let key = if leaf { Some(entry_of(id, &mut at)?.key) } else { child_of(id, &mut at, i == 0)?.0 };
        if let Some(k) = key {
            if last.is_some_and(|l| l.cmp(&k).is_ge()) {
                return Err(bad("key", format!("key {} does not follow the one before", k.to_key())));
            }
            last = Some(k);
        }
    }
    if !at.is_empty() {
        return Err(bad("used_bytes", format!("{} bytes after the last entry", at.len())));
    }
    Ok(offsets)
}

/// The end of the entries of key block `id`, from its head alone.
fn entries_end(id: u32, block: &[u8]) -> Result<usize, StorageError> {
    let used = block
        .get(FRAME_LEN + 4..ENTRIES_START)
        .and_then(|b| b.try_into().ok())
        .map(u32::from_le_bytes)
        .ok_or_else(|| StorageError::corrupt(id, "key_block", "too small"))?;
    Ok(ENTRIES_START.saturating_add(used as usize))
}

/// The bytes from `offset` to the end of the entries of a key block that
/// [`validate`] checked whole (so the head alone bounds them here).
fn from_offset(id: u32, block: &[u8], offset: u32) -> Result<&[u8], StorageError> {
    let end = entries_end(id, block)?;
    block
        .get(offset as usize..end)
        .filter(|_| offset as usize >= ENTRIES_START)
        .ok_or_else(|| StorageError::corrupt(id, "entries", "an entry offset past the used bytes"))
}

/// The entry of `key` in key leaf `id`, validated by [`validate`] into
/// `offsets`: a binary search in place, copying out that entry only.
pub fn search_leaf(id: u32, block: &[u8], offsets: &[u32], key: &Key) -> Result<Option<KeyEntry>, StorageError> {
    let want = key.as_ref();
    let (mut lo, mut hi) = (0, offsets.len());
    while lo < hi {
        let mid = (lo + hi) / 2;
        let mut at = from_offset(id, block, offsets[mid])?;
        let e = entry_of(id, &mut at)?;
        match e.key.cmp(&want) {
            std::cmp::Ordering::Less => lo = mid + 1,
            std::cmp::Ordering::Greater => hi = mid,
            std::cmp::Ordering::Equal => return Ok(Some(e.to_entry())),
        }
    }
    Ok(None)
}

/// The child (block, checksum) of key branch `id`, validated by
/// [`validate`] into `offsets`, whose key range holds `key`.
pub fn search_branch(id: u32, block: &[u8], offsets: &[u32], key: &Key) -> Result<(u32, u32), StorageError> {
    if offsets.is_empty() {
        return Err(StorageError::corrupt(id, "children", "a branch of no children"));
    }
    let want = key.as_ref();
    // Children 1.. hold keys from their least key on; the first holds the rest.
    let (mut lo, mut hi) = (1, offsets.len());
    while lo < hi {
        let mid = (lo + hi) / 2;
        let mut at = from_offset(id, block, offsets[mid])?;
        match child_of(id, &mut at, false)?.0 {
            Some(k) if k.cmp(&want).is_le() => lo = mid + 1,
            _ => hi = mid,
        }
    }
    let child = lo - 1;
    let mut at = from_offset(id, block, offsets[child])?;
    let (_, block, checksum) = child_of(id, &mut at, child == 0)?;
    Ok((block, checksum))
}

/// The entries of key leaf `id` (validated into `offsets`) as they lie in
/// the block, each with its key: a change commit copies the ones it does
/// not change into the new leaf as they are.
pub(crate) fn leaf_entries<'a>(
    id: u32,
    block: &'a [u8],
    offsets: &[u32],
) -> Result<Vec<(KeyRef<'a>, &'a [u8])>, StorageError> {
    let end = entries_end(id, block)?;
    let mut out = Vec::with_capacity(offsets.len());
    for (i, &o) in offsets.iter().enumerate() {
        let next = offsets.get(i + 1).map_or(end, |&n| n as usize);
        let bytes = block
            .get(o as usize..next)
            .ok_or_else(|| StorageError::corrupt(id, "entries", "entry offsets out of order"))?;
        let (key, _) = KeyRef::decode(bytes).ok_or_else(|| StorageError::corrupt(id, "key", "a key overruns"))?;
        out.push((key, bytes));
    }
    Ok(out)
}

/// Writes a leaf of `entries`, each already encoded (in key order), into
/// `block`'s payload.
pub fn encode_leaf_bytes(entries: &[&[u8]], block: &mut [u8]) -> Result<(), String> {
    let mut bytes = Vec::with_capacity(capacity(block.len() as u32));
    for e in entries {
        bytes.extend_from_slice(e);
    }
    put(block, entries.len(), &bytes)
}

/// `entry` encoded as a leaf holds it.
pub fn encode_entry(entry: &KeyEntry) -> Result<Vec<u8>, String> {
    if entry.payload.len() > Object::MAX_PAYLOAD {
        return Err(format!("a payload of {} bytes (at most {})", entry.payload.len(), Object::MAX_PAYLOAD));
    }
    if entry.name.len() > MAX_NAME {
        return Err(format!("a name of {} bytes (at most {MAX_NAME})", entry.name.len()));
    }
    let mut out = Vec::new();
    entry.encode(&mut out);
    Ok(out)
}

/// Decodes and validates key block `id` (its checksum verified): a leaf
/// when `leaf`, else a branch. Entries fill `used` bytes exactly, keys
/// strictly increase, boxes are boxes, the rest is zero.
pub fn decode(id: u32, block: &[u8], leaf: bool) -> Result<KeyBlock, StorageError> {
    decode_validated(id, block, &validate(id, block, leaf)?, leaf)
}

/// Decodes key block `id`, validated by [`validate`] into `offsets`.
pub fn decode_validated(id: u32, block: &[u8], offsets: &[u32], leaf: bool) -> Result<KeyBlock, StorageError> {
    if leaf {
        let mut entries = Vec::with_capacity(offsets.len());
        for &o in offsets {
            entries.push(entry_of(id, &mut from_offset(id, block, o)?)?.to_entry());
        }
        return Ok(KeyBlock::Leaf(entries));
    }
    let mut children = Vec::with_capacity(offsets.len());
    for (i, &o) in offsets.iter().enumerate() {
        let (k, block, checksum) = child_of(id, &mut from_offset(id, block, o)?, i == 0)?;
        children.push(ChildRef { first_key: k.map_or(Key::Int(0), KeyRef::to_key), block, checksum });
    }
    Ok(KeyBlock::Branch(children))
}

/// Bytes of an entry of key `key`, a payload of `payload_len` bytes and a
/// name of `name_len` bytes, known before the entry is made.
pub fn entry_len(key: &Key, payload_len: usize, name_len: usize) -> usize {
    key.encoded_len() + 2 + payload_len + 2 + name_len + FIXED_LEN
}

/// Consecutive groups of items of `sizes` bytes filling blocks of
/// `capacity` bytes in order. A group after the first holds at least two
/// items when there are two: a branch has at least two children. (Every
/// item fits a third of a block in a branch, so the block before a lone
/// last item holds at least three and can give one.)
pub(crate) fn pack(sizes: &[usize], capacity: usize) -> Vec<std::ops::Range<usize>> {
    let mut groups: Vec<std::ops::Range<usize>> = Vec::new();
    let (mut start, mut used) = (0, 0);
    for (i, &s) in sizes.iter().enumerate() {
        // A branch's first child takes no key; sizes are what each adds.
        if i > start && used + s > capacity {
            groups.push(start..i);
            (start, used) = (i, 0);
        }
        used += s;
    }
    groups.push(start..sizes.len());
    let n = groups.len();
    if n >= 2 && groups[n - 1].len() == 1 && groups[n - 2].len() >= 3 {
        groups[n - 2].end -= 1;
        groups[n - 1].start -= 1;
    }
    groups
}


#[cfg(test)]
mod tests {
    use super::*;

    fn entry(key: Key, id: u32) -> KeyEntry {
        KeyEntry {
            key,
            payload: vec![id as u8; id as usize % 5],
            name: "n".repeat(id as usize % 3),
            object_id: id,
            path: TreePath { bits: u64::from(id) & 3, len: 2 + id as u8 },
            aabb: Aabb::from_array([0.0, 1.0, 2.0, 3.0, 4.0, 5.0 + f64::from(id)]),
        }
    }

    #[test]
    fn leaves_and_branches_round_trip() {
        let entries: Vec<KeyEntry> = (0..6).map(|i| entry(Key::Int(i * 10), i as u32)).collect();
        let mut block = vec![0u8; 1024];
        encode_leaf(&entries, &mut block).unwrap();
        assert_eq!(decode(5, &block, true).unwrap(), KeyBlock::Leaf(entries));
        let children = vec![
            ChildRef { first_key: Key::Int(0), block: 4, checksum: 9 },
            ChildRef { first_key: Key::bytes("m").unwrap(), block: 6, checksum: 10 },
        ];
        let mut block = vec![0u8; 1024];
        encode_branch(&children, &mut block).unwrap();
        assert_eq!(decode(5, &block, false).unwrap(), KeyBlock::Branch(children.clone()));
        let offsets = validate(5, &block, false).unwrap();
        let child = |k: &Key| search_branch(5, &block, &offsets, k).unwrap();
        assert_eq!(child(&Key::Int(u64::MAX)), (4, 9));
        assert_eq!(child(&Key::bytes("a").unwrap()), (4, 9));
        assert_eq!(child(&Key::bytes("m").unwrap()), (6, 10));
        assert_eq!(child(&Key::bytes("z").unwrap()), (6, 10));
    }

    #[test]
    fn a_leaf_is_searched_and_spliced_in_place() {
        let entries: Vec<KeyEntry> = (0..40).map(|i| entry(Key::Int(i * 10), i as u32)).collect();
        let mut block = vec![0u8; 16384];
        encode_leaf(&entries, &mut block).unwrap();
        let offsets = validate(5, &block, true).unwrap();
        for e in &entries {
            assert_eq!(search_leaf(5, &block, &offsets, &e.key).unwrap().as_ref(), Some(e));
            let next = Key::Int(e.key.as_int().unwrap() + 1);
            assert_eq!(search_leaf(5, &block, &offsets, &next).unwrap(), None);
        }
        // Copying the entries as they lie, one re-encoded, gives the leaf encoded anew.
        let mut changed = entries.clone();
        changed[7].name = "moved".into();
        let again = encode_entry(&changed[7]).unwrap();
        let mut parts: Vec<&[u8]> = leaf_entries(5, &block, &offsets).unwrap().into_iter().map(|(_, b)| b).collect();
        parts[7] = &again;
        let mut spliced = vec![0u8; 16384];
        encode_leaf_bytes(&parts, &mut spliced).unwrap();
        assert_eq!(decode(5, &spliced, true).unwrap(), KeyBlock::Leaf(changed));
    }

    #[test]
    fn a_path_is_a_prefix_of_its_descendants_only() {
        let root = TreePath::default();
        let p = root.child(1).child(0);
        assert!(root.is_prefix_of(&p) && p.is_prefix_of(&p));
        assert!(p.is_prefix_of(&p.child(1).child(1)));
        assert!(!p.is_prefix_of(&root.child(1)), "a path is no prefix of its ancestor");
        assert!(!p.is_prefix_of(&root.child(1).child(1).child(0)), "nor of a cousin");
        let deep = (0..64).fold(root, |q, i| q.child(i % 2));
        assert!(deep.is_prefix_of(&deep) && root.child(0).is_prefix_of(&deep));
        assert!(!root.child(1).is_prefix_of(&deep));
        assert_eq!(deep.truncated(1), root.child(0));
        assert_eq!(p.truncated(0), root);
        assert_eq!(p.truncated(9), p);
    }

    #[test]
    fn broken_key_blocks_are_corruption() {
        let entries: Vec<KeyEntry> = (0..3).map(|i| entry(Key::Int(i), i as u32)).collect();
        let mut good = vec![0u8; 1024];
        encode_leaf(&entries, &mut good).unwrap();
        let broken = |f: &dyn Fn(&mut Vec<u8>)| {
            let mut b = good.clone();
            f(&mut b);
            decode(5, &b, true).is_err_and(|e| e.is_corruption())
        };
        assert!(broken(&|b| b[FRAME_LEN] = 0), "no entries");
        assert!(broken(&|b| b[FRAME_LEN] = 200), "more entries than bytes");
        assert!(broken(&|b| b[FRAME_LEN + 4] += 4), "used bytes past the entries");
        assert!(broken(&|b| b[FRAME_LEN + 4] -= 1), "used bytes cutting an entry");
        assert!(broken(&|b| b[1000] = 1), "a byte past the entries");
        assert!(broken(&|b| b[ENTRIES_START] = 7), "an unknown key tag");
        // The second key made equal to the first.
        let second = ENTRIES_START + entry_len(&entries[0].key, entries[0].payload.len(), entries[0].name.len());
        assert!(broken(&|b| b[second + 8] = 0), "keys that do not increase");
        assert!(broken(&|b| b[ENTRIES_START + 10] = 0xff), "a payload longer than allowed");
        // The first entry (key 0, no payload, no name): its path length, then a bit past it.
        let path = ENTRIES_START + 9 + 2 + 2 + 4;
        assert!(broken(&|b| b[path + 8] = 65), "a path deeper than 64 levels");
        assert!(broken(&|b| b[path + 7] = 0x80), "a path bit past its length");
        assert!(broken(&|b| b[path + 9] = 1), "reserved bytes after the path");
        assert!(!broken(&|_| {}));
        let mut one_child = vec![0u8; 1024];
        encode_branch(&[ChildRef { first_key: Key::Int(0), block: 4, checksum: 9 }], &mut one_child).unwrap();
        assert!(decode(5, &one_child, false).is_ok(), "a branch of one child, as a change commit may leave");
    }

    #[test]
    fn groups_fill_blocks_in_order_and_never_leave_a_lone_branch_child() {
        assert_eq!(pack(&[4, 4, 4], 8), vec![0..2, 2..3]);
        assert_eq!(
            pack(&[3, 3, 3, 3], 9),
            vec![0..2, 2..4],
            "a lone last item takes one from the block before"
        );
        assert_eq!(pack(&[5], 8), vec![0..1]);
        assert_eq!(
            pack(&[9, 2], 8),
            vec![0..1, 1..2],
            "an item larger than a block stands alone (the caller refuses it)"
        );
    }
}
