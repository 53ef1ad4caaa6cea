//! Cosine and sine computed with + and * only, so every platform rounds the
//! same way.
//!
//! Why not `f64::sin_cos`: Rust leaves its precision to the platform's libm,
//! and one ulp of difference in a pipe's vertex could change the generated
//! OBJ bytes. IEEE 754 fixes the result of each +, *, / and Rust never
//! fuses them, so a fixed polynomial evaluated in a fixed order gives the
//! same bits everywhere.

use std::f64::consts::TAU;

/// `(cos, sin)` of an angle given in turns (1 turn = 2π).
pub(crate) fn cos_sin(turns: f64) -> (f64, f64) {
    // Reduce to |r| <= π/4 around the nearest quarter turn, where the Taylor
    // series below is accurate to well under an ulp.
    let quarter = (turns * 4.0).round();
    let r = (turns - quarter * 0.25) * TAU;
    let r2 = r * r;
    let mut sin = 0.0;
    let mut cos = 0.0;
    // Horner from the highest term: sin = r(1 - r²/3!(1 - r²/(4·5)(...))).
    for k in (1..=9u32).rev() {
        let (s_den, c_den) = (f64::from((2 * k) * (2 * k + 1)), f64::from((2 * k - 1) * (2 * k)));
        sin = 1.0 - r2 / s_den * sin;
        cos = 1.0 - r2 / c_den * cos;
    }
    let sin = r * sin;
    match (quarter as i64).rem_euclid(4) {
        0 => (cos, sin),
        1 => (-sin, cos),
        2 => (-cos, -sin),
        _ => (sin, -cos),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn agrees_with_libm_to_a_few_ulps() {
        for i in -200..=200 {
            let turns = f64::from(i) / 199.0;
            let (c, s) = cos_sin(turns);
            let (ls, lc) = (turns * TAU).sin_cos();
            assert!((c - lc).abs() < 1e-15, "cos({turns} turns)");
            assert!((s - ls).abs() < 1e-15, "sin({turns} turns)");
            // Whole turns are removed exactly, so far arguments keep their precision.
            let (c3, s3) = cos_sin(turns + 3.0);
            assert!((c3 - c).abs() < 1e-14 && (s3 - s).abs() < 1e-14, "{turns} + 3 turns");
        }
    }

    #[test]
    fn quarter_turns_are_exact() {
        assert_eq!(cos_sin(0.0), (1.0, 0.0));
        assert_eq!(cos_sin(0.25), (-0.0, 1.0));
        assert_eq!(cos_sin(0.5), (-1.0, -0.0));
    }
}
