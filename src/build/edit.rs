//! Changes to a built tree one object at a time, as an R-tree makes them:
//! an insert goes down to the leaf whose box grows least and a leaf that no
//! longer fits its page is split by the tree's own method (a bulk load of
//! the leaf's objects); a delete removes its leaf when it empties and
//! merges a leaf into its sibling leaf when both fit one page. Boxes and
//! split records are refitted on the path, so the result is a valid
//! hierarchy ([`Hierarchy::validate`]) of the live objects.

use super::leaf::Leaf;
use super::{BuildError, BuildParams, Hierarchy, HierarchyError, Node, NodeId, NodeKind, Split, build};
use crate::geom::Aabb;
use crate::scene::ObjectId;

/// A node of the tree being changed (an arena slot).
#[derive(Debug, Clone)]
struct Slot {
    aabb: Aabb,
    parent: Option<usize>,
    kind: Kind,
}

#[derive(Debug, Clone)]
enum Kind {
    Leaf(Vec<u32>),
    Internal([usize; 2], Split),
    Vacant,
}

/// A hierarchy open for inserts and deletes. Objects are named by the
/// number [`TreeEdit::insert`] gave them (the ids of the tree it started
/// from keep their numbers); a removed object's number is not reused.
#[derive(Debug, Clone)]
pub(crate) struct TreeEdit {
    params: BuildParams,
    boxes: Vec<Aabb>,
    sizes: Vec<u64>,
    /// Per object: its leaf, `None` once removed.
    leaf_of: Vec<Option<usize>>,
    nodes: Vec<Slot>,
    vacant: Vec<usize>,
    root: Option<usize>,
}

impl TreeEdit {
    /// An empty tree that will be built with `params`.
    pub(crate) fn empty(params: BuildParams) -> TreeEdit {
        TreeEdit {
            params,
            boxes: Vec::new(),
            sizes: Vec::new(),
            leaf_of: Vec::new(),
            nodes: Vec::new(),
            vacant: Vec::new(),
            root: None,
        }
    }

    /// `tree` over objects of exact `boxes` and `sizes` (by id). Its boxes
    /// and split records are recomputed from `boxes`, so a tree read back
    /// with quantized boxes becomes exact again.
    pub(crate) fn from_hierarchy(
        tree: &Hierarchy,
        boxes: Vec<Aabb>,
        sizes: Vec<u64>,
        params: BuildParams,
    ) -> Result<TreeEdit, HierarchyError> {
        let mut edit = TreeEdit { leaf_of: vec![None; boxes.len()], boxes, sizes, ..TreeEdit::empty(params) };
        if tree.nodes.is_empty() {
            return Ok(edit);
        }
        tree.check_layout()?;
        edit.nodes = vec![Slot { aabb: Aabb::EMPTY, parent: None, kind: Kind::Vacant }; tree.nodes.len()];
        for (i, node) in tree.nodes.iter().enumerate() {
            edit.nodes[i].kind = match &node.kind {
                NodeKind::Leaf { objects } => {
                    for &object in objects {
                        let node = NodeId(i as u32);
                        let slot = edit.leaf_of.get_mut(object.index());
                        *slot.ok_or(HierarchyError::UnknownObject { node, object })? = Some(i);
                    }
                    Kind::Leaf(objects.iter().map(|o| o.0).collect())
                }
                NodeKind::Internal { children, split } => {
                    // check_layout: every child is a node reached once.
                    for c in children {
                        edit.nodes[c.index()].parent = Some(i);
                    }
                    Kind::Internal(children.map(NodeId::index), *split)
                }
            };
        }
        edit.root = Some(0);
        // Preorder: children come after their parent.
        for i in (0..tree.nodes.len()).rev() {
            edit.refit(i);
        }
        Ok(edit)
    }

    /// Live objects.
    pub(crate) fn len(&self) -> usize {
        self.leaf_of.iter().filter(|l| l.is_some()).count()
    }

