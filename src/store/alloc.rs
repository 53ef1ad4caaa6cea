//! Free space: sorted, merged ranges of free blocks, first-fit allocation of
//! runs, and growth past the end of the file (format-spec/freelist.md,
//! format-spec/commit.md).

use std::collections::BTreeMap;

use super::StorageError;

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
        let mut f = FreeSpace { ranges: BTreeMap::new(), end };
        for (first, count) in ranges {
            f.release(first, count);
        }
        f
    }

    /// Blocks in the file.
    pub fn end(&self) -> u32 {
        self.end
    }

    /// Free blocks.
    pub fn free_blocks(&self) -> u64 {
        self.ranges.values().map(|&c| u64::from(c)).sum()
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
        let first = self.end;
        self.end = self.end.checked_add(count).ok_or(StorageError::FileTooLarge)?;
        Ok(first)
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

#[cfg(test)]
mod tests {
    use super::*;

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
}
