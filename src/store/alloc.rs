//! Free space: sorted, merged ranges of free blocks, first-fit allocation of
//! runs, and growth past the end of the file (format-spec/freelist.md,
//! format-spec/commit.md).

use std::collections::BTreeMap;

use super::StorageError;
use super::format::freelist::FreeRange;

/// A set of free block ranges plus the file's end.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct FreeSpace {
    /// first block -> count; sorted, disjoint, never touching.
    ranges: BTreeMap<u32, u32>,
    /// Blocks in the file (block 0 included); allocation past it grows the file.
    end: u32,
}

impl FreeSpace {
    /// Free space of a file of `end` blocks whose free blocks are `ranges`.
    pub fn new(end: u32, ranges: impl IntoIterator<Item = (u32, u32)>) -> FreeSpace {
        let mut sorted: Vec<(u32, u32)> = ranges.into_iter().filter(|&(_, c)| c > 0).collect();
        sorted.sort_unstable();
        FreeSpace { ranges: coalesce(sorted).collect(), end }
    }

    /// Blocks in the file.
    pub fn end(&self) -> u32 {
        self.end
    }

    /// The free ranges, sorted.
    pub fn ranges(&self) -> Vec<(u32, u32)> {
        self.ranges.iter().map(|(&f, &c)| (f, c)).collect()
    }

    /// True when `block` is free.
    pub fn contains(&self, block: u32) -> bool {
        self.ranges.range(..=block).next_back().is_some_and(|(&f, &c)| block < f + c)
    }

    /// `count` consecutive blocks: the first free range that holds them
    /// (lowest address), else past the end of the file.
    pub fn allocate(&mut self, count: u32) -> Result<u32, StorageError> {
        debug_assert!(count >= 1);
        if let Some((&first, &n)) = self.ranges.iter().find(|&(_, &n)| n >= count) {
            self.ranges.remove(&first);
            if n > count {
                self.ranges.insert(first + count, n - count);
            }
            return Ok(first);
        }
        self.allocate_at_end(count)
    }

    /// `count` consecutive blocks past the end of the file.
    pub fn allocate_at_end(&mut self, count: u32) -> Result<u32, StorageError> {
        let first = self.end;
        self.end = self.end.checked_add(count).ok_or(StorageError::FileTooLarge)?;
        Ok(first)
    }

    /// Gives back the blocks `taken` (as allocated) since the file had `end`
    /// blocks: those below `end` are free again, and the file ends at `end`.
    pub fn give_back(&mut self, taken: &[(u32, u32)], end: u32) {
        for &(first, count) in taken {
            let count = count.min(end.saturating_sub(first));
            self.release(first, count);
        }
        self.end = self.end.min(end);
    }

    /// Marks `count` blocks from `first` free, merging with neighbours.
    pub fn release(&mut self, first: u32, count: u32) {
        if count == 0 {
            return;
        }
        let (mut first, mut count) = (first, count);
        if let Some((&pf, &pc)) = self.ranges.range(..first).next_back()
            && pf + pc == first
        {
            self.ranges.remove(&pf);
            first = pf;
            count += pc;
        }
        if let Some(&nc) = self.ranges.get(&(first + count)) {
            self.ranges.remove(&(first + count));
            count += nc;
        }
        self.ranges.insert(first, count);
    }

    /// Removes the blocks of `other` from this set (blocks pinned by readers).
    pub fn remove_all(&mut self, other: &[(u32, u32)]) {
        for &(first, count) in other {
            for b in first..first + count {
                if let Some((&f, &c)) = self.ranges.range(..=b).next_back()
                    && b < f + c
                {
                    self.ranges.remove(&f);
                    if b > f {
                        self.ranges.insert(f, b - f);
                    }
                    if b + 1 < f + c {
                        self.ranges.insert(b + 1, f + c - b - 1);
                    }
                }
            }
        }
    }

