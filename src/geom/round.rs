//! Directed rounding from f64 to f32, so a box stored in f32 still contains
//! the f64 geometry it bounds.

/// The largest f32 that is <= `x` (for a box's lower corner).
pub fn round_down_f32(x: f64) -> f32 {
    let r = x as f32; // round to nearest
    if f64::from(r) > x { r.next_down() } else { r }
}

/// The smallest f32 that is >= `x` (for a box's upper corner).
pub fn round_up_f32(x: f64) -> f32 {
    let r = x as f32;
    if f64::from(r) < x { r.next_up() } else { r }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn directed_rounding_brackets_the_value(x in -1.0e9f64..1.0e9) {
            let lo = round_down_f32(x);
            let hi = round_up_f32(x);
            prop_assert!(f64::from(lo) <= x);
            prop_assert!(f64::from(hi) >= x);
            // At most one f32 step apart: the rounding is as tight as f32 allows.
            prop_assert!(lo == hi || lo.next_up() == hi);
        }
    }

    #[test]
    fn exact_values_are_kept() {
        assert_eq!(round_down_f32(1.5), 1.5);
        assert_eq!(round_up_f32(-3.0), -3.0);
    }
}
