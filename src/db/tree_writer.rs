//! Lays a built tree out in blocks (format-spec/node.md, geometry.md):
//! geometry records packed into geometry blocks in leaf order, node records
//! with quantized boxes packed into node blocks as connected pieces, and
//! each child entry's counts of the blocks below it.

use crate::build::{Hierarchy, Order};
use crate::geom::Aabb;
use crate::scene::Scene;
use crate::store::format::frame::{BlockType, FRAME_LEN};
use crate::store::format::geometry::{self, Placement};
use crate::store::format::node::{
    self, BoundEntry, ChildEntry, ObjectEntry, RecordDraft, RecordRef, SplitInfo, leaf_len,
};
use crate::store::format::quant::{QuantBox, quantize};
use crate::store::{Pager, StorageError, layout};

/// What the layout wrote, for the meta block.
#[derive(Debug, Clone, Default)]
pub(crate) struct Written {
    pub root: (u32, u32, u32),
    pub node_blocks: u32,
    pub node_bytes: u64,
    pub geometry_blocks: u64,
    pub geometry_bytes: u64,
}

/// Writes `tree` over `scene` with the inline `bounds` of each node
/// (internal: its children's group bounds; leaf: its objects'), allocating
/// blocks through `allocate` (count -> first block of a run).
pub(crate) fn write(
    pager: &Pager,
    txn: u64,
    scene: &Scene,
    tree: &Hierarchy,
    bounds: &[Vec<BoundEntry>],
    allocate: &mut dyn FnMut(u32) -> Result<u32, StorageError>,
) -> Result<Written, StorageError> {
    let bs = pager.block_size();
    let nodes = &tree.nodes;
    let n = nodes.len();
    let invalid = |d: String| StorageError::Invalid(d);
    // Geometry: every leaf's objects in preorder, packed into one run of blocks.
    let mut placement = Placement::new(bs);
    let mut positions: Vec<Vec<u64>> = vec![Vec::new(); n];
    let mut geometry_bytes = 0u64;
    for (i, node) in nodes.iter().enumerate() {
        if let Some(objects) = node.objects() {
            for id in objects {
                let o = scene.object(*id).ok_or_else(|| invalid(format!("no object {id}")))?;
                let len = geometry::record_len(&o.mesh);
                geometry_bytes += len;
                positions[i].push(placement.place(len));
            }
        }
    }
    let stream_end = placement.end();
    let geometry_blocks = placement.blocks();
    let count = u32::try_from(geometry_blocks).map_err(|_| StorageError::FileTooLarge)?;
    let first_geometry = allocate(count)?;
    let p = geometry::payload(bs);
    let mut sums = Vec::with_capacity(count as usize);
    let mut block = vec![0u8; bs as usize];
    let mut filled = 0u64; // stream bytes of blocks already written
    let mut record = Vec::new();
    let flush = |block: &mut Vec<u8>, index: u64, sums: &mut Vec<u32>| -> Result<(), StorageError> {
        let id = first_geometry + index as u32;
        sums.push(pager.write(id, block, BlockType::Geometry, txn)?);
        block.fill(0);
        Ok(())
    };
    for (i, node) in nodes.iter().enumerate() {
        let Some(objects) = node.objects() else { continue };
        for (id, &pos) in objects.iter().zip(&positions[i]) {
            let o = scene.object(*id).ok_or_else(|| invalid(format!("no object {id}")))?;
            record.clear();
            geometry::encode_object(*id, &o.mesh, &mut record);
            let mut at = pos;
            let mut rest = &record[..];
            while !rest.is_empty() {
                while at >= filled + p {
                    flush(&mut block, filled / p, &mut sums)?;
                    filled += p;
                }
                let off = (at - filled) as usize;
                let take = rest.len().min(p as usize - off);
                block[FRAME_LEN + off..FRAME_LEN + off + take].copy_from_slice(&rest[..take]);
                rest = &rest[take..];
                at += take as u64;
            }
        }
    }
    while filled < stream_end {
        flush(&mut block, filled / p, &mut sums)?;
        filled += p;
    }
    // Frames: each node's box as its parent's entry stores it (the root's is exact).
    let mut frame = vec![Aabb::EMPTY; n];
    frame[0] = nodes[0].aabb;
    let mut child_q = vec![[0u16; 6]; n];
    for i in 0..n {
        if let Some(kids) = nodes[i].children() {
            for c in kids {
                let q = quantize(&frame[i], &nodes[c.index()].aabb);
                let qb = QuantBox::decode(&frame[i], q).ok_or_else(|| invalid("a box quantized backwards".into()))?;
                if !qb.outer.contains(&nodes[c.index()].aabb) {
                    return Err(invalid(format!("node {} does not lie in its parent's box", c.0)));
                }
                child_q[c.index()] = q;
                frame[c.index()] = qb.outer;
            }
        }
    }
    // Leaf drafts (block references are fixed below) and record sizes.
    let leaf_span = |i: usize| -> (u64, u64) {
        let first = positions[i].first().copied().unwrap_or(0) / p;
        let last_end = match nodes[i].objects() {
            Some(objs) => {
                let last = *objs.last().unwrap_or(&crate::scene::ObjectId(0));
                let len = scene.object(last).map_or(0, |o| geometry::record_len(&o.mesh));
                positions[i].last().copied().unwrap_or(0) + len
            }
            None => 0,
        };
        (first, (last_end - 1) / p)
    };
    let sizes: Vec<usize> = (0..n)
        .map(|i| {
            let extra: usize = bounds[i].iter().map(|b| node::BOUND_HEAD_LEN + b.blob.len().next_multiple_of(4)).sum();
            match nodes[i].objects() {
                Some(objs) => {
                    let (a, b) = leaf_span(i);
                    leaf_len(objs.len(), (b - a + 1) as usize, extra)
                }
                None => node::INTERNAL_LEN + extra,
            }
        })
        .collect();
    let capacity = node::capacity(bs);
    if let Some(i) = (0..n).find(|&i| sizes[i] > capacity) {
        return Err(invalid(format!(
            "node {i}'s record takes {} bytes and a node block holds {capacity}: use smaller leaves or larger blocks",
            sizes[i]
        )));
    }
    let packing = layout::pack(&sizes, |i| nodes[i].children().map(|c| c.map(|x| x.index())), capacity);
    let block_count = u32::try_from(packing.blocks.len()).map_err(|_| StorageError::FileTooLarge)?;
    let first_node = allocate(block_count)?;
    // Offsets of every record in its block.
    let mut offset = vec![0u32; n];
    for members in &packing.blocks {
        let mut at = node::RECORDS_START as u32;
        for &m in members {
            offset[m as usize] = at;
            at += sizes[m as usize] as u32;
        }
    }
    let below = node_blocks_below(n, &packing.place, |i| nodes[i].children().map(|c| c.map(|x| x.index())));
    let subtree_leaves = |i: usize| -> (usize, usize) {
        // First and last leaf of a subtree in preorder.
        let (mut a, mut b) = (i, i);
        while let Some(c) = nodes[a].children() {
            a = c[0].index();
        }
        while let Some(c) = nodes[b].children() {
            b = c[1].index();
        }
        (a, b)
    };
    // Blocks last to first: a child's block never precedes its parent's.
    let mut checksums = vec![0u32; packing.blocks.len()];
    let mut node_bytes = 0u64;
    for b in (0..packing.blocks.len()).rev() {
        let records: Vec<RecordDraft> = packing.blocks[b]
            .iter()
            .map(|&m| {
                let i = m as usize;
                let node = &nodes[i];
                match (node.children(), node.split()) {
                    (Some(kids), Some(s)) => {
                        let child = |c: usize| {
                            let (cb, _) = packing.place[c];
                            let at = if cb as usize == b {
                                RecordRef { block: 0, checksum: 0, offset: offset[c] }
                            } else {
                                RecordRef { block: first_node + cb, checksum: checksums[cb as usize], offset: offset[c] }
                            };
                            let (fl, ll) = subtree_leaves(c);
                            let geometry_blocks = (leaf_span(ll).1 - leaf_span(fl).0 + 1) as u32;
                            ChildEntry {
                                qbox: child_q[c],
                                at,
                                node_blocks: below[c] - u32::from(block_in_subtree(&packing.place, b as u32, c, subtree_end(c, &subtree_leaves))),
                                geometry_blocks,
                            }
                        };
                        let order = match s.order {
                            Order::Min => 0,
                            Order::Max => 1,
                            Order::Center => 2,
                        };
                        RecordDraft::Internal {
                            node_id: i as u32,
                            object_count: object_count(tree, i),
                            split: SplitInfo { axis: s.axis, order, overlap: s.overlap as f32, gap: s.gap as f32 },
                            children: [child(kids[0].index()), child(kids[1].index())],
                            bounds: bounds[i].clone(),
                        }
                    }
                    _ => {
                        let objs = node.objects().unwrap_or_default();
                        let (a, last) = leaf_span(i);
                        let base = a * p;
                        let objects = objs
                            .iter()
                            .zip(&positions[i])
                            .map(|(id, &pos)| {
                                let aabb = scene.object(*id).map_or(Aabb::EMPTY, |o| o.mesh.aabb());
                                ObjectEntry { object_id: id.0, qbox: quantize(&frame[i], &aabb), position: pos - base }
                            })
                            .collect();
                        let end = positions[i].last().copied().unwrap_or(0)
                            + objs.last().and_then(|id| scene.object(*id)).map_or(0, |o| geometry::record_len(&o.mesh));
                        RecordDraft::Leaf {
                            node_id: i as u32,
                            first_block: first_geometry + a as u32,
                            checksums: sums[a as usize..=last as usize].to_vec(),
                            objects,
                            end: end - base,
                            bounds: bounds[i].clone(),
                        }
                    }
                }
            })
            .collect();
        let mut bytes = vec![0u8; bs as usize];
        node::encode_block(&records, &mut bytes).map_err(invalid)?;
        node_bytes += records.iter().map(|r| r.len() as u64).sum::<u64>();
        checksums[b] = pager.write(first_node + b as u32, &mut bytes, BlockType::Node, txn)?;
    }
    let (rb, _) = packing.place[0];
    Ok(Written {
        root: (first_node + rb, checksums[rb as usize], offset[0]),
        node_blocks: block_count,
        node_bytes,
        geometry_blocks,
        geometry_bytes,
    })
}

