//! One-dimensional layout steps shared by the structure and the outfitting:
//! cutting a stretch into pieces (plates, pipe spools, tray lengths) and
//! spacing stations along it (stiffeners, supports).

/// `[lo, hi]` cut into the fewest equal pieces of at most `longest`. The
/// last piece ends exactly at `hi`, so a caller can tell it by `end == hi`.
pub(crate) fn pieces(lo: f64, hi: f64, longest: f64) -> impl Iterator<Item = (f64, f64)> {
    let n = ((hi - lo) / longest).ceil().max(1.0) as u32;
    let step = (hi - lo) / f64::from(n);
    let at = move |k: u32| if k == n { hi } else { lo + step * f64::from(k) };
    (0..n).map(move |k| (at(k), at(k + 1)))
}

/// Stations `spacing` apart, as many as fit strictly inside `[lo, hi]` with
/// at least half a spacing to either end, centred.
pub(crate) fn stations(lo: f64, hi: f64, spacing: f64) -> impl Iterator<Item = f64> {
    let n = ((hi - lo) / spacing).floor().max(0.0) as u32;
    let first = lo + (hi - lo - spacing * f64::from(n.saturating_sub(1))) / 2.0;
    (0..n).map(move |k| first + spacing * f64::from(k))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pieces_cover_the_span_without_exceeding_the_longest() {
        let p: Vec<_> = pieces(0.0, 7000.0, 2500.0).collect();
        assert_eq!(p.len(), 3);
        assert_eq!((p[0].0, p[2].1), (0.0, 7000.0));
        assert!(p.iter().all(|(a, b)| b - a <= 2500.0));
        assert_eq!(pieces(5.0, 6.0, 2500.0).count(), 1);
        assert_eq!(pieces(0.1, 0.7, 0.2).last().unwrap().1, 0.7);
    }

    #[test]
    fn stations_are_centred_and_keep_off_the_ends() {
        let s: Vec<_> = stations(0.0, 2000.0, 750.0).collect();
        assert_eq!(s, vec![625.0, 1375.0]);
        assert_eq!(stations(0.0, 2250.0, 750.0).collect::<Vec<_>>(), vec![375.0, 1125.0, 1875.0]);
        assert_eq!(stations(0.0, 500.0, 750.0).count(), 0);
        assert_eq!(stations(10.0, 5.0, 750.0).count(), 0);
    }
}
