//! Fetching ahead over a network (docs/object-storage.md, "Fetching
//! ahead"): when a step must go to the device, the blocks the waiting steps
//! will read go with it, then round by round the node blocks below those,
//! with the geometry of the objects their leaves leave undecided, each
//! round in one round trip. The blocks the traversal reads and counts are
//! unchanged.

use super::*;

/// The most blocks fetched ahead of one read: enough for a 20% box on
/// ship 10^6 (243 reads) to wait 7 round trips, not 72 as with 64
/// (docs/object-storage.md, "Fetching ahead"); the device keeps at most
/// half its cache of them.
pub(super) const AHEAD_MAX: usize = 1024;

/// A block a waiting step will read: a node block, entered at record `at`
/// with box `frame`, or a geometry block (id, checksum).
pub(super) enum Ahead {
    Node { at: RecordRef, frame: Aabb, inside: bool },
    Geometry((u32, u32)),
}

impl Ahead {
    fn block(&self) -> (u32, u32) {
        match self {
            Ahead::Node { at, .. } => (at.block, at.checksum),
            Ahead::Geometry(b) => *b,
        }
    }
}

impl<S: Selection> Select<'_, S> {
    /// When `next` must read a block from the device that was not fetched
    /// ahead, has the device fetch the blocks the waiting steps will read too
    /// (the soonest first), and then, round by round, the node blocks below
    /// those fetched that the query meets: a round trip per level of node
    /// blocks, not per block, up to [`AHEAD_MAX`] blocks. Reads are counted
    /// as the steps make them, the same blocks as without this.
    pub(super) fn fetch_ahead(&mut self, next: &Queued) {
        let mut ahead = Vec::new();
        self.blocks_of(&next.step, &mut ahead);
        let needed = self.txn.unread(&ahead.iter().map(Ahead::block).collect::<Vec<_>>(), &self.reads);
        if needed.iter().all(|id| self.fetched_ahead.contains(id)) {
            return;
        }
        let mut waiting: Vec<&Queued> = self.heap.iter().collect();
        waiting.sort_unstable_by(|a, b| b.cmp(a));
        for q in waiting {
            if ahead.len() >= AHEAD_MAX {
                break;
            }
            self.blocks_of(&q.step, &mut ahead);
        }
        let mut fetched = 0;
        while !ahead.is_empty() && fetched < AHEAD_MAX {
            let wanted: Vec<(u32, u32)> = ahead.iter().map(Ahead::block).collect();
            let mut ids = self.txn.unread(&wanted, &self.reads);
            ids.retain(|id| !self.fetched_ahead.contains(id));
            ids.truncate(AHEAD_MAX - fetched);
            // A device that could not keep them all: looking into them
            // would fetch them again.
            if ids.is_empty() || !self.txn.fetch_ahead(&ids) {
                break;
            }
            fetched += ids.len();
            self.fetched_ahead.extend(ids.iter().copied());
            let round: rustc_hash::FxHashSet<u32> = ids.into_iter().collect();
            let mut below = Vec::new();
            for a in &ahead {
                if let Ahead::Node { at, frame, inside } = a
                    && round.contains(&at.block)
                    && let Some(block) = self.txn.peek_node(at.block, at.checksum)
                {
                    self.blocks_below(&block, at.offset, *frame, *inside, &mut below);
                }
            }
            ahead = below;
        }
    }

    /// What `step` reads: a child's node block, the geometry of an undecided
    /// object's part, or for a record in hand, the node blocks below it that
    /// the query meets. A record that fails to decode adds nothing: its
    /// step, if it runs, reports it.
    fn blocks_of(&self, step: &Step, out: &mut Vec<Ahead>) {
        match step {
            Step::Unread { at, frame, inside, .. } if at.block != 0 => {
                out.push(Ahead::Node { at: *at, frame: *frame, inside: *inside })
            }
            Step::Node { block, offset, frame, inside, .. } => {
                self.blocks_below(block, *offset, *frame, *inside, out)
            }
            Step::Exact { block, offset, index, .. } => {
                let Ok(NodeView::Leaf(leaf)) = view(block, *offset) else { return };
                let decided = leaf.object(*index).is_none_or(|o| self.done.contains(&o.object_id));
                if !decided && let Ok(blocks) = self.txn.object_blocks(block.id, &leaf, *index) {
                    out.extend(blocks.into_iter().map(Ahead::Geometry));
                }
            }
            _ => {}
        }
    }

    /// The node blocks below record `offset` of `block` (box `frame`) that
    /// the query will read: its descendants in the block are tested as
    /// [`step`](Self::step) tests them. A record that fails to decode adds
    /// nothing here; its step reports it.
    fn blocks_below(&self, block: &Block, offset: u32, frame: Aabb, inside: bool, out: &mut Vec<Ahead>) {
        let mut stack = vec![(offset, frame, inside)];
        let mut records = 0;
        while let Some((offset, frame, inside)) = stack.pop() {
            // A block's records form a tree, each named once: a forged block
            // naming one record twice stops here.
            records += 1;
            if records > block.records.len() || out.len() >= AHEAD_MAX {
                return;
            }
            let Ok(record) = view(block, offset) else { continue };
            let frame = record.frame(frame);
            let n = match record {
                NodeView::Internal(n) => n,
                NodeView::Leaf(leaf) => {
                    self.geometry_below(block, &leaf, &frame, inside, out);
                    continue;
                }
            };
            for i in 0..2 {
                let Some(qb) = n.child_box(i, &frame) else { continue };
                if !inside && !self.sel.may_meet_box(&qb.outer) {
                    continue;
                }
                let (at, inside) = (n.child_ref(i), inside || self.sel.holds_box(&qb.outer));
                match at.block {
                    0 => stack.push((at.offset, qb.outer, inside)),
                    _ => out.push(Ahead::Node { at, frame: qb.outer, inside }),
                }
            }
        }
    }

    /// The geometry blocks of the objects of `leaf` (in `block`, box
    /// `frame`) that the traversal will test exactly: those its box and
    /// bounds leave undecided (`step.rs`'s verdict), at level M, each in
    /// one part. An entry
    /// that fails to decode adds nothing; its step reports it.
    fn geometry_below(
        &self,
        block: &Block,
        leaf: &LeafView,
        frame: &Aabb,
        inside: bool,
        out: &mut Vec<Ahead>,
    ) {
        if inside || self.k != self.m {
            return;
        }
        let mut j = 0;
        while j < leaf.len() && out.len() < AHEAD_MAX {
            let Some(id) = leaf.object(j).map(|o| o.object_id) else { return };
            let mut end = j + 1;
            while leaf.object(end).is_some_and(|o| o.object_id == id) {
                end += 1;
            }
            let mut pending = Vec::new();
            // One part that proves contact decides the object unread.
            let mut decided = self.done.contains(&id);
            for i in j..end {
                let Some(qb) = leaf.object(i).and_then(|o| QuantBox::decode(frame, o.qbox)) else { return };
                match self.verdict(block.id(), leaf, i, &qb, false) {
                    Ok(step::Verdict::Pending(..)) => pending.push(i),
                    Ok(step::Verdict::Inside | step::Verdict::Face | step::Verdict::Cell(..)) => {
                        decided = true
                    }
                    Ok(step::Verdict::Misses | step::Verdict::VoxelsMiss(..)) => {}
                    Err(_) => return,
                }
            }
            // An object stored as parts is decided by whichever part meets
            // the query first: which parts are read is known only then.
            if !decided && pending.len() == 1 {
                for i in pending {
                    let Ok(blocks) = self.txn.object_blocks(block.id(), leaf, i) else { return };
                    out.extend(blocks.into_iter().map(Ahead::Geometry));
                }
            }
            j = end;
        }
    }
}
