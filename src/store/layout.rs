//! Packing binary nodes into node blocks as clustered subtrees
//! (format-spec/node.md, "Packing"): a block starts at a subtree root and
//! takes its descendants breadth-first until full; children left out start
//! later blocks. A depth-first traversal then enters each block once.

use std::collections::VecDeque;

/// Where each node went: block index (in the order blocks were started) and
/// slot; `blocks[b]` lists block b's nodes by slot.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Packing {
    pub place: Vec<(u32, u16)>,
    pub blocks: Vec<Vec<u32>>,
}

/// Packs a tree of `n` nodes rooted at node 0, `children(i)` giving node i's
/// children, `capacity` records per block.
pub fn pack(n: usize, children: impl Fn(usize) -> Option<[usize; 2]>, capacity: usize) -> Packing {
    assert!(capacity >= 1 && n >= 1, "pack needs a node and room for one");
    let mut place = vec![(u32::MAX, 0u16); n];
    let mut blocks: Vec<Vec<u32>> = Vec::new();
    let mut roots = VecDeque::from([0usize]);
    while let Some(root) = roots.pop_front() {
        let b = blocks.len() as u32;
        let mut members = Vec::with_capacity(capacity);
        let mut frontier = VecDeque::from([root]);
        while let Some(i) = frontier.pop_front() {
            if members.len() == capacity {
                roots.push_back(i);
                roots.extend(frontier.drain(..));
                break;
            }
            place[i] = (b, members.len() as u16);
            members.push(i as u32);
            if let Some(c) = children(i) {
                frontier.extend(c);
            }
        }
        blocks.push(members);
    }
    Packing { place, blocks }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A complete binary tree in heap order: children of i are 2i+1, 2i+2.
    fn heap(n: usize) -> impl Fn(usize) -> Option<[usize; 2]> {
        move |i| (2 * i + 2 < n).then_some([2 * i + 1, 2 * i + 2])
    }

    #[test]
    fn every_node_is_placed_once_and_blocks_are_connected() {
        for (n, cap) in [(1, 1), (7, 3), (31, 3), (63, 5), (255, 7)] {
            let p = pack(n, heap(n), cap);
            let mut seen = vec![false; n];
            for (b, members) in p.blocks.iter().enumerate() {
                assert!(members.len() <= cap);
                for (s, &m) in members.iter().enumerate() {
                    assert!(!seen[m as usize]);
                    seen[m as usize] = true;
                    assert_eq!(p.place[m as usize], (b as u32, s as u16));
                    // Connected: every member but the first has its parent in the block.
                    if s > 0 {
                        let parent = (m as usize - 1) / 2;
                        assert_eq!(p.place[parent].0, b as u32);
                    }
                }
            }
            assert!(seen.iter().all(|&s| s));
        }
    }

    #[test]
    fn a_path_crosses_few_blocks() {
        // 2^12 - 1 nodes, 15 per block (4 levels): a root-to-leaf path of 12 levels touches 3 blocks.
        let n = (1 << 12) - 1;
        let p = pack(n, heap(n), 15);
        let mut i = n - 1;
        let mut blocks = std::collections::HashSet::new();
        loop {
            blocks.insert(p.place[i].0);
            if i == 0 {
                break;
            }
            i = (i - 1) / 2;
        }
        assert_eq!(blocks.len(), 3);
    }
}