    /// The complement of `used` within blocks 1 .. end, as ranges.
    pub fn complement(end: u32, used: &FreeSpace) -> Vec<(u32, u32)> {
        let mut out = Vec::new();
        let mut next = 1u32;
        for (&f, &c) in &used.ranges {
            if f > next {
                out.push((next, f - next));
            }
            next = next.max(f + c);
        }
        if next < end {
            out.push((next, end - next));
        }
        out
    }
}

/// Sorted ranges with overlapping and touching ones merged.
fn coalesce(sorted: Vec<(u32, u32)>) -> impl Iterator<Item = (u32, u32)> {
    let mut out: Vec<(u32, u32)> = Vec::with_capacity(sorted.len());
    for (first, count) in sorted {
        let end = u64::from(first) + u64::from(count);
        match out.last_mut() {
            Some((f, c)) if u64::from(*f) + u64::from(*c) >= u64::from(first) => {
                *c = (end.max(u64::from(*f) + u64::from(*c)) - u64::from(*f)) as u32;
            }
            _ => out.push((first, count)),
        }
    }
    out.into_iter()
}

/// The blocks of `free` (sorted, disjoint), each labelled with the commit
/// that freed it: its label in `before` where it was free already, else
/// `now`. Neighbours with one label are merged.
pub fn label_freed(free: &[(u32, u32)], before: &[FreeRange], now: u64) -> Vec<FreeRange> {
    let mut out: Vec<FreeRange> = Vec::new();
    let mut push = |first: u64, end: u64, freed: u64| {
        let (first, count) = (first as u32, (end - first) as u32);
        match out.last_mut() {
            Some(l) if u64::from(l.first) + u64::from(l.count) == u64::from(first) && l.freed == freed => {
                l.count += count
            }
            _ => out.push(FreeRange { first, count, freed }),
        }
    };
    let end_of = |r: &FreeRange| u64::from(r.first) + u64::from(r.count);
    let mut j = 0;
    for &(first, count) in free {
        let (mut at, end) = (u64::from(first), u64::from(first) + u64::from(count));
        while at < end {
            while j < before.len() && end_of(&before[j]) <= at {
                j += 1;
            }
            match before.get(j) {
                Some(b) if u64::from(b.first) <= at => {
                    let stop = end.min(end_of(b));
                    push(at, stop, b.freed);
                    at = stop;
                }
                Some(b) => {
                    let stop = end.min(u64::from(b.first));
                    push(at, stop, now);
                    at = stop;
                }
                None => {
                    push(at, end, now);
                    at = end;
                }
            }
        }
    }
    out
}

/// The free ranges after a commit that keeps the committed tree, in one
/// pass over the committed ones: the committed free ranges `before` (their
/// labels kept) and the blocks from `base_end` (the committed file's end)
/// to `end`, less the blocks `written`, plus the committed blocks `freed`
/// now, labelled `now`; neighbours with one label merged. It is what
/// labelling the complement of every block the new state uses gives
/// ([`label_freed`]), without building that set, whose size is the
/// file's.
pub fn free_keeping(
    before: &[FreeRange],
    base_end: u32,
    end: u32,
    written: &FreeSpace,
    freed: &[(u32, u32)],
    now: u64,
) -> Vec<FreeRange> {
    let mut freed: Vec<(u32, u32)> = freed.iter().copied().filter(|&(_, c)| c > 0).collect();
    freed.sort_unstable();
    let mut pass = Pass { written: written.ranges(), wi: 0, freed, fi: 0, now, out: Vec::with_capacity(before.len() + 8) };
    // A committed list's ranges lie in the committed file, past block 0.
    for r in before {
        let stop = (u64::from(r.first) + u64::from(r.count)).min(u64::from(base_end));
        pass.free(u64::from(r.first.max(1)), stop, r.freed);
    }
    pass.free(u64::from(base_end.max(1)), u64::from(end), now);
    pass.finish()
}

