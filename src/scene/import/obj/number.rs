//! OBJ import's number parsing (see `obj.rs`): coordinates and vertex
//! indices read without allocating, eight digits at a time, rounded
//! exactly; std's parser for exponents and the like.

/// The number that starts `s`, and the bytes after it. The number must end
/// at whitespace or at the end of `s`.
///
/// Plain decimals (no exponent) of up to 19 digits, the form our scenes
/// are written in, are read in one pass and rounded exactly here (see
/// [`exact_quotient`]). Anything else (an exponent, more digits, `inf`,
/// `nan`) goes to std's parser, which is exact too.
pub(super) fn scan_f64(s: &[u8]) -> Option<(f64, &[u8])> {
    if let Some(fast) = short_decimal(s).or_else(|| scan_plain_decimal(s)) {
        return Some(fast);
    }
    let token = token_at(s);
    let value = std::str::from_utf8(token).ok()?.parse().ok()?;
    Some((value, &s[token.len()..]))
}

fn scan_plain_decimal(s: &[u8]) -> Option<(f64, &[u8])> {
    let (negative, body) = split_sign(s);
    let (whole, whole_digits, after_whole) = leading_digits(body, 0);
    let (digits, fraction_digits, rest) = match after_whole.split_first() {
        Some((b'.', fraction)) => leading_digits(fraction, whole),
        _ => (whole, 0, after_whole),
    };
    let ends = rest.first().is_none_or(u8::is_ascii_whitespace);
    // Up to 19 digits the accumulator is exact (10^19 < 2^64).
    if !ends || !(1..=19).contains(&(whole_digits + fraction_digits)) {
        return None;
    }
    let value = exact_quotient(digits, fraction_digits)?;
    Some((if negative { -value } else { value }, rest))
}

/// A plain decimal as nearly every coordinate is written: up to seven
/// digits, a point and up to seven more, then a blank or the line's end.
/// Read from two chunks; fourteen digits are below 2^53, so one division
/// rounds exactly (see [`exact_quotient`]). `None` for anything else.
#[inline(always)]
fn short_decimal(s: &[u8]) -> Option<(f64, &[u8])> {
    const POWERS_OF_TEN: [u64; 8] = [1, 10, 100, 1_000, 10_000, 100_000, 1_000_000, 10_000_000];
    let (negative, body) = split_sign(s);
    let chunk = u64::from_le_bytes(*body.first_chunk::<8>()?);
    let whole_digits = digit_run(chunk);
    if !(1..8).contains(&whole_digits) {
        return None;
    }
    let whole = run_value(chunk, whole_digits);
    let (digits, fraction_digits, rest) = match &body[whole_digits..] {
        [b'.', fraction @ ..] => {
            let chunk = u64::from_le_bytes(*fraction.first_chunk::<8>()?);
            let n = digit_run(chunk);
            let value = *POWERS_OF_TEN.get(n)? * whole + if n > 0 { run_value(chunk, n) } else { 0 };
            (value, n, &fraction[n..])
        }
        rest => (whole, 0, rest),
    };
    if !matches!(rest.first(), Some(b' ' | b'\t' | b'\n' | b'\r')) {
        return None;
    }
    let value = digits as f64 / F64_POWERS_OF_TEN[fraction_digits];
    Some((if negative { -value } else { value }, rest))
}

/// 10^k for k <= 22, all exact in f64.
const F64_POWERS_OF_TEN: [f64; 23] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18,
    1e19, 1e20, 1e21, 1e22,
];