    /// Adds an object of box `aabb` and stored size `size`; returns its number.
    pub(crate) fn insert(&mut self, aabb: Aabb, size: u64) -> Result<u32, BuildError> {
        let object = u32::try_from(self.boxes.len())
            .map_err(|_| BuildError::TooManyObjects { objects: self.boxes.len(), max: u32::MAX as usize })?;
        self.boxes.push(aabb);
        self.sizes.push(size);
        let Some(mut at) = self.root else {
            let leaf = self.alloc(Slot { aabb, parent: None, kind: Kind::Leaf(vec![object]) });
            self.root = Some(leaf);
            self.leaf_of.push(Some(leaf));
            return Ok(object);
        };
        while let Kind::Internal(children, _) = &self.nodes[at].kind {
            at = *children
                .iter()
                .min_by(|&&a, &&b| {
                    growth(&self.nodes[a].aabb, &aabb).total_cmp(&growth(&self.nodes[b].aabb, &aabb))
                })
                .unwrap_or(&children[0]);
        }
        if let Kind::Leaf(objects) = &mut self.nodes[at].kind {
            objects.push(object);
        }
        self.leaf_of.push(Some(at));
        self.refit_up(at);
        self.split_if_over(at)?;
        Ok(object)
    }

    /// Removes object `object`; false if it is not in the tree.
    pub(crate) fn remove(&mut self, object: u32) -> bool {
        let Some(leaf) = self.leaf_of.get_mut(object as usize).and_then(Option::take) else { return false };
        if let Kind::Leaf(objects) = &mut self.nodes[leaf].kind {
            objects.retain(|&o| o != object);
            if objects.is_empty() {
                self.detach(leaf);
                return true;
            }
        }
        self.refit_up(leaf);
        self.merge_with_sibling(leaf);
        true
    }

    /// The tree in preorder with objects renumbered by `ids` (a live
    /// object's number to its id in the scene that is written).
    pub(crate) fn to_hierarchy(&self, ids: &[Option<ObjectId>]) -> Hierarchy {
        let mut nodes = Vec::with_capacity(self.nodes.len() - self.vacant.len());
        let Some(root) = self.root else { return Hierarchy { nodes } };
        // (arena index, level, where the parent wants the child's id).
        let mut stack = vec![(root, 0u32, None::<(usize, usize)>)];
        while let Some((at, level, link)) = stack.pop() {
            let id = NodeId(nodes.len() as u32);
            if let Some((parent, side)) = link
                && let NodeKind::Internal { children, .. } = &mut nodes[parent].kind
            {
                children[side] = id;
            }
            let slot = &self.nodes[at];
            let kind = match &slot.kind {
                Kind::Leaf(objects) => {
                    let mut objects: Vec<ObjectId> =
                        objects.iter().filter_map(|&o| ids.get(o as usize).copied().flatten()).collect();
                    objects.sort_unstable();
                    NodeKind::Leaf { objects }
                }
                Kind::Internal(children, split) => {
                    // Right pushed first so the left subtree comes first.
                    stack.push((children[1], level + 1, Some((id.index(), 1))));
                    stack.push((children[0], level + 1, Some((id.index(), 0))));
                    NodeKind::Internal { children: [NodeId(u32::MAX); 2], split: *split }
                }
                Kind::Vacant => continue,
            };
            nodes.push(Node { aabb: slot.aabb, level, kind });
        }
        Hierarchy { nodes }
    }

    fn alloc(&mut self, slot: Slot) -> usize {
        match self.vacant.pop() {
            Some(i) => {
                self.nodes[i] = slot;
                i
            }
            None => {
                self.nodes.push(slot);
                self.nodes.len() - 1
            }
        }
    }

    fn free(&mut self, i: usize) {
        self.nodes[i] = Slot { aabb: Aabb::EMPTY, parent: None, kind: Kind::Vacant };
        self.vacant.push(i);
    }

