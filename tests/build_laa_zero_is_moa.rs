//! LAA with `look_ahead_level` = 0 builds exactly the MOA tree, node by
//! node, under every tie-break rule and rate.

mod common;

use common::arb_boxes;

use mktree::bulk::{BuildParams, LeafRule, LookAhead, Method, TieBreak, build};
use proptest::prelude::*;

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    #[test]
    fn laa_with_zero_look_ahead_equals_moa_node_by_node(
        boxes in arb_boxes(1, 200),
        rate in prop_oneof![Just(0.0), Just(0.5), 0.0f64..=0.5],
        mem_page in 1u32..10,
        tie_break in prop::sample::select(TieBreak::ALL.to_vec()),
    ) {
        let moa = BuildParams { method: Method::Moa, rate, leaf: LeafRule::Objects(mem_page), tie_break, ..BuildParams::paper() };
        let laa = BuildParams { method: Method::Laa, look_ahead: LookAhead::Levels(0), ..moa.clone() };
        let a = build(&boxes, None, &moa, &|_| {}).unwrap();
        let b = build(&boxes, None, &laa, &|_| {}).unwrap();
        prop_assert_eq!(a, b);
    }
}