/// `digits / 10^k` correctly rounded to f64, or `None` when this cannot
/// tell cheaply (std's parser then decides).
///
/// With at most 53 significant bits the digits are exact in f64, and so is
/// 10^k for k <= 22: one division rounds once and is exact (Clinger's fast
/// path). With more (shortest round-trip decimals often have 17 digits),
/// that quotient is within one unit in the last place; it, or its
/// neighbour towards the true value, is checked against half a unit in
/// 128-bit integers.
fn exact_quotient(digits: u64, k: usize) -> Option<f64> {
    let quotient = digits as f64 / *F64_POWERS_OF_TEN.get(k)?;
    if digits <= 1 << 53 {
        return Some(quotient);
    }
    // k <= 19 here (at most 19 digits), so 10^k fits in 64 bits.
    let power = 10u64.checked_pow(k as u32)?;
    match rounding_error(digits, power, quotient)? {
        std::cmp::Ordering::Equal => Some(quotient),
        towards => {
            let neighbour =
                f64::from_bits(if towards.is_gt() { quotient.to_bits() + 1 } else { quotient.to_bits() - 1 });
            rounding_error(digits, power, neighbour)?.is_eq().then_some(neighbour)
        }
    }
}

/// Whether the positive normal `candidate` is `digits / power` correctly
/// rounded (`Equal`), or too small (`Greater`: the true value lies above
/// half a unit over it) or too large (`Less`). `None` for a tie, a power
/// of two (whose lower half-unit is smaller), or numbers out of reach.
fn rounding_error(digits: u64, power: u64, candidate: f64) -> Option<std::cmp::Ordering> {
    let bits = candidate.to_bits();
    let biased_exponent = (bits >> 52) as i32;
    let fraction = bits & ((1 << 52) - 1);
    if !(1..0x7FF).contains(&biased_exponent) || fraction == 0 {
        return None;
    }
    // candidate = mantissa * 2^exponent exactly.
    let mantissa = fraction | (1 << 52);
    let exponent = biased_exponent - 1075;
    // (digits / power - candidate) * 2 * power * 2^max(-exponent, 0),
    // compared with half a unit, scaled alike: power * 2^max(exponent, 0).
    let up = exponent.max(0) as u32;
    let down = (-exponent).max(0) as u32;
    let shift = |value: u128, by: u32| (value.leading_zeros() > by).then(|| value << by);
    let scaled_value = shift(u128::from(digits) << 1, down)?;
    // A 53-bit mantissa times a 64-bit power: 117 bits, no overflow.
    let scaled_candidate = shift((u128::from(mantissa) * u128::from(power)) << 1, up)?;
    let half_unit = shift(u128::from(power), up)?;
    let (gap, above) = match scaled_value.checked_sub(scaled_candidate) {
        Some(gap) => (gap, true),
        None => (scaled_candidate - scaled_value, false),
    };
    match gap.cmp(&half_unit) {
        std::cmp::Ordering::Less => Some(std::cmp::Ordering::Equal),
        std::cmp::Ordering::Equal => None,
        std::cmp::Ordering::Greater if above => Some(std::cmp::Ordering::Greater),
        std::cmp::Ordering::Greater => Some(std::cmp::Ordering::Less),
    }
}

/// The vertex index that starts `s` (the `v` of `v/vt/vn`), and the bytes
/// after the whole corner. At most 18 digits, so it cannot overflow (no
/// file has 10^18 vertices).
pub(super) fn scan_index(s: &[u8]) -> Option<(i64, &[u8])> {
    let (negative, body) = split_sign(s);
    let (value, digits, mut rest) = leading_digits(body, 0);
    if !(1..=18).contains(&digits) {
        return None;
    }
    if rest.first() == Some(&b'/') {
        rest = &rest[token_at(rest).len()..];
    }
    if !rest.first().is_none_or(u8::is_ascii_whitespace) {
        return None;
    }
    // 18 digits fit in an i64.
    let value = value as i64;
    Some((if negative { -value } else { value }, rest))
}

fn split_sign(s: &[u8]) -> (bool, &[u8]) {
    match s {
        [b'-', body @ ..] => (true, body),
        [b'+', body @ ..] => (false, body),
        _ => (false, s),
    }
}