    fn leaf_rule(&self) -> Result<Leaf<'_>, BuildError> {
        Leaf::new(self.params.leaf, Some(&self.sizes))
    }

    /// Recomputes node `i`'s box (and split) from its children or objects.
    fn refit(&mut self, i: usize) {
        let (aabb, kind) = match &self.nodes[i].kind {
            Kind::Leaf(objects) => {
                (objects.iter().fold(Aabb::EMPTY, |b, &o| b.union(&self.boxes[o as usize])), None)
            }
            Kind::Internal([a, b], split) => {
                let (l, r) = (self.nodes[*a].aabb, self.nodes[*b].aabb);
                (l.union(&r), Some(Kind::Internal([*a, *b], split.refit(&l, &r))))
            }
            Kind::Vacant => return,
        };
        self.nodes[i].aabb = aabb;
        if let Some(kind) = kind {
            self.nodes[i].kind = kind;
        }
    }

    fn refit_up(&mut self, mut i: usize) {
        loop {
            self.refit(i);
            match self.nodes[i].parent {
                Some(p) => i = p,
                None => return,
            }
        }
    }

    /// Splits leaf `leaf` by the tree's method when it no longer fits a page.
    fn split_if_over(&mut self, leaf: usize) -> Result<(), BuildError> {
        let Kind::Leaf(objects) = &self.nodes[leaf].kind else { return Ok(()) };
        if self.leaf_rule()?.fits(objects) {
            return Ok(());
        }
        let objects = objects.clone();
        let boxes: Vec<Aabb> = objects.iter().map(|&o| self.boxes[o as usize]).collect();
        let sizes: Vec<u64> = objects.iter().map(|&o| self.sizes[o as usize]).collect();
        let sub = build(&boxes, Some(&sizes), &self.params, &|_| {})?;
        // Graft: sub's root takes the leaf's place, the rest get new slots.
        let mut at = vec![leaf];
        for _ in 1..sub.nodes.len() {
            at.push(self.alloc(Slot { aabb: Aabb::EMPTY, parent: None, kind: Kind::Vacant }));
        }
        for (i, node) in sub.nodes.iter().enumerate() {
            let kind = match &node.kind {
                NodeKind::Leaf { objects: local } => {
                    let mine: Vec<u32> = local.iter().map(|o| objects[o.index()]).collect();
                    for &o in &mine {
                        self.leaf_of[o as usize] = Some(at[i]);
                    }
                    Kind::Leaf(mine)
                }
                NodeKind::Internal { children, split } => {
                    for c in children {
                        self.nodes[at[c.index()]].parent = Some(at[i]);
                    }
                    Kind::Internal(children.map(|c| at[c.index()]), *split)
                }
            };
            self.nodes[at[i]].kind = kind;
            self.nodes[at[i]].aabb = node.aabb;
        }
        Ok(())
    }

    /// Takes empty leaf `leaf` out: its sibling takes its parent's place.
    fn detach(&mut self, leaf: usize) {
        let parent = self.nodes[leaf].parent;
        self.free(leaf);
        let Some(p) = parent else {
            self.root = None;
            return;
        };
        let Kind::Internal(children, _) = self.nodes[p].kind else { return };
        let sibling = if children[0] == leaf { children[1] } else { children[0] };
        let grand = self.nodes[p].parent;
        self.nodes[sibling].parent = grand;
        match grand {
            None => self.root = Some(sibling),
            Some(g) => {
                if let Kind::Internal(c, _) = &mut self.nodes[g].kind {
                    for x in c.iter_mut().filter(|x| **x == p) {
                        *x = sibling;
                    }
                }
                self.refit_up(g);
            }
        }
        self.free(p);
    }

    /// Condensing: leaf `leaf` and its sibling leaf become one leaf, their
    /// parent, when their objects fit one page together.
    fn merge_with_sibling(&mut self, leaf: usize) {
        let Some(p) = self.nodes[leaf].parent else { return };
        let Kind::Internal([a, b], _) = self.nodes[p].kind else { return };
        let (Kind::Leaf(x), Kind::Leaf(y)) = (&self.nodes[a].kind, &self.nodes[b].kind) else { return };
        let merged: Vec<u32> = x.iter().chain(y).copied().collect();
        if !self.leaf_rule().is_ok_and(|rule| rule.fits(&merged)) {
            return;
        }
        for &o in &merged {
            self.leaf_of[o as usize] = Some(p);
        }
        self.nodes[p].kind = Kind::Leaf(merged);
        self.free(a);
        self.free(b);
        self.refit_up(p);
    }
}

