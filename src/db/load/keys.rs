//! Step 4 of a bulk load: the key index, written bottom-up after the tree
//! (format-spec/keys.md).

use super::{Sink, Written};
use crate::bulk::{LoadProgress, Stage, StageMeter};
use crate::db::source::ObjectSource;
use crate::scene::{Key, KeyError, ObjectId};
use crate::store::StorageError;
use crate::store::format::frame::BlockType;
use crate::store::format::keys::{self, ChildRef, KeyEntry};

/// The key index as written: its root, levels and blocks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct WrittenKeys {
    pub block: u32,
    pub checksum: u32,
    pub height: u32,
    pub blocks: u32,
}

/// Writes the key index of `objects`, whose leaf records and boxes
/// `written` tells, into `sink`. Keys must be unique
/// (`Scene::check_keys`). Only the keys in order are held for every
/// object; entries are made a block at a time, and counted as they are.
pub(super) fn write(
    Sink { pager, txn, allocate }: Sink,
    objects: &dyn ObjectSource,
    written: &Written,
    progress: &(dyn Fn(LoadProgress) + Sync),
) -> Result<WrittenKeys, crate::Error> {
    let meter = StageMeter::new(progress, Stage::Keys, objects.len() as u64);
    let bs = pager.block_size();
    let capacity = keys::capacity(bs);
    let mut order: Vec<(Key, ObjectId)> =
        (0..objects.len()).map(|i| (objects.key(ObjectId(i as u32)), ObjectId(i as u32))).collect();
    order.sort_unstable();
    if let Some(w) = order.windows(2).find(|w| w[0].0 == w[1].0) {
        let (first, second) = (w[0].1.min(w[1].1), w[0].1.max(w[1].1));
        return Err(KeyError::Duplicate { key: w[0].0.clone(), first, second }.into());
    }
    let entry = |&(ref key, id): &(Key, ObjectId)| KeyEntry {
        key: key.clone(),
        payload: objects.payload(id).to_vec(),
        name: objects.name(id).to_string(),
        object_id: id.0,
        path: written.paths.of(id),
        aabb: written.aabb(objects, id),
    };
    let sizes: Vec<usize> = order
        .iter()
        .map(|(key, id)| keys::entry_len(key, objects.payload(*id).len(), objects.name(*id).len()))
        .collect();
    if let Some(at) = sizes.iter().position(|&len| len > capacity) {
        return Err(KeyError::EntryTooLarge { key: order[at].0.clone(), len: sizes[at], capacity }.into());
    }
    let mut block = vec![0u8; bs as usize];
    let mut blocks = 0u32;
    // Writes the encoded `block` as a new block of type `t` whose least key is `first_key`.
    let mut put = |block: &mut [u8], t: BlockType, first_key: Key| -> Result<ChildRef, StorageError> {
        let id = allocate(1)?;
        let checksum = pager.write(id, block, t, txn)?;
        blocks += 1;
        Ok(ChildRef { first_key, block: id, checksum })
    };
    let mut level: Vec<ChildRef> = Vec::new();
    for group in keys::pack(&sizes, capacity) {
        let first_key = order[group.start].0.clone();
        meter.add(group.len() as u64);
        let part: Vec<KeyEntry> = order[group].iter().map(entry).collect();
        keys::encode_leaf(&part, &mut block).map_err(StorageError::Invalid)?;
        level.push(put(&mut block, BlockType::KeyLeaf, first_key)?);
    }
    let mut height = 1;
    while level.len() > 1 {
        let sizes: Vec<usize> =
            level.iter().enumerate().map(|(i, c)| keys::child_len(&c.first_key, i == 0)).collect();
        let mut up = Vec::new();
        for group in keys::pack(&sizes, capacity) {
            let part = &level[group];
            keys::encode_branch(part, &mut block).map_err(StorageError::Invalid)?;
            up.push(put(&mut block, BlockType::KeyBranch, part[0].first_key.clone())?);
        }
        level = up;
        height += 1;
    }
    let root = level.pop().ok_or_else(|| StorageError::Invalid("a key index of no keys".into()))?;
    Ok(WrittenKeys { block: root.block, checksum: root.checksum, height, blocks })
}
