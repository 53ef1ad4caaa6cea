//! Reading the committed state (format-spec/commit.md): both copies of
//! both slots, the newest commit in force, its free list and meta block,
//! the check that a commit synced once reached the disk whole, and the
//! recovery a writer runs after an interrupted transaction.

use super::{Recovery, Warning};
use crate::store::format::frame::{self, BlockType};
use crate::store::format::freelist::{FreeListBlock, FreeRange};
use crate::store::format::header::{self, Commit, PREFIX_LEN, SlotPair, SlotRead};
use crate::store::format::meta::Meta;
use crate::store::{Pager, ReadStats, StorageError};

/// A committed state as read from the file.
#[derive(Debug)]
pub(super) struct Loaded {
    pub(super) slots: [SlotPair; 2],
    pub(super) committed: Commit,
    pub(super) committed_slot: usize,
    pub(super) free: Vec<FreeRange>,
    /// The free list's blocks, head first.
    pub(super) chain: Vec<u32>,
    pub(super) meta: Option<Meta>,
    /// A newer commit, committed with one sync, whose blocks did not all
    /// reach the disk (a crash before its sync): `committed` is the one before.
    pub(super) unfinished: Option<u64>,
}

/// Reads both copies of both slots. A copy failing its checksum may be one a
/// writer in another process is writing right now: it is read again before
/// it counts as damaged, unless the device's writes are atomic.
pub(super) fn read_slots(pager: &Pager) -> Result<[SlotPair; 2], StorageError> {
    let mut prefix = vec![0u8; PREFIX_LEN];
    let tries = if pager.device().writes_are_atomic() { 1 } else { 3 };
    let mut tried = 0;
    loop {
        pager.device().read_at(0, &mut prefix)?;
        let slots = header::decode_slots(&prefix);
        tried += 1;
        if tried == tries || slots.iter().all(|p| p.invalid_copies().next().is_none()) {
            return Ok(slots);
        }
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
}

/// The committed slot in force: the valid committed slot with the larger
/// transaction. A slot whose copies both fail is an error, never a silent
/// fall back to an older state: it may have held the newest commit.
pub(super) fn newest(slots: &[SlotPair; 2]) -> Result<(usize, Commit), StorageError> {
    let values = slots.map(|p| p.value());
    if let Some(i) = (0..2).find(|&i| values[i] == SlotRead::Invalid) {
        return Err(StorageError::corrupt(
            0,
            "slots",
            format!("both copies of commit slot {i} fail their checksums: the newest commit cannot be told"),
        ));
    }
    match values {
        [SlotRead::Committed(a), SlotRead::Committed(b)] => Ok(if b.txn > a.txn { (1, b) } else { (0, a) }),
        [SlotRead::Committed(a), _] => Ok((0, a)),
        [_, SlotRead::Committed(b)] => Ok((1, b)),
        _ => Err(StorageError::corrupt(0, "slots", "no valid committed slot")),
    }
}

/// The newest committed state. Its blocks are read after its slot, and a
/// writer in another process may reuse them in between (no pin holds them
/// yet): when a read fails and the slots have moved on, read again.
pub(super) fn load(pager: &Pager) -> Result<Loaded, StorageError> {
    load_from(pager, read_slots(pager)?)
}

/// [`load`] with the slots already read.
pub(super) fn load_from(pager: &Pager, mut slots: [SlotPair; 2]) -> Result<Loaded, StorageError> {
    loop {
        let result = load_state(pager, &slots);
        let Err(e) = result else { return result };
        let again = read_slots(pager)?;
        if newest(&again).ok().map(|c| c.1.txn) == newest(&slots).ok().map(|c| c.1.txn) {
            return Err(e);
        }
        slots = again;
    }
}

pub(super) fn load_state(pager: &Pager, slots: &[SlotPair; 2]) -> Result<Loaded, StorageError> {
    let (committed_slot, committed) = newest(slots)?;
    match load_commit(pager, slots, committed_slot, committed) {
        // A commit synced once whose blocks are not all there was never
        // durable (its sync did not return): the one before it stands.
        Err(e) if committed.listed && e.is_corruption() => {
            let other = 1 - committed_slot;
            let SlotRead::Committed(before) = slots[other].value() else { return Err(e) };
            let mut l = load_commit(pager, slots, other, before)?;
            l.unfinished = Some(committed.txn);
            Ok(l)
        }
        loaded => loaded,
    }
}

/// The state commit `committed` (in slot `committed_slot`) made: its free
/// list and meta block, and for a commit synced once, the blocks it lists
/// verified against their checksums.
pub(super) fn load_commit(
    pager: &Pager,
    slots: &[SlotPair; 2],
    committed_slot: usize,
    committed: Commit,
) -> Result<Loaded, StorageError> {
    // Block 0 is the header, so every committed state holds it.
    if committed.block_count == 0 {
        return Err(StorageError::corrupt(0, "block_count", "a commit of no blocks, not even the header"));
    }
    let blocks_on_disk = pager.block_count()?;
    if blocks_on_disk < u64::from(committed.block_count) {
        return Err(StorageError::Truncated {
            detail: format!("the commit holds {} blocks, the file {blocks_on_disk}", committed.block_count),
        });
    }
    // Over a network, the meta block and the free list's first block come
    // in one round trip, not two (a local device ignores this).
    let heads: Vec<u32> = [committed.meta_block, committed.freelist_block]
        .into_iter()
        .filter(|&b| b != 0 && b < committed.block_count)
        .collect();
    pager.fetch_ahead(&heads);
    let (free, chain) = free_list_chain(pager, &committed)?;
    let meta = read_meta(pager, &committed)?;
    if committed.listed {
        verify_written(pager, &committed, meta.as_ref())?;
    }
    Ok(Loaded { slots: *slots, committed, committed_slot, free, chain, meta, unfinished: None })
}

/// Checks that every block a commit synced once lists carries the checksum
/// listed: then the commit reached the disk whole (format-spec/commit.md).
pub(super) fn verify_written(pager: &Pager, c: &Commit, meta: Option<&Meta>) -> Result<(), StorageError> {
    let Some(meta) = meta else {
        return Err(StorageError::corrupt(0, "state", "a commit synced once names no meta block"));
    };
    // The list is bounded by the meta block's size; over a network its
    // blocks come in one round trip, not one each.
    let listed: Vec<u32> =
        meta.written.iter().map(|&(b, _)| b).filter(|&b| b != 0 && b < c.block_count).collect();
    pager.fetch_ahead(&listed);
    for &(block, sum) in &meta.written {
        if block == 0 || block >= c.block_count {
            return Err(StorageError::corrupt(
                c.meta_block,
                "written",
                format!("block {block} is not in the file"),
            ));
        }
        let bytes = pager.read_raw(block)?;
        let carried = frame::open(block, &bytes).map(|(f, _)| f.checksum.get());
        if carried.as_ref().ok() != Some(&sum) {
            return Err(StorageError::corrupt(
                block,
                "written",
                format!(
                    "the block does not carry the checksum {sum:#010x} its commit lists: the commit did not reach the disk whole"
                ),
            ));
        }
    }
    Ok(())
}

/// True when a write transaction was interrupted: the other slot pending,
/// or blocks past the committed end.
pub(super) fn interrupted(pager: &Pager, l: &Loaded) -> Result<bool, StorageError> {
    let len = pager.device().len()?;
    let bs = u64::from(pager.block_size());
    Ok(matches!(l.slots[1 - l.committed_slot].value(), SlotRead::Pending { .. })
        || l.unfinished.is_some()
        || len > u64::from(l.committed.block_count) * bs)
}

pub(super) fn warnings(pager: &Pager, l: &Loaded) -> Result<Vec<Warning>, StorageError> {
    let mut w: Vec<Warning> = (0..2)
        .flat_map(|slot| {
            l.slots[slot]
                .invalid_copies()
                .map(move |copy| Warning::DamagedSlotCopy { slot: slot as u8, copy: copy as u8 })
        })
        .collect();
    if let Some(txn) = l.unfinished {
        w.push(Warning::UnfinishedCommit { txn });
    }
    if interrupted(pager, l)? {
        w.push(Warning::Interrupted);
    }
    Ok(w)
}

/// The free ranges of the commit's free-list chain, and the chain's blocks.
pub(super) fn free_list_chain(pager: &Pager, c: &Commit) -> Result<(Vec<FreeRange>, Vec<u32>), StorageError> {
    let mut ranges: Vec<FreeRange> = Vec::new();
    let mut chain = Vec::new();
    let (mut block, mut sum) = (c.freelist_block, c.freelist_checksum);
    let mut stats = ReadStats::default();
    let mut hops = 0u64;
    while block != 0 {
        hops += 1;
        if block >= c.block_count || hops > u64::from(c.block_count) {
            return Err(StorageError::corrupt(block, "next_block", "the free list leaves the file or loops"));
        }
        let (b, _) = pager.read(block, BlockType::FreeList, Some(sum), &mut stats)?;
        let fl = FreeListBlock::decode(block, &b)?;
        chain.push(block);
        for &r in &fl.ranges {
            // Neighbours touch only when different commits freed them.
            let last = ranges.last().map_or(1, |p| p.first + p.count + u32::from(p.freed == r.freed));
            if r.count == 0
                || r.first < last
                || u64::from(r.first) + u64::from(r.count) > u64::from(c.block_count)
                || r.freed == 0
                || r.freed > c.txn
            {
                return Err(StorageError::corrupt(
                    block,
                    "ranges",
                    format!(
                        "range ({}, {}) freed by {} is out of order, out of the file or from a later commit",
                        r.first, r.count, r.freed
                    ),
                ));
            }
            ranges.push(r);
        }
        (block, sum) = (fl.next_block, fl.next_checksum);
    }
    let total: u64 = ranges.iter().map(|r| u64::from(r.count)).sum();
    if total != u64::from(c.free_blocks) {
        return Err(StorageError::corrupt(
            0,
            "free_blocks",
            format!("the slot says {}, the list holds {total}", c.free_blocks),
        ));
    }
    Ok((ranges, chain))
}

/// The commit's meta block, if it has a tree.
pub(super) fn read_meta(pager: &Pager, c: &Commit) -> Result<Option<Meta>, StorageError> {
    if c.meta_block == 0 {
        return Ok(None);
    }
    if c.meta_block >= c.block_count {
        return Err(StorageError::corrupt(
            0,
            "meta_block",
            format!("block {} is past the end", c.meta_block),
        ));
    }
    let (b, _) =
        pager.read(c.meta_block, BlockType::Meta, Some(c.meta_checksum), &mut ReadStats::default())?;
    let meta = Meta::decode(c.meta_block, &b)?;
    if meta.root_block == 0 || meta.root_block >= c.block_count {
        return Err(StorageError::corrupt(
            c.meta_block,
            "root_block",
            format!("{} is not a block of the file", meta.root_block),
        ));
    }
    // Readers size loops and stacks by these counts: bound them by the bytes
    // that must hold them. Every node record and every object entry takes at
    // least 20 bytes of a node block's payload (format-spec/node.md).
    let per_block = u64::from(pager.block_size() - 24) / 20;
    let entries = u64::from(meta.node_blocks) * per_block;
    let too_many = |field: &'static str, n: u64, most: u64| {
        (n > most).then(|| {
            StorageError::corrupt(c.meta_block, field, format!("{n} is more than the file can hold ({most})"))
        })
    };
    if let Some(e) = too_many("node_blocks", meta.node_blocks.into(), c.block_count.into())
        .or_else(|| too_many("geometry_blocks", meta.geometry_blocks, c.block_count.into()))
        .or_else(|| too_many("node_count", meta.node_count.into(), entries))
        .or_else(|| too_many("object_count", meta.object_count.into(), entries))
        .or_else(|| too_many("depth", meta.depth.into(), u64::from(meta.node_count).saturating_sub(1)))
        .or_else(|| too_many("keys_blocks", meta.keys_blocks.into(), c.block_count.into()))
        .or_else(|| too_many("keys_height", meta.keys_height.into(), meta.keys_blocks.into()))
        .or_else(|| too_many("keys_block", meta.keys_block.into(), u64::from(c.block_count) - 1))
    {
        return Err(e);
    }
    Ok(Some(meta))
}

/// Cleans up after an interrupted transaction (format-spec/commit.md): drops
/// blocks past the committed end and rewrites torn free blocks. Only a
/// write transaction calls it, holding the writer's lock.
pub(super) fn recover(
    pager: &Pager,
    c: &Commit,
    free: &[FreeRange],
    r: &mut Recovery,
) -> Result<(), StorageError> {
    let bs = u64::from(pager.block_size());
    let len = pager.device().len()?;
    let end = u64::from(c.block_count) * bs;
    if len > end {
        r.truncated_blocks = (len - end).div_ceil(bs);
        pager.device().set_len(end)?;
    }
    for f in free {
        for id in f.first..f.first + f.count {
            let mut b = pager.read_raw(id)?;
            if frame::open(id, &b).is_err() {
                b.fill(0);
                pager.write(id, &mut b, BlockType::Free, c.txn)?;
                r.scrubbed_blocks += 1;
            }
        }
    }
    pager.sync()
}
