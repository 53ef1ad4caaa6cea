//! The read model a bulk load's layout is judged on (format-spec/lod.md,
//! "What pays"): box queries of the [`QueryMix`] sampled at each scale,
//! the node blocks a packing makes them read, and the geometry blocks of
//! the objects no box, face or bound decides. It chooses the packing of
//! node records (`choose_packing`), whether stored bounds pay
//! (`Plan::expected_reads`), and measures a file's layout drift.

use std::collections::HashMap;

use rayon::prelude::*;

use super::plan::Plan;
use crate::bulk::Hierarchy;
use crate::geom::Aabb;
use crate::lod::{StoredBounds, Voxels};
use crate::store::format::node;
use crate::store::format::quant::QuantBox;
use crate::store::layout::{self, Packing};

/// Sample queries per scale of the read model.
pub(crate) const SAMPLES_PER_SCALE: usize = 256;

/// The least average fill of node blocks a packing must reach, when one can.
const MIN_FILL: f64 = 0.8;

/// Decoded bounds the read model keeps per job: the samples of a large
/// tree may leave open more entries than memory should hold at once.
const DECODED_MAX: usize = 4096;

/// Piece sizes tried, as shares of a block (`store/layout.rs`).
const PIECE_SHARES: [f64; 5] = [0.25, 0.35, 0.5, 0.7, 1.0];

impl Plan {
    /// The model's expected block reads per query for an exact answer, per
    /// scale of the mix, when the tree is laid out with those of `stored`'s
    /// bounds worth at least `min_value` (none at infinity): the node blocks
    /// the chosen packing makes it read, and the geometry blocks of the
    /// objects no box, face or bound decides (as the traversal decides them).
    pub fn expected_reads(
        &self,
        tree: &Hierarchy,
        stored: &StoredBounds,
        min_value: f64,
        block_size: u32,
    ) -> Vec<f64> {
        let sizes = self.sizes(tree, |i| stored.bytes_at(i, min_value));
        let capacity = node::capacity(block_size);
        let scales = self.samples.len().div_ceil(SAMPLES_PER_SCALE);
        if sizes.iter().any(|&s| s > capacity) {
            // Bounds that swell a record past a block cannot be written: never worth keeping.
            return vec![f64::INFINITY; scales];
        }
        let (packing, _) = choose_packing(tree, &sizes, capacity, &self.samples);
        let walk = BlockWalk::new(tree, &packing);
        // Per sample: its node block reads plus its distinct geometry blocks
        // (integer sums, so the same on any number of threads).
        // Each entry's bound is decoded once per job, not once per sample it
        // leaves open (up to DECODED_MAX kept at a time).
        let per_sample: Vec<usize> = self
            .samples
            .par_iter()
            .map_init(Scratch::default, |s: &mut Scratch, q| {
                let Scratch { decoded, blocks, stack, pending, walk_stack, walk_blocks } = s;
                blocks.clear();
                stack.clear();
                if self.frames[0].intersects(q) && !q.contains(&self.frames[0]) {
                    stack.push(0usize);
                }
                while let Some(i) = stack.pop() {
                    for c in tree.nodes[i].children().into_iter().flatten() {
                        let f = &self.frames[c.index()];
                        // A child the query holds is answered without geometry.
                        if f.intersects(q) && !q.contains(f) {
                            stack.push(c.index());
                        }
                    }
                    // An object's entries are consecutive: one confirmed part
                    // answers it, else every part not ruled out is read.
                    let mut j = 0;
                    let es = &self.entries[i];
                    while j < es.len() {
                        let id = es[j].id;
                        let end = j + es[j..].iter().take_while(|e| e.id == id).count();
                        pending.clear();
                        let mut confirmed = false;
                        for (e, entry) in es.iter().enumerate().take(end).skip(j) {
                            let Some(b) = QuantBox::decode(&self.frames[i], entry.qbox) else { continue };
                            if !b.outer.intersects(q) {
                                continue;
                            }
                            if b.face_slabs().iter().any(|f| q.contains(f)) {
                                confirmed = true;
                                break;
                            }
                            // Decoded here, for the few entries a sample leaves open.
                            if decoded.len() >= DECODED_MAX && !decoded.contains_key(&(i, e)) {
                                decoded.clear();
                            }
                            let bound = decoded
                                .entry((i, e))
                                .or_insert_with(|| stored.finest(i, e, min_value, &b.outer));
                            if bound.as_ref().is_some_and(|v| v.holds_a_cell_in(q)) {
                                confirmed = true;
                                break;
                            }
                            if bound.as_ref().is_none_or(|v| v.may_meet(q)) {
                                pending.push(e);
                            }
                        }
                        if !confirmed {
                            for &e in pending.iter() {
                                blocks.extend(self.entry_blocks(i, e));
                            }
                        }
                        j = end;
                    }
                }
                blocks.sort_unstable();
                blocks.dedup();
                walk.blocks_read(q, walk_stack, walk_blocks) + blocks.len()
            })
            .collect();
        let mut reads = vec![0usize; scales];
        for (qi, r) in per_sample.into_iter().enumerate() {
            reads[qi / SAMPLES_PER_SCALE] += r;
        }
        reads.iter().map(|&r| r as f64 / SAMPLES_PER_SCALE as f64).collect()
    }
}