/// [`free_keeping`]'s one pass: free ranges come in order of first block.
struct Pass {
    /// The blocks the commit wrote (sorted, few) and the next that may
    /// meet a range.
    written: Vec<(u32, u32)>,
    wi: usize,
    /// The committed blocks freed now (sorted, few) and the next to place.
    freed: Vec<(u32, u32)>,
    fi: usize,
    now: u64,
    out: Vec<FreeRange>,
}

impl Pass {
    /// The list, with the freed blocks past every free range.
    fn finish(mut self) -> Vec<FreeRange> {
        for &(f, c) in &self.freed[self.fi..] {
            push_merged(&mut self.out, u64::from(f), u64::from(f) + u64::from(c), self.now);
        }
        self.out
    }

    /// Blocks `first .. stop`, free with label `label`, less those written;
    /// after the freed blocks that come before them.
    fn free(&mut self, first: u64, stop: u64, label: u64) {
        while let Some(&(f, c)) = self.freed.get(self.fi).filter(|&&(f, _)| u64::from(f) < first) {
            push_merged(&mut self.out, u64::from(f), u64::from(f) + u64::from(c), self.now);
            self.fi += 1;
        }
        let end_of = |(f, c): (u32, u32)| u64::from(f) + u64::from(c);
        while self.written.get(self.wi).is_some_and(|&r| end_of(r) <= first) {
            self.wi += 1;
        }
        let (mut at, mut k) = (first, self.wi);
        while at < stop {
            match self.written.get(k) {
                Some(&(f, c)) if u64::from(f) < stop => {
                    if u64::from(f) > at {
                        push_merged(&mut self.out, at, u64::from(f), label);
                    }
                    at = at.max(end_of((f, c)));
                    k += 1;
                }
                _ => {
                    push_merged(&mut self.out, at, stop, label);
                    at = stop;
                }
            }
        }
    }
}

