//! The depth-first engine under every builder and under LAA's trial
//! subtrees (the recursion of `wDivideList`, MOA1/LAA1, and of
//! `wDivideListTrial`, LAA3).
//!
//! Why not plain recursion: a low rate R lets a cut peel a handful of
//! objects off a node, so a tree can be as deep as it has objects, and a
//! recursive builder would overflow the stack. The engine keeps pending
//! right siblings on a heap stack instead and recurses only to hand a pair
//! of big siblings (each at least [`PAR_MIN`] objects) to `rayon::join`,
//! which bounds that recursion by N / `PAR_MIN`. Which pairs go parallel
//! depends on sizes only, never on the number of threads, so outputs are
//! identical for any pool.

/// Below this many objects a node's work stays on one thread.
pub(crate) const PAR_MIN: usize = 4096;

/// A depth-first walk over a tree of splits, left subtree first.
pub(crate) trait Walk: Sync {
    /// A node's objects.
    type Set: Send;
    /// What the walk produces.
    type Out: Send;
    /// What `visit` leaves for `right_begins` and `splice` about a node.
    type Mark: Send;

    /// Objects in a set.
    fn len(&self, set: &Self::Set) -> usize;
    /// An empty output.
    fn start(&self) -> Self::Out;
    /// Records the node of `set` at `depth` into `out`; returns its two
    /// parts if it is to be divided.
    fn visit(
        &self,
        set: Self::Set,
        depth: u32,
        out: &mut Self::Out,
    ) -> Option<(Self::Set, Self::Set, Self::Mark)>;
    /// Called when the walk, having finished the left subtree of the node
    /// marked `mark`, starts on its right one.
    fn right_begins(&self, out: &mut Self::Out, mark: Self::Mark);
    /// Appends the outputs of both subtrees of the node marked `mark`, just
    /// recorded, walked apart.
    fn splice(&self, out: &mut Self::Out, mark: Self::Mark, left: Self::Out, right: Self::Out);
}

/// A pending step: a left subtree, or a right one after its sibling.
enum Task<S, M> {
    Enter(S, u32),
    Right(S, u32, M),
}

/// Walks the tree rooted at `set`, at `depth`.
pub(crate) fn walk<W: Walk>(w: &W, set: W::Set, depth: u32) -> W::Out {
    let mut out = w.start();
    let mut stack = vec![Task::Enter(set, depth)];
    while let Some(task) = stack.pop() {
        let (set, depth) = match task {
            Task::Enter(set, depth) => (set, depth),
            Task::Right(set, depth, mark) => {
                w.right_begins(&mut out, mark);
                (set, depth)
            }
        };
        if let Some((left, right, mark)) = w.visit(set, depth, &mut out) {
            if w.len(&left).min(w.len(&right)) >= PAR_MIN {
                let (a, b) = rayon::join(|| walk(w, left, depth + 1), || walk(w, right, depth + 1));
                w.splice(&mut out, mark, a, b);
            } else {
                stack.push(Task::Right(right, depth + 1, mark));
                stack.push(Task::Enter(left, depth + 1));
            }
        }
    }
    out
}

/// `(a(), b())`, the two on rayon when `par`.
pub(crate) fn join_if<A: Send, B: Send>(
    par: bool,
    a: impl FnOnce() -> A + Send,
    b: impl FnOnce() -> B + Send,
) -> (A, B) {
    if par { rayon::join(a, b) } else { (a(), b()) }
}
