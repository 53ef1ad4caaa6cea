//! LAA with `look_ahead_level` = 0 builds exactly the MOA tree, node by
//! node, under every tie-break rule and rate.

use mktree::build::{BuildParams, LeafRule, LookAhead, Method, TieBreak, build};
use mktree::geom::Aabb;
use proptest::prelude::*;

fn scene() -> impl Strategy<Value = Vec<Aabb>> {
    let grid = (prop::array::uniform3(0u8..10), prop::array::uniform3(0u8..4)).prop_map(|(lo, ext)| {
        let lo = lo.map(f64::from);
        Aabb::from_array([
            lo[0],
            lo[1],
            lo[2],
            lo[0] + f64::from(ext[0]),
            lo[1] + f64::from(ext[1]),
            lo[2] + f64::from(ext[2]),
        ])
    });
    let free =
        (prop::array::uniform3(0f64..100.0), prop::array::uniform3(0f64..20.0)).prop_map(|(lo, ext)| {
            Aabb::from_array([lo[0], lo[1], lo[2], lo[0] + ext[0], lo[1] + ext[1], lo[2] + ext[2]])
        });
    prop_oneof![prop::collection::vec(grid, 1..200), prop::collection::vec(free, 1..200)]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    #[test]
    fn laa_with_zero_look_ahead_equals_moa_node_by_node(
        boxes in scene(),
        rate in prop_oneof![Just(0.0), Just(0.5), 0.0f64..=0.5],
        mem_page in 1u32..10,
        tie_break in prop::sample::select(TieBreak::ALL.to_vec()),
    ) {
        let moa = BuildParams { method: Method::Moa, rate, leaf: LeafRule::Objects(mem_page), tie_break, ..BuildParams::default() };
        let laa = BuildParams { method: Method::Laa, look_ahead: LookAhead::Levels(0), ..moa.clone() };
        let a = build(&boxes, None, &moa, &|_| {}).unwrap();
        let b = build(&boxes, None, &laa, &|_| {}).unwrap();
        prop_assert_eq!(a, b);
    }
}