fn object_count(tree: &Hierarchy, i: usize) -> u32 {
    let mut stack = vec![i];
    let mut n = 0u32;
    while let Some(j) = stack.pop() {
        match (tree.nodes[j].children(), tree.nodes[j].objects()) {
            (Some(c), _) => stack.extend(c.map(|c| c.index())),
            (None, Some(o)) => n += o.len() as u32,
            _ => {}
        }
    }
    n
}

/// One past the last preorder id of node `i`'s subtree.
fn subtree_end(i: usize, leaves: &dyn Fn(usize) -> (usize, usize)) -> usize {
    leaves(i).1 + 1
}

/// True when a node of the subtree `[c, end)` (preorder ids) lies in block `b`.
fn block_in_subtree(place: &[(u32, u32)], b: u32, c: usize, end: usize) -> bool {
    place[c..end].iter().any(|p| p.0 == b)
}

/// For each node, the distinct node blocks of its subtree (nodes in
/// preorder: a subtree is a range of ids), by the offline distinct-count of
/// ranges with a Fenwick tree.
fn node_blocks_below(n: usize, place: &[(u32, u32)], children: impl Fn(usize) -> Option<[usize; 2]>) -> Vec<u32> {
    // Subtree ranges [i, end_i).
    let mut end = vec![0usize; n];
    for i in (0..n).rev() {
        end[i] = match children(i) {
            Some(c) => end[c[1]],
            None => i + 1,
        };
    }
    let mut by_end: Vec<usize> = (0..n).collect();
    by_end.sort_by_key(|&i| end[i]);
    let mut fenwick = vec![0i64; n + 1];
    let add = |f: &mut Vec<i64>, mut i: usize, v: i64| {
        i += 1;
        while i < f.len() {
            f[i] += v;
            i += i & i.wrapping_neg();
        }
    };
    let sum = |f: &Vec<i64>, mut i: usize| -> i64 {
        let mut s = 0;
        while i > 0 {
            s += f[i];
            i -= i & i.wrapping_neg();
        }
        s
    };
    let mut last_seen: std::collections::HashMap<u32, usize> = std::collections::HashMap::new();
    let mut out = vec![0u32; n];
    let mut pos = 0usize;
    for &i in &by_end {
        while pos < end[i] {
            let b = place[pos].0;
            if let Some(&prev) = last_seen.get(&b) {
                add(&mut fenwick, prev, -1);
            }
            add(&mut fenwick, pos, 1);
            last_seen.insert(b, pos);
            pos += 1;
        }
        out[i] = (sum(&fenwick, end[i]) - sum(&fenwick, i)) as u32;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distinct_blocks_of_subtrees() {
        // 0 -> (1, 4); 1 -> (2, 3); preorder ids.
        let kids = |i: usize| match i {
            0 => Some([1, 4]),
            1 => Some([2, 3]),
            _ => None,
        };
        let place = [(0, 0), (0, 1), (1, 0), (2, 0), (1, 1)];
        assert_eq!(node_blocks_below(5, &place, kids), vec![3, 3, 1, 1, 1]);
    }
}
