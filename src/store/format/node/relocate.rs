//! Relocating node blocks (format-spec/node.md): a compaction moves a
//! tree as it is, so a moved block keeps every byte but the references to
//! the blocks that moved with it.

use zerocopy::FromBytes;
use zerocopy::byteorder::little_endian::U32;

use super::{BlockHead, FLAG_FRAME, FRAME_BOX_LEN, InternalRaw, KIND_INTERNAL, KIND_LEAF, LeafRaw, RECORDS_START};
use crate::store::StorageError;
use crate::store::format::frame::FRAME_LEN;

/// Where a child's block went: (block, checksum) -> the new ones.
pub type MoveChild<'a> = dyn FnMut(u32, u32) -> Result<(u32, u32), StorageError> + 'a;

/// Where a leaf's span went: (first block, its blocks' checksums) -> the new ones.
pub type MoveSpan<'a> = dyn FnMut(u32, &[u32]) -> Result<(u32, Vec<u32>), StorageError> + 'a;

/// Points the references of node block `id`, which
/// [`validate_block`](super::validate_block) accepted with record offsets
/// `records`, at blocks moved elsewhere: each child in another block
/// through `child` (its block and checksum -> the new ones), and each
/// leaf's span through `span` (its first geometry block and its blocks'
/// checksums -> the new first block and checksums). Everything else stays
/// byte for byte.
pub fn relocate_block(
    id: u32,
    block: &mut [u8],
    records: &[u32],
    child: &mut MoveChild<'_>,
    span: &mut MoveSpan<'_>,
) -> Result<(), StorageError> {
    let short = |r: u32| StorageError::corrupt_record(id, r, "record", "short record");
    // The group block moves as a child block does.
    if let Some(head) = block.get_mut(FRAME_LEN..RECORDS_START).and_then(|b| BlockHead::mut_from_bytes(b).ok())
        && head.group_block.get() != 0
    {
        let (b, sum) = child(head.group_block.get(), head.group_checksum.get())?;
        (head.group_block, head.group_checksum) = (b.into(), sum.into());
    }
    for &r in records {
        let bytes = block.get_mut(r as usize..).ok_or_else(|| short(r))?;
        match bytes.first() {
            Some(&KIND_INTERNAL) => {
                let (raw, _) = InternalRaw::mut_from_prefix(bytes).map_err(|_| short(r))?;
                for c in raw.children.iter_mut().filter(|c| c.block.get() != 0) {
                    let (b, sum) = child(c.block.get(), c.checksum.get())?;
                    (c.block, c.checksum) = (b.into(), sum.into());
                }
            }
            Some(&KIND_LEAF) => {
                let (raw, rest) = LeafRaw::mut_from_prefix(bytes).map_err(|_| short(r))?;
                let skip = if raw.flags & FLAG_FRAME != 0 { FRAME_BOX_LEN } else { 0 };
                let rest = rest.get_mut(skip..).ok_or_else(|| short(r))?;
                let (sums, _) = <[U32]>::mut_from_prefix_with_elems(rest, usize::from(raw.span.get()))
                    .map_err(|_| short(r))?;
                let old: Vec<u32> = sums.iter().map(|c| c.get()).collect();
                let (first, new) = span(raw.first_block.get(), &old)?;
                raw.first_block = first.into();
                for (c, n) in sums.iter_mut().zip(new) {
                    *c = n.into();
                }
            }
            _ => return Err(StorageError::corrupt_record(id, r, "kind", "not a record")),
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::store::format::node::tests::{drafts, limits};
    use crate::store::format::node::{NodeView, RecordRef, encode_block, validate_block};

    #[test]
    fn a_relocated_block_changes_only_its_references() {
        let mut block = vec![0u8; 1024];
        let offsets = encode_block(&drafts(), &mut block).unwrap();
        let before = block.clone();
        let mut children = Vec::new();
        let child = &mut |b: u32, sum: u32| {
            children.push((b, sum));
            Ok((b + 100, sum ^ 0xffff))
        };
        let span = &mut |first: u32, sums: &[u32]| Ok((first + 1000, sums.iter().map(|s| s + 1).collect()));
        relocate_block(3, &mut block, &offsets, child, span).unwrap();
        assert_eq!(children, [(5, 1234)], "the child in this block is not a reference");
        assert_eq!(validate_block(3, &block, &limits()).unwrap(), offsets);
        let NodeView::Internal(n) = NodeView::at(&block, offsets[0]).unwrap() else { panic!() };
        assert_eq!(n.child_ref(0), RecordRef { block: 0, checksum: 0, offset: RECORDS_START as u32 + 84 });
        assert_eq!(n.child_ref(1), RecordRef { block: 105, checksum: 1234 ^ 0xffff, offset: RECORDS_START as u32 });
        let NodeView::Leaf(l) = NodeView::at(&block, offsets[1]).unwrap() else { panic!() };
        let (first, sums) = l.geometry();
        assert_eq!((first, sums.collect::<Vec<_>>()), (1009, vec![78]));
        // Every other byte as it was: the child's block and checksum (20 +
        // 32 + 12 .. + 20 of the internal record) and the leaf's first block
        // and checksum (8 .. 12 and 20 .. 24 of its record).
        let internal = offsets[0] as usize + 20 + 32 + 12;
        let leaf = offsets[1] as usize;
        let moved: Vec<usize> = (internal..internal + 8).chain(leaf + 8..leaf + 12).chain(leaf + 20..leaf + 24).collect();
        for (i, (a, b)) in before.iter().zip(&block).enumerate() {
            assert!(a == b || moved.contains(&i), "byte {i} changed");
        }
    }

}