/// What one rayon job of [`Plan::expected_reads`] reuses from sample to
/// sample: the bounds it decoded, and buffers (allocations were a tenth
/// of a small tree's commit).
#[derive(Default)]
struct Scratch {
    decoded: HashMap<(usize, usize), Option<Voxels>>,
    blocks: Vec<u64>,
    stack: Vec<usize>,
    pending: Vec<usize>,
    walk_stack: Vec<usize>,
    walk_blocks: Vec<usize>,
}

/// The node blocks of a packing that queries read: a query reads the block
/// of every node whose box it meets (as the traversal does, which tests a
/// child's box before reading its block).
pub(super) struct BlockWalk<'a> {
    tree: &'a Hierarchy,
    p: &'a Packing,
    /// Per node: true when its whole subtree lies in its block, so a query
    /// that reads the node reads no other block below it.
    closed: Vec<bool>,
}

impl<'a> BlockWalk<'a> {
    pub(super) fn new(tree: &'a Hierarchy, p: &'a Packing) -> BlockWalk<'a> {
        let mut closed = vec![false; tree.nodes.len()];
        // Preorder: children come after their parent.
        for i in (0..tree.nodes.len()).rev() {
            let b = p.place[i].0;
            closed[i] = tree.nodes[i]
                .children()
                .is_none_or(|cs| cs.iter().all(|c| closed[c.index()] && p.place[c.index()].0 == b));
        }
        BlockWalk { tree, p, closed }
    }

    /// Calls `read` with the block of every node `q` reads, except below a
    /// closed node (its block already named).
    fn walk(&self, q: &Aabb, stack: &mut Vec<usize>, mut read: impl FnMut(usize)) {
        stack.clear();
        if self.tree.nodes.first().is_some_and(|r| r.aabb.intersects(q)) {
            stack.push(0);
        }
        while let Some(i) = stack.pop() {
            read(self.p.place[i].0 as usize);
            if self.closed[i] {
                continue;
            }
            for c in self.tree.nodes[i].children().into_iter().flatten() {
                if self.tree.nodes[c.index()].aabb.intersects(q) {
                    stack.push(c.index());
                }
            }
        }
    }

    /// Per block, how many of `queries` read it.
    pub(super) fn reads_per_block(&self, queries: &[Aabb]) -> Vec<u32> {
        let mut reads = vec![0u32; self.p.blocks.len()];
        let mut seen = vec![u32::MAX; self.p.blocks.len()];
        let mut stack = Vec::new();
        for (qi, q) in queries.iter().enumerate() {
            self.walk(q, &mut stack, |b| {
                if seen[b] != qi as u32 {
                    seen[b] = qi as u32;
                    reads[b] += 1;
                }
            });
        }
        reads
    }

    /// The distinct blocks one query `q` reads (`stack` and `blocks`: scratch).
    fn blocks_read(&self, q: &Aabb, stack: &mut Vec<usize>, blocks: &mut Vec<usize>) -> usize {
        blocks.clear();
        self.walk(q, stack, |b| blocks.push(b));
        blocks.sort_unstable();
        blocks.dedup();
        blocks.len()
    }
}

