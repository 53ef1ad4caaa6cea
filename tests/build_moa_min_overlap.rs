//! Every internal node of an MOA tree is cut where MOA2 says: the cut of
//! least overlap over the six orders (x-min, x-max, y-min, y-max, z-min,
//! z-max; ties by id) within the rate's range, chosen by the tie-break
//! rule. Checked against an independent quadratic search in the style of
//! the paper's `SearchMax`/`SearchMin`, on random small scenes.

mod common;

use common::arb_boxes;

use mktree::bulk::{BuildParams, Hierarchy, LeafRule, Method, NodeId, Order, TieBreak, build};
use mktree::geom::Aabb;
use proptest::prelude::*;

/// The objects under `node`, sorted by id.
fn objects_under(tree: &Hierarchy, node: NodeId) -> Vec<u32> {
    let mut out = Vec::new();
    let mut stack = vec![node];
    while let Some(id) = stack.pop() {
        let n = &tree.nodes[id.index()];
        match (n.children(), n.objects()) {
            (Some([a, b]), _) => stack.extend([a, b]),
            (None, Some(objects)) => out.extend(objects.iter().map(|o| o.0)),
            (None, None) => unreachable!(),
        }
    }
    out.sort_unstable();
    out
}

/// The brute-force choice of cut.
struct Choice {
    /// The tie-break rule's key: smaller is better.
    key: (f64, usize),
    /// Order 0..6: x-min, x-max, y-min, ...
    order: usize,
    /// The first part, sorted by id.
    first: Vec<u32>,
    /// MOA2's raw overlap.
    gap: f64,
}

/// The cut of least overlap by exhaustive search.
fn brute_force(boxes: &[Aabb], objects: &[u32], rate: f64, tie: TieBreak) -> Choice {
    let n = objects.len();
    // The documented range: k = ⌊R·N⌋, Icut in [k, N-1-k] ∩ [0, N-2], or
    // the middle cut when that is empty.
    let k = (((rate * n as f64) * (1.0 + 1e-12)).floor() as usize).min(n / 2);
    let (lo, hi) = (k.min(n - 2), (n - 1 - k).min(n - 2));
    let (lo, hi) = if lo > hi { (n / 2 - 1, n / 2 - 1) } else { (lo, hi) };
    let clamp = |g: f64| g.max(0.0);
    // Lexicographic key per rule; the first minimum wins.
    let key = |gap: f64, cut: usize| -> (f64, usize) {
        match tie {
            TieBreak::FirstFound => (clamp(gap), 0),
            TieBreak::WidestGap => (gap, 0),
            TieBreak::MostBalanced => (clamp(gap), (2 * (cut + 1)).abs_diff(n)),
        }
    };
    let mut best: Option<Choice> = None;
    for o in 0..6 {
        let axis = o / 2;
        let coord =
            |j: u32| if o % 2 == 0 { boxes[j as usize].min[axis] } else { boxes[j as usize].max[axis] };
        let mut sorted = objects.to_vec();
        sorted.sort_by(|&a, &b| coord(a).total_cmp(&coord(b)).then(a.cmp(&b)));
        for cut in lo..=hi {
            let max =
                sorted[..=cut].iter().map(|&j| boxes[j as usize].max[axis]).fold(f64::NEG_INFINITY, f64::max);
            let min =
                sorted[cut + 1..].iter().map(|&j| boxes[j as usize].min[axis]).fold(f64::INFINITY, f64::min);
            let gap = max - min;
            let k = key(gap, cut);
            if best.as_ref().is_none_or(|b| k < b.key) {
                let mut first = sorted[..=cut].to_vec();
                first.sort_unstable();
                best = Some(Choice { key: k, order: o, first, gap });
            }
        }
    }
    best.unwrap()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    #[test]
    fn every_moa_split_is_a_brute_force_minimum_overlap_cut(
        boxes in arb_boxes(2, 90),
        rate in prop_oneof![Just(0.0), Just(0.5), 0.0f64..=0.5],
        mem_page in 1u32..8,
        tie in prop::sample::select(TieBreak::ALL.to_vec()),
    ) {
        let params = BuildParams { method: Method::Moa, rate, leaf: LeafRule::Objects(mem_page), tie_break: tie, ..BuildParams::paper() };
        let tree = build(&boxes, None, &params, &|_| {}).unwrap();
        for (i, node) in tree.nodes.iter().enumerate() {
            let (Some(split), Some([left, _])) = (node.split(), node.children()) else { continue };
            let objects = objects_under(&tree, NodeId(i as u32));
            let Choice { order: o, first, gap, .. } = brute_force(&boxes, &objects, rate, tie);
            let order = if o % 2 == 0 { Order::Min } else { Order::Max };
            prop_assert_eq!((split.axis.index(), split.order), (o / 2, order), "node {}", i);
            prop_assert_eq!(split.gap, gap, "node {}", i);
            prop_assert_eq!(split.overlap, gap.max(0.0), "node {}", i);
            prop_assert_eq!(objects_under(&tree, left), first, "node {}", i);
        }
    }
}
