//! Claim: `refine` never raises the cost model's value above that of the
//! `vsah` tree it starts from (`CostModel::expected_cost` for its query
//! extent, up to the rounding of the sums), for any scene, leaf rule, rate and
//! query extent; and both trees are valid hierarchies of their input.

mod common;

use common::arb_boxes;
use mktree::bulk::{BuildParams, CostModel, LeafRule, Method, QueryExtent, build};
use proptest::prelude::*;

fn extent() -> impl Strategy<Value = QueryExtent> {
    prop_oneof![Just(QueryExtent::Auto), prop::array::uniform3(0.0f64..2_000.0).prop_map(QueryExtent::Mm),]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn refine_costs_no_more_than_vsah(
        boxes in arb_boxes(1, 400),
        mem_page in 1u32..20,
        rate in 0.0f64..=0.5,
        query_extent in extent(),
    ) {
        let vsah = BuildParams { method: Method::Vsah, rate, leaf: LeafRule::Objects(mem_page), query_extent, ..BuildParams::paper() };
        let refine = BuildParams { method: Method::Refine, ..vsah.clone() };
        let a = build(&boxes, None, &vsah, &|_| {}).unwrap();
        let b = build(&boxes, None, &refine, &|_| {}).unwrap();
        a.validate(&boxes, None, &vsah).unwrap();
        b.validate(&boxes, None, &refine).unwrap();
        let model = CostModel::of_boxes(&boxes, query_extent);
        let (ca, cb) = (model.expected_cost(&a), model.expected_cost(&b));
        prop_assert!(cb <= ca * (1.0 + 1e-9), "refine {cb} > vsah {ca}");
    }
}

#[test]
fn refine_lowers_the_cost_of_a_scene_of_slabs() {
    // Thin plates in stacks: the vsah tree is not the cheapest, and at
    // least one of MOA's cuts is better somewhere.
    let mut boxes = Vec::new();
    for i in 0..40 {
        for j in 0..25 {
            let (x, z) = (f64::from(i) * 103.0, f64::from(j) * 400.0);
            boxes.push(mktree::geom::Aabb::from_array([x, 0.0, z, x + 100.0, 3_000.0, z + 10.0]));
        }
    }
    let vsah = BuildParams { method: Method::Vsah, leaf: LeafRule::Objects(16), ..BuildParams::paper() };
    let refine = BuildParams { method: Method::Refine, ..vsah.clone() };
    let model = CostModel::of_boxes(&boxes, QueryExtent::Auto);
    let a = model.expected_cost(&build(&boxes, None, &vsah, &|_| {}).unwrap());
    let b = model.expected_cost(&build(&boxes, None, &refine, &|_| {}).unwrap());
    println!("vsah {a}, refine {b}");
    assert!(b < a);
}