/// The packing of `tree`'s records (`sizes` bytes each), among the piece
/// sizes tried, whose blocks the model's `samples` read least (then the fullest); with each block's reads,
/// unless every piece size packs alike (nothing to choose: not measured).
pub(crate) fn choose_packing(
    tree: &Hierarchy,
    sizes: &[usize],
    capacity: usize,
    samples: &[Aabb],
) -> (Packing, Option<Vec<u32>>) {
    let children = |i: usize| tree.nodes[i].children().map(|c| c.map(|x| x.index()));
    let total: usize = sizes.iter().sum();
    let packings: Vec<Packing> = PIECE_SHARES
        .par_iter()
        .map(|share| layout::pack(sizes, children, capacity, (capacity as f64 * share) as usize))
        .collect();
    // Piece sizes often pack a small tree alike: each distinct packing is measured once.
    let mut distinct: Vec<Packing> = Vec::with_capacity(packings.len());
    for p in packings {
        if !distinct.contains(&p) {
            distinct.push(p);
        }
    }
    if distinct.len() == 1 {
        return (distinct.remove(0), None);
    }
    let tried: Vec<(Packing, Vec<u32>)> = distinct
        .into_par_iter()
        .map(|p| {
            let reads = BlockWalk::new(tree, &p).reads_per_block(samples);
            (p, reads)
        })
        .collect();
    // Blocks at least MIN_FILL full on average when some packing makes
    // them so (fewer blocks, a smaller file), then the fewest reads.
    let full = |p: &Packing| total as f64 >= MIN_FILL * (p.blocks.len() * capacity) as f64;
    let any_full = tried.iter().any(|(p, _)| full(p));
    let chosen = tried
        .into_iter()
        .filter(|(p, _)| full(p) || !any_full)
        .min_by_key(|(p, reads)| (reads.iter().map(|&r| u64::from(r)).sum::<u64>(), p.blocks.len()));
    match chosen {
        Some((p, reads)) => (p, Some(reads)),
        None => (layout::pack(sizes, children, capacity, capacity), None),
    }
}

/// The node blocks the read model's `samples` read per query on `packing`
/// of `tree`, averaged per scale of the mix (samples in scale order,
/// [`SAMPLES_PER_SCALE`] each).
pub(crate) fn node_reads_per_scale(tree: &Hierarchy, packing: &Packing, samples: &[Aabb]) -> Vec<f64> {
    let walk = BlockWalk::new(tree, packing);
    let (mut stack, mut blocks) = (Vec::new(), Vec::new());
    samples
        .chunks(SAMPLES_PER_SCALE)
        .map(|scale| {
            let reads: usize = scale.iter().map(|q| walk.blocks_read(q, &mut stack, &mut blocks)).sum();
            reads as f64 / scale.len() as f64
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bulk::{BuildParams, LeafRule, Method, build};
    use proptest::prelude::*;

    /// Per block, the queries that read it, walking every node a query meets.
    fn every_node_walk(tree: &Hierarchy, p: &Packing, queries: &[Aabb]) -> Vec<u32> {
        (0..p.blocks.len())
            .map(|b| {
                let met = |q: &Aabb| {
                    let mut stack = vec![0usize];
                    let mut hit = false;
                    while let Some(i) = stack.pop() {
                        if !tree.nodes[i].aabb.intersects(q) {
                            continue;
                        }
                        hit |= p.place[i].0 as usize == b;
                        stack.extend(tree.nodes[i].children().into_iter().flatten().map(|c| c.index()));
                    }
                    hit
                };
                queries.iter().filter(|q| met(q)).count() as u32
            })
            .collect()
    }

    fn arb_box(span: f64) -> impl Strategy<Value = Aabb> {
        (prop::array::uniform3(0.0..span), prop::array::uniform3(0.0..span / 4.0)).prop_map(|(lo, d)| {
            Aabb::new([lo[0], lo[1], lo[2]].into(), [lo[0] + d[0], lo[1] + d[1], lo[2] + d[2]].into())
        })
    }

    proptest! {
        /// A closed subtree (all in its node's block) is not walked below,
        /// and every packing's reads equal those of walking every node met.
        #[test]
        fn block_reads_skip_closed_subtrees_and_count_the_same(
            boxes in prop::collection::vec(arb_box(100.0), 1..120),
            queries in prop::collection::vec(arb_box(140.0), 1..40),
            sizes in prop::collection::vec(40usize..400, 240),
            piece in 100usize..1000,
        ) {
            let params = BuildParams { method: Method::Moa, leaf: LeafRule::Objects(3), ..BuildParams::paper() };
            let tree = build(&boxes, None, &params, &|_| {}).unwrap();
            let sizes = &sizes[..tree.nodes.len()];
            let children = |i: usize| tree.nodes[i].children().map(|c| c.map(|x| x.index()));
            let p = layout::pack(sizes, children, 1000, piece);
            let walk = BlockWalk::new(&tree, &p);
            let reads = walk.reads_per_block(&queries);
            prop_assert_eq!(&reads, &every_node_walk(&tree, &p, &queries));
            // The scratch buffers carry over from query to query, as in the read model.
            let (mut stack, mut blocks) = (Vec::new(), Vec::new());
            for q in &queries {
                let one = every_node_walk(&tree, &p, std::slice::from_ref(q));
                prop_assert_eq!(walk.blocks_read(q, &mut stack, &mut blocks), one.iter().filter(|&&r| r > 0).count());
            }
        }
    }
}
