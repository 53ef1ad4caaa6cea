//! Every method builds a valid hierarchy of random scenes, under both leaf
//! rules, any rate R and any tie-break: nodes in preorder with consistent
//! levels, every object in exactly one leaf, every node's box the exact
//! union of its objects' boxes, leaves within the page, split records
//! matching the children (all checked by `Hierarchy::validate`).

mod common;

use common::arb_boxes;

use mktree::bulk::{BuildParams, LeafRule, LookAhead, Method, QueryExtent, TieBreak, build};
use proptest::prelude::*;

fn params() -> impl Strategy<Value = BuildParams> {
    (
        prop::sample::select(Method::ALL.to_vec()),
        prop_oneof![Just(0.0), Just(0.5), 0.0f64..=0.5],
        prop_oneof![
            (1u32..12).prop_map(LeafRule::Objects),
            (1u64..2_000).prop_map(|capacity| LeafRule::Bytes { capacity })
        ],
        prop_oneof![(0u32..4).prop_map(LookAhead::Levels), Just(LookAhead::Max)],
        prop::sample::select(TieBreak::ALL.to_vec()),
        prop_oneof![
            Just(QueryExtent::Auto),
            (0.0f64..500.0).prop_map(|q| QueryExtent::Mm([q, 2.0 * q, 0.0]))
        ],
    )
        .prop_map(|(method, rate, leaf, look_ahead, tie_break, query_extent)| BuildParams {
            method,
            rate,
            leaf,
            look_ahead,
            tie_break,
            query_extent,
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]

    #[test]
    fn every_method_builds_a_valid_hierarchy(
        boxes in arb_boxes(1, 150),
        params in params(),
        size_seed in any::<u64>(),
    ) {
        // Sizes from 1 to 500 bytes, some over a small capacity.
        let sizes: Vec<u64> = (0..boxes.len() as u64)
            .map(|j| 1 + (j.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ size_seed) % 500)
            .collect();
        let tree = build(&boxes, Some(&sizes), &params, &|_| {}).unwrap();
        tree.validate(&boxes, Some(&sizes), &params).unwrap();
        let placed: usize = tree.leaves().map(|(_, o)| o.len()).sum();
        prop_assert_eq!(placed, boxes.len());
    }
}
