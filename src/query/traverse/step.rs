//! One step of the traversal's queue (paper §1.5): reading a record,
//! deciding a record's children and a leaf's objects by the coarsest
//! bound that can, and testing an object's exact geometry at level M.

use std::sync::Arc;

use super::*;

/// What a leaf record alone says of one entry (an object or a part):
/// the coarsest proof its box and stored bound give, or that its geometry
/// must be read (the level and error of the finest bound passed).
pub(super) enum Verdict {
    /// A subtree's box holding it lies inside the query.
    Inside,
    /// Its box misses the query.
    Misses,
    /// The query holds a face of its box.
    Face,
    /// Its voxel bound (level) misses the query.
    VoxelsMiss(u8, Voxels),
    /// The query holds a surface cell of its voxel bound (level).
    Cell(u8, Voxels),
    /// Undecided: level, error and bound of the finest bound passed.
    Pending(u8, f64, Option<Voxels>),
}

impl<S: Selection> Select<'_, S> {
    /// What entry `i` of `leaf` (in block `block`, stored box `qb`) is by
    /// its box and bounds, without reading anything.
    pub(super) fn verdict(
        &self,
        block: u32,
        leaf: &LeafView,
        i: usize,
        qb: &QuantBox,
        inside: bool,
    ) -> Result<Verdict, StorageError> {
        let aabb = qb.outer;
        if inside {
            return Ok(Verdict::Inside);
        }
        if !self.sel.may_meet_box(&aabb) {
            return Ok(Verdict::Misses);
        }
        if qb.face_slabs().iter().any(|f| self.sel.holds_box(f)) {
            return Ok(Verdict::Face);
        }
        let Some(b) = finest(leaf.bounds(), i as u16, self.bound_level) else {
            return Ok(Verdict::Pending(1, aabb.extent().norm(), None));
        };
        let v = self.voxels(block, &b, &aabb)?;
        Ok(if !self.sel.may_meet_voxels(&v) {
            Verdict::VoxelsMiss(b.level, v)
        } else if self.sel.confirms_voxels(&v) {
            Verdict::Cell(b.level, v)
        } else {
            Verdict::Pending(b.level, v.grid().max_cell_diagonal(), Some(v))
        })
    }

    /// The voxel set of bound `b`, whose target's box is `outer`.
    pub(super) fn voxels(&self, block: u32, b: &BoundView, outer: &Aabb) -> Result<Voxels, StorageError> {
        let lattice = self
            .txn
            .lattice()
            .ok_or_else(|| StorageError::corrupt(block, "bounds", "no lattice in the meta block"))?;
        crate::lod::decode(b.blob, &lattice, outer)
            .map_err(|e| StorageError::corrupt(block, "bounds", e.to_string()))
    }

    pub(super) fn step(&mut self, step: Step) -> Result<(), StorageError> {
        match step {
            Step::Unread { at, frame, inside, name, .. } => {
                let block = self.txn.block(
                    at.block,
                    crate::store::format::frame::BlockType::Node,
                    at.checksum,
                    &mut self.reads,
                )?;
                let name = NodeName { id: Some(view(&block, at.offset)?.node_id()), ..name };
                self.push(Step::Node { block, offset: at.offset, frame, inside, name })
            }
            Step::Node { block, offset, frame, inside, name } => {
                // With a budget, a record with group bounds is shown by its
                // finest first, and refined from there (Step::Group).
                if self.budget.is_some() && !inside {
                    let (levels, cost) = self.group_levels(&block, offset, &frame)?;
                    if let Some(&(level, eps)) = levels.last()
                        && !self.over_budget(cost)
                        && let Some(voxels) =
                            self.txn.group_bound(&block, offset, &frame, level, &mut self.reads)?
                    {
                        let frame = view(&block, offset)?.frame(frame);
                        return self.push(Step::Group { block, offset, frame, name, level, eps, voxels });
                    }
                }
                self.node(block, offset, frame, inside)
            }
            Step::Group { block, offset, frame, .. } => {
                self.refining = true;
                let done = self.node(block, offset, frame, false);
                self.refining = false;
                done
            }
            Step::Exact { block, offset, index, part, whole, key, .. } => {
                let NodeView::Leaf(leaf) = view(&block, offset)? else { return Ok(()) };
                let Some(o) = leaf.object(index) else { return Ok(()) };
                // Another part of the object already decided it: this one need
                // not be read, unless the query draws every part.
                let draws = self.sel.tolerance().is_some();
                if self.done.contains(&o.object_id) && !draws {
                    return Ok(());
                }
                let leaf_id = view(&block, offset)?.node_id();
                let (id, mesh) = self.txn.read_object(block.id(), &leaf, index, &mut self.reads)?;
                self.stats.geometry_tests += 1;
                let n = &mut self.stats.triangles_tested;
                let distance = match &self.rank {
                    Some(rank) => rank.mesh_distance(&mesh, n),
                    None => self.sel.meets_mesh(&mesh, n).then_some(0.0),
                };
                let hit = distance.is_some();
                self.seen((leaf_id, id.0, part), (self.m, hit, Proof::Exact), None, Some(&mesh))?;
                let left = self.parts.entry(id.0).or_insert(1);
                *left = left.saturating_sub(1);
                let last = *left == 0;
                let done = self.done.contains(&id.0);
                match distance {
                    Some(distance) if self.rank.is_some() => {
                        self.found.insert(id.0);
                        self.push(Step::Found { object: id.0, aabb: whole, key, distance })?;
                    }
                    Some(_) if !done => self.decide((id.0, whole, key), (self.m, true, Proof::Exact), None),
                    Some(_) => {}
                    None if last && !done && !self.found.contains(&id.0) => {
                        self.decide((id.0, whole, key), (self.m, false, Proof::Exact), None);
                    }
                    None => {}
                }
                Ok(())
            }
            Step::Found { object, aabb, key, distance } => {
                // Its nearest part's distance comes first; a farther part's is dropped.
                if !self.done.contains(&object) {
                    self.decide((object, aabb, key), (self.m, true, Proof::Exact), Some(distance));
                }
                Ok(())
            }
        }
    }

    fn node(
        &mut self,
        block: Arc<Block>,
        offset: u32,
        frame: Aabb,
        inside: bool,
    ) -> Result<(), StorageError> {
        self.visits += 1;
        if self.visits > self.visit_limit {
            return Err(StorageError::corrupt(
                block.id(),
                "child_block",
                "more nodes than the meta block counts: the links loop",
            ));
        }
        self.stats.nodes_visited += 1;
        let record = view(&block, offset)?;
        // A record with a frame of its own quantizes its entries in it; the
        // parent's entry bounds that frame, so whatever the subtree holds
        // lies in every box above it (format-spec/node.md).
        if let Some(own) = record.own_frame()
            && !frame.contains(&own)
        {
            return Err(StorageError::corrupt(
                block.id(),
                "frame",
                "a record's frame leaves its parent's box",
            ));
        }
        let frame = record.frame(frame);
        if let Some(visitor) = self.visitor.as_deref_mut() {
            visitor.node(&block, offset, &frame)?;
        }
        let bad = |d: &str| StorageError::corrupt(block.id(), "record", d.to_string());
        let id = record.node_id();
        match record {
            NodeView::Internal(n) => {
                let estimate = f64::from(n.child_blocks(0).1.max(1));
                for i in (0..2).rev() {
                    let qb = n.child_box(i, &frame).ok_or_else(|| bad("a child box is backwards"))?;
                    let mut child_inside = inside;
                    if !inside {
                        if !self.sel.may_meet_box(&qb.outer) {
                            self.stats.pruned += 1;
                            continue;
                        }
                        child_inside = self.sel.holds_box(&qb.outer);
                    }
                    let at = n.child_ref(i);
                    // Preorder: the first child follows its parent.
                    let first = (i == 0 && self.txn.ids_in_preorder()).then(|| id.checked_add(1)).flatten();
                    let name = NodeName { id: first, parent: Some(id), child: i as u8 };
                    if at.block == 0 {
                        let name = NodeName { id: Some(view(&block, at.offset)?.node_id()), ..name };
                        self.push(Step::Node {
                            block: block.clone(),
                            offset: at.offset,
                            frame: qb.outer,
                            inside: child_inside,
                            name,
                        })?;
                    } else {
                        self.push(Step::Unread {
                            at,
                            frame: qb.outer,
                            inside: child_inside,
                            estimate,
                            name,
                        })?;
                    }
                }
            }
            NodeView::Leaf(leaf) => {
                self.stats.leaves_visited += 1;
                // An object larger than a geometry block is stored as parts:
                // consecutive entries of one id. One part proves contact for
                // the object; it misses only when every part does.
                // Each object's key, in the order of its first entries.
                let mut keys = leaf.keys();
                let mut j = 0;
                while j < leaf.len() {
                    let id = leaf.object(j).ok_or_else(|| bad("an object is missing"))?.object_id;
                    let mut end = j + 1;
                    while leaf.object(end).is_some_and(|o| o.object_id == id) {
                        end += 1;
                    }
                    let key = keys.next().ok_or_else(|| bad("an object has no key"))?.1.to_key();
                    self.object((&block, offset, id), &leaf, (j, end, key), &frame, inside)?;
                    j = end;
                }
            }
        }
        Ok(())
    }

    /// Decides the object of entries `parts` of `leaf` (record `offset` of
    /// `block`, box `frame`): by its boxes and bounds, or by queuing the
    /// parts whose geometry must be read.
    fn object(
        &mut self,
        (block, offset, leaf_id): (&Arc<Block>, u32, u32),
        leaf: &LeafView,
        (first, end, key): (usize, usize, Key),
        frame: &Aabb,
        inside: bool,
    ) -> Result<(), StorageError> {
        let bad = |d: &str| StorageError::corrupt(block.id(), "record", d.to_string());
        let parts = (first, end);
        let whole = object_box(leaf, parts, frame);
        // Entries left undecided: index, level and error of the finest
        // bound passed (the box's diagonal without one), box, bound.
        let mut pending: Vec<(usize, u8, f64, Aabb, Option<Voxels>)> = Vec::new();
        let (mut rejected_at, mut reject_proof) = (1u8, Proof::BoxMisses);
        let mut id = 0;
        for i in parts.0..parts.1 {
            let o = leaf.object(i).ok_or_else(|| bad("an object is missing"))?;
            id = o.object_id;
            let qb = QuantBox::decode(frame, o.qbox).ok_or_else(|| bad("an object box is backwards"))?;
            let aabb = qb.outer;
            match self.verdict(block.id(), leaf, i, &qb, inside)? {
                Verdict::Inside => {
                    self.seen((leaf_id, id, aabb), (1, true, Proof::InsideNode), None, None)?;
                    self.decide((id, whole, key.clone()), (1, true, Proof::InsideNode), None);
                    return Ok(());
                }
                Verdict::Misses => {
                    self.seen((leaf_id, id, aabb), (1, false, Proof::BoxMisses), None, None)?
                }
                Verdict::Face => {
                    self.seen((leaf_id, id, aabb), (1, true, Proof::Face), None, None)?;
                    self.decide((id, whole, key.clone()), (1, true, Proof::Face), None);
                    return Ok(());
                }
                Verdict::VoxelsMiss(level, v) => {
                    self.seen(
                        (leaf_id, id, aabb),
                        (level, false, Proof::VoxelsMiss),
                        Some((level, &v)),
                        None,
                    )?;
                    (rejected_at, reject_proof) = (rejected_at.max(level), Proof::VoxelsMiss);
                }
                Verdict::Cell(level, v) => {
                    self.seen((leaf_id, id, aabb), (level, true, Proof::Cell), Some((level, &v)), None)?;
                    self.decide((id, whole, key.clone()), (level, true, Proof::Cell), None);
                    return Ok(());
                }
                Verdict::Pending(level, eps, voxels) => pending.push((i, level, eps, aabb, voxels)),
            }
        }
        // With stand-ins, an object whose every part's bound is close enough is not read.
        let settled = pending.iter().all(|p| self.settles(&p.3, p.2));
        if pending.is_empty() {
            self.decide((id, whole, key.clone()), (rejected_at, false, reject_proof), None);
        } else if self.k == self.m && !settled {
            self.parts.insert(id, pending.len() as u32);
            for (i, level, eps, part, _) in pending {
                self.push(Step::Exact {
                    block: block.clone(),
                    offset,
                    index: i,
                    level,
                    eps,
                    part,
                    whole,
                    key: key.clone(),
                })?;
            }
        } else {
            let level = pending.iter().map(|p| p.1).max().unwrap_or(1);
            for (_, l, _, aabb, v) in &pending {
                self.seen(
                    (leaf_id, id, *aabb),
                    (*l, true, Proof::Candidate),
                    v.as_ref().map(|v| (*l, v)),
                    None,
                )?;
            }
            self.decide((id, whole, key.clone()), (level, true, Proof::Candidate), None);
        }
        Ok(())
    }
}