/// Appends the blocks `first .. stop` labelled `freed` to `out` (in order of
/// first block): merged with the last range when they touch and share the
/// label. Blocks the last range holds already are left out, so that the
/// list stays disjoint even when a hostile file's list names blocks its
/// tree uses.
fn push_merged(out: &mut Vec<FreeRange>, first: u64, stop: u64, freed: u64) {
    let first = match out.last_mut() {
        Some(l) => {
            let l_stop = u64::from(l.first) + u64::from(l.count);
            if stop <= l_stop {
                return;
            }
            let first = first.max(l_stop);
            if first == l_stop && l.freed == freed {
                l.count = (stop - u64::from(l.first)) as u32;
                return;
            }
            first
        }
        None => first,
    };
    if first < stop {
        out.push(FreeRange { first: first as u32, count: (stop - first) as u32, freed });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The free list a commit that keeps the committed tree wrote before
    /// `free_keeping`: every block the new state uses as a set, then its
    /// complement, labelled.
    fn free_by_complement(
        before: &[FreeRange],
        base_end: u32,
        end: u32,
        written: &FreeSpace,
        freed: &[(u32, u32)],
        now: u64,
    ) -> Vec<FreeRange> {
        let mut used = written.clone();
        let free = FreeSpace::new(base_end, before.iter().map(|r| (r.first, r.count)));
        for (first, count) in FreeSpace::complement(base_end, &free) {
            used.release(first, count);
        }
        used.remove_all(freed);
        label_freed(&FreeSpace::complement(end, &used), before, now)
    }

    proptest! {
        /// The one-pass free list equals the complement of every used
        /// block, for any committed list, blocks taken from it or past its
        /// end, and committed blocks freed.
        #[test]
        fn the_free_list_after_a_kept_tree_is_the_complement_of_what_is_used(
            cells in prop::collection::vec(0u8..4, 1..120),
            grow in 0u32..6,
            taken in prop::collection::vec(any::<prop::sample::Index>(), 0..12),
        ) {
            // Each block of the committed file: 0 used, 1 free (freed by
            // commit 3), 2 free (by commit 5), 3 used and freed now.
            let base_end = cells.len() as u32 + 1;
            let end = base_end + grow;
            let mut before: Vec<FreeRange> = Vec::new();
            let mut freed = Vec::new();
            for (i, &c) in cells.iter().enumerate() {
                let b = i as u32 + 1;
                match c {
                    1 | 2 => {
                        let label = if c == 1 { 3 } else { 5 };
                        match before.last_mut() {
                            Some(l) if l.first + l.count == b && l.freed == label => l.count += 1,
                            _ => before.push(FreeRange { first: b, count: 1, freed: label }),
                        }
                    }
                    3 => freed.push((b, 1)),
                    _ => {}
                }
            }
            // The commit writes blocks free before it, or past the committed end.
            let mut open: Vec<u32> = before.iter().flat_map(|r| r.first..r.first + r.count).collect();
            open.extend(base_end..end);
            let mut written = FreeSpace::new(end, []);
            for ix in &taken {
                if !open.is_empty() {
                    written.release(open.remove(ix.index(open.len())), 1);
                }
            }
            prop_assert_eq!(
                free_keeping(&before, base_end, end, &written, &freed, 9),
                free_by_complement(&before, base_end, end, &written, &freed, 9)
            );
        }
    }

    #[test]
    fn allocation_is_first_fit_then_appends() {
        let mut f = FreeSpace::new(20, [(3, 2), (10, 5)]);
        assert_eq!(f.allocate(3).unwrap(), 10);
        assert_eq!(f.allocate(2).unwrap(), 3);
        assert_eq!(f.allocate(3).unwrap(), 20);
        assert_eq!(f.end(), 23);
        assert_eq!(f.ranges(), vec![(13, 2)]);
    }

    #[test]
    fn blocks_given_back_are_free_again_and_the_end_returns() {
        let before = FreeSpace::new(20, [(3, 2), (10, 5)]);
        let mut f = before.clone();
        let taken: Vec<(u32, u32)> = [1, 3, 4, 2].iter().map(|&n| (f.allocate(n).unwrap(), n)).collect();
        assert_eq!(f.end(), 24, "the four blocks grew the file");
        f.give_back(&taken, 20);
        assert_eq!(f, before);
    }

    #[test]
    fn new_and_release_merge() {
        let f = FreeSpace::new(50, [(9, 2), (3, 2), (5, 1), (20, 0), (10, 4)]);
        assert_eq!(f.ranges(), vec![(3, 3), (9, 5)], "touching and overlapping ranges merge");
        let mut g = FreeSpace::new(50, [(3, 2), (30, 1)]);
        for (first, count) in [(1, 2), (5, 5), (31, 3)] {
            g.release(first, count);
        }
        assert_eq!(g.ranges(), vec![(1, 9), (30, 4)]);
    }

    #[test]
    fn release_merges_neighbours_and_complement_inverts() {
        let mut f = FreeSpace::new(30, []);
        f.release(5, 2);
        f.release(9, 1);
        f.release(7, 2);
        assert_eq!(f.ranges(), vec![(5, 5)]);
        assert_eq!(FreeSpace::complement(30, &f), vec![(1, 4), (10, 20)]);
        f.remove_all(&[(6, 2)]);
        assert_eq!(f.ranges(), vec![(5, 1), (8, 2)]);
        assert!(f.contains(8) && !f.contains(6));
    }

    #[test]
    fn freed_blocks_keep_the_commit_that_freed_them() {
        let r = |first, count, freed| FreeRange { first, count, freed };
        let before = [r(2, 3, 4), r(10, 2, 6)];
        // Blocks 2..5 and 10..12 were free before; 5..7 and 12..13 are freed now.
        let got = label_freed(&[(3, 4), (10, 3)], &before, 9);
        assert_eq!(got, vec![r(3, 2, 4), r(5, 2, 9), r(10, 2, 6), r(12, 1, 9)]);
        assert_eq!(label_freed(&[(1, 5)], &[r(1, 2, 9)], 9), vec![r(1, 5, 9)], "one label merges");
    }
}
