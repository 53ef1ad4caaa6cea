//! Bad options and bad input are refused before any work, each with its
//! own `BuildError` naming the culprit: R outside [0, 0.5], a zero
//! capacity, no objects, a non-finite or inverted box, sizes missing for
//! the byte rule or not one per box.

use mktree::bulk::{BuildError, BuildParams, LeafRule, build};
use mktree::geom::Aabb;
use mktree::scene::ObjectId;

fn unit(x: f64) -> Aabb {
    Aabb::from_array([x, 0.0, 0.0, x + 1.0, 1.0, 1.0])
}

fn refused(boxes: &[Aabb], sizes: Option<&[u64]>, params: &BuildParams) -> BuildError {
    let calls = std::sync::atomic::AtomicUsize::new(0);
    let err = build(boxes, sizes, params, &|_| {
        calls.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    })
    .unwrap_err();
    assert_eq!(calls.into_inner(), 0, "no progress before the input is accepted");
    err
}

#[test]
fn a_rate_outside_zero_to_one_half_is_refused() {
    let boxes = [unit(0.0), unit(2.0)];
    for rate in [-0.1, 0.500_001, f64::NAN] {
        let p = BuildParams { rate, ..BuildParams::paper() };
        assert!(matches!(refused(&boxes, None, &p), BuildError::RateOutOfRange { .. }), "{rate}");
    }
}

#[test]
fn a_zero_capacity_is_refused() {
    let boxes = [unit(0.0)];
    for leaf in [LeafRule::Objects(0), LeafRule::Bytes { capacity: 0 }] {
        let p = BuildParams { leaf, ..BuildParams::paper() };
        assert_eq!(refused(&boxes, Some(&[1]), &p), BuildError::ZeroCapacity);
    }
}

#[test]
fn an_empty_input_is_refused() {
    assert_eq!(refused(&[], None, &BuildParams::paper()), BuildError::EmptyInput);
}

#[test]
fn a_non_finite_or_inverted_box_is_refused_by_object() {
    let p = BuildParams::paper();
    let mut boxes = vec![unit(0.0), unit(2.0), unit(4.0)];
    boxes[1].max.y = f64::INFINITY;
    assert_eq!(refused(&boxes, None, &p), BuildError::NonFiniteBox { object: ObjectId(1) });
    boxes[1] = unit(2.0);
    boxes[2].min.z = f64::NAN;
    assert_eq!(refused(&boxes, None, &p), BuildError::NonFiniteBox { object: ObjectId(2) });
    boxes[2] = Aabb::from_array([0.0, 5.0, 0.0, 1.0, 4.0, 1.0]);
    assert_eq!(refused(&boxes, None, &p), BuildError::InvertedBox { object: ObjectId(2) });
}

#[test]
fn sizes_must_be_given_for_the_byte_rule_and_match_the_boxes() {
    let boxes = [unit(0.0), unit(2.0)];
    let bytes = BuildParams { leaf: LeafRule::Bytes { capacity: 100 }, ..BuildParams::paper() };
    assert_eq!(refused(&boxes, None, &bytes), BuildError::MissingSizes);
    assert_eq!(refused(&boxes, Some(&[1, 2, 3]), &bytes), BuildError::SizesMismatch { boxes: 2, sizes: 3 });
    assert_eq!(
        refused(&boxes, Some(&[1]), &BuildParams::paper()),
        BuildError::SizesMismatch { boxes: 2, sizes: 1 }
    );
}

#[test]
fn errors_say_what_is_wrong() {
    let p = BuildParams { rate: 0.7, ..BuildParams::paper() };
    assert_eq!(refused(&[unit(0.0)], None, &p).to_string(), "rate R = 0.7 is outside [0, 0.5]");
}