/// How much worse `node` gets by taking `object`: the volume it grows by,
/// then (for flat boxes, whose volume does not move) the half-perimeter.
fn growth(node: &Aabb, object: &Aabb) -> f64 {
    let union = node.union(object);
    let half_perimeter = |b: &Aabb| {
        let e = b.extent();
        e.x + e.y + e.z
    };
    let dv = union.volume() - node.volume();
    let dp = half_perimeter(&union) - half_perimeter(node);
    // Volume first; perimeter growth only breaks ties (scaled far below any
    // volume difference that matters).
    dv + dp * f64::EPSILON
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::build::{LeafRule, Method};
    use crate::geom::Point;
    use proptest::prelude::*;

    fn cube(x: f64, y: f64, z: f64, s: f64) -> Aabb {
        Aabb::new(Point::new(x, y, z), Point::new(x + s, y + s, z + s))
    }

    fn params(method: Method, leaf: u32) -> BuildParams {
        BuildParams { method, leaf: LeafRule::Objects(leaf), ..BuildParams::paper() }
    }

    /// The hierarchy of the live objects, renumbered densely, with their boxes.
    fn live(edit: &TreeEdit) -> (Hierarchy, Vec<Aabb>, Vec<u64>) {
        let mut ids = vec![None; edit.boxes.len()];
        let (mut boxes, mut sizes) = (Vec::new(), Vec::new());
        for (o, l) in edit.leaf_of.iter().enumerate() {
            if l.is_some() {
                ids[o] = Some(ObjectId(boxes.len() as u32));
                boxes.push(edit.boxes[o]);
                sizes.push(edit.sizes[o]);
            }
        }
        (edit.to_hierarchy(&ids), boxes, sizes)
    }

    #[test]
    fn inserts_into_an_empty_tree_split_leaves_by_the_method() {
        let p = params(Method::Moa, 4);
        let mut edit = TreeEdit::empty(p.clone());
        for i in 0..40 {
            edit.insert(cube(f64::from(i % 7) * 3.0, f64::from(i / 7) * 3.0, 0.0, 1.0), 100).unwrap();
        }
        let (tree, boxes, sizes) = live(&edit);
        tree.validate(&boxes, Some(&sizes), &p).unwrap();
        assert!(tree.leaves().count() >= 10, "40 objects in leaves of 4");
    }

    #[test]
    fn deleting_everything_leaves_no_tree_and_a_delete_twice_is_refused() {
        let p = params(Method::Moa, 3);
        let mut edit = TreeEdit::empty(p.clone());
        let ids: Vec<u32> =
            (0..10).map(|i| edit.insert(cube(f64::from(i), 0.0, 0.0, 0.5), 1).unwrap()).collect();
        for &o in &ids {
            assert!(edit.remove(o));
            let (tree, boxes, sizes) = live(&edit);
            if !boxes.is_empty() {
                tree.validate(&boxes, Some(&sizes), &p).unwrap();
            }
        }
        assert!(!edit.remove(ids[0]));
        assert_eq!(edit.len(), 0);
        assert!(live(&edit).0.nodes.is_empty());
    }

    #[test]
    fn a_tree_read_back_with_loose_boxes_is_refitted_exactly() {
        let p = params(Method::Moa, 2);
        let boxes: Vec<Aabb> = (0..9).map(|i| cube(f64::from(i) * 2.0, 0.0, 0.0, 1.0)).collect();
        let sizes = vec![1; boxes.len()];
        let mut tree = build(&boxes, Some(&sizes), &p, &|_| {}).unwrap();
        for n in &mut tree.nodes {
            n.aabb = n.aabb.grown(0.25);
        }
        let edit = TreeEdit::from_hierarchy(&tree, boxes.clone(), sizes.clone(), p.clone()).unwrap();
        let (back, _, _) = live(&edit);
        back.validate(&boxes, Some(&sizes), &p).unwrap();
    }

    proptest! {
        /// Any sequence of inserts and deletes keeps a valid tree of exactly
        /// the live objects, for every method that splits leaves.
        #[test]
        fn random_changes_keep_a_valid_tree(
            method in prop::sample::select(vec![Method::Moa, Method::Laa, Method::Refine, Method::Median, Method::Sah]),
            leaf in 1u32..6,
            ops in prop::collection::vec((any::<bool>(), 0u32..40, 0.0f64..50.0, 0.0f64..50.0, 0.0f64..4.0), 1..120),
        ) {
            let p = params(method, leaf);
            let mut edit = TreeEdit::empty(p.clone());
            let mut alive: Vec<u32> = Vec::new();
            for (insert, pick, x, y, s) in ops {
                if insert || alive.is_empty() {
                    alive.push(edit.insert(cube(x, y, x * 0.5, s), 10).unwrap());
                } else {
                    let o = alive.swap_remove(pick as usize % alive.len());
                    prop_assert!(edit.remove(o));
                }
                prop_assert_eq!(edit.len(), alive.len());
                let (tree, boxes, sizes) = live(&edit);
                if !boxes.is_empty() {
                    prop_assert!(tree.validate(&boxes, Some(&sizes), &p).is_ok(), "{:?}", tree.validate(&boxes, Some(&sizes), &p));
                }
            }
        }
    }
}