/// Appends the decimal digits that start `s` to `value`; returns the new
/// value, how many digits were read, and the bytes after them. Past 19
/// digits the value wraps: callers check the count.
///
/// Eight bytes at a time, as in Lemire's fast_float but for runs of any
/// length: the first non-digit of the chunk ends the run, the digits before
/// it are shifted to the top and converted together. Coordinates written as
/// shortest round-trip decimals have 16 or 17 digits, indices 5 to 9, so a
/// byte-at-a-time loop would cost a multiply per digit.
#[inline]
pub(super) fn leading_digits(mut s: &[u8], mut value: u64) -> (u64, usize, &[u8]) {
    const POWERS_OF_TEN: [u64; 9] = [1, 10, 100, 1_000, 10_000, 100_000, 1_000_000, 10_000_000, 100_000_000];
    let mut count = 0;
    loop {
        let chunk = match s.first_chunk::<8>() {
            Some(chunk) => u64::from_le_bytes(*chunk),
            None => {
                // Past the end of `s`, spaces: they end the run like any non-digit.
                let mut padded = [b' '; 8];
                for (p, &b) in padded.iter_mut().zip(s) {
                    *p = b;
                }
                u64::from_le_bytes(padded)
            }
        };
        let digits = digit_run(chunk);
        if digits == 0 {
            return (value, count, s);
        }
        value = value.wrapping_mul(POWERS_OF_TEN[digits]).wrapping_add(run_value(chunk, digits));
        count += digits;
        s = &s[digits..];
        if digits < 8 {
            return (value, count, s);
        }
    }
}

const ZEROS: u64 = 0x3030_3030_3030_3030;

/// How many digits start `chunk` (first byte lowest), 0 to 8.
#[inline(always)]
fn digit_run(chunk: u64) -> usize {
    // A byte's high bit is set here iff it is not a digit; bytes after the
    // first non-digit may be garbled by borrows, but are not used.
    let non_digits =
        (chunk.wrapping_sub(ZEROS) | chunk.wrapping_add(0x4646_4646_4646_4646)) & 0x8080_8080_8080_8080;
    (non_digits.trailing_zeros() / 8) as usize
}

/// The number that the first `digits` (1 to 8) bytes of `chunk` spell.
#[inline(always)]
fn run_value(chunk: u64, digits: usize) -> u64 {
    // The run's digits into the top bytes, '0's below them.
    let shift = 8 * (8 - digits) as u32;
    eight_digits(chunk.checked_shl(shift).unwrap_or(0) | ZEROS.checked_shr(64 - shift).unwrap_or(0))
}

/// A corner as nearly every file writes it: a positive index of at most
/// seven digits, then a blank or the line's end. Read from one chunk, it
/// skips [`scan_index`]'s sign, slash and length checks; `None` for
/// anything else, which [`scan_index`] then reads.
#[inline(always)]
pub(super) fn short_index(s: &[u8]) -> Option<(i64, &[u8])> {
    let chunk = u64::from_le_bytes(*s.first_chunk::<8>()?);
    let digits = digit_run(chunk);
    let ends = matches!(s.get(digits), Some(b' ' | b'\t' | b'\n' | b'\r'));
    if !(1..8).contains(&digits) || !ends {
        return None;
    }
    // Seven digits fit in an i64.
    Some((run_value(chunk, digits) as i64, &s[digits..]))
}

/// The number that eight ASCII digits (first digit in the lowest byte)
/// spell: pairs, then quads, then all eight, by multiply and shift.
#[inline]
fn eight_digits(chunk: u64) -> u64 {
    let d = chunk.wrapping_sub(0x3030_3030_3030_3030);
    let pairs = d.wrapping_mul(10).wrapping_add(d >> 8);
    let low = (pairs & 0x0000_00FF_0000_00FF).wrapping_mul(0x000F_4240_0000_0064);
    let high = ((pairs >> 16) & 0x0000_00FF_0000_00FF).wrapping_mul(0x0000_2710_0000_0001);
    u64::from((low.wrapping_add(high) >> 32) as u32)
}

/// The bytes of `s` up to the first whitespace.
pub(super) fn token_at(s: &[u8]) -> &[u8] {
    &s[..s.iter().position(u8::is_ascii_whitespace).unwrap_or(s.len())]
}
