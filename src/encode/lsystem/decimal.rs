//! Decimal roundings of parameters, computed arithmetically.
//!
//! The closed-loop writer (see `write`) tries every rounding of every turn,
//! pitch and length to 0–12 decimals and needs, for each, the value the
//! reader will parse and the bytes it prints as. Formatting each candidate
//! to text and parsing it back cost more than half of `encode`; here both
//! come from one integer, with the text path kept for the rare values where
//! the arithmetic cannot decide (exact ties, huge magnitudes). The results
//! are bit for bit those of the text path, so documents do not change.

use super::format::push_number;

/// Powers of ten that `f64` holds exactly (10^0 to 10^22).
const POW10: [f64; 23] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16,
    1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
];

/// Powers of ten that `u64` holds (10^0 to 10^19).
const POW10_U64: [u64; 20] = {
    let mut p = [1u64; 20];
    let mut i = 1;
    while i < p.len() {
        p[i] = p[i - 1] * 10;
        i += 1;
    }
    p
};

/// Scaled magnitudes up to here keep a fraction bit, so `floor` and the
/// half-way test below are exact.
const EXACT_BELOW: f64 = (1u64 << 52) as f64;

/// A value rounded to a number of decimals, as the reader parses its text.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Rounding {
    /// The parsed value.
    pub(crate) value: f64,
    /// Characters of [`push_number`] for `|value|`.
    pub(crate) magnitude_chars: usize,
    /// Characters of [`push_number`] for `value`.
    pub(crate) chars: usize,
}

/// `value` rounded to `decimals` (at most 22) as `format!("{value:.decimals$}")`
/// prints it and the reader parses it back, with the length of its shortest
/// printed form.
pub(crate) fn rounding(value: f64, decimals: usize) -> Rounding {
    scaled_rounding(value, decimals).unwrap_or_else(|| {
        let value: f64 = format!("{value:.decimals$}")
            .parse()
            .expect("a formatted f64 parses");
        Rounding {
            value,
            magnitude_chars: number_chars(value.abs()),
            chars: number_chars(value),
        }
    })
}

/// Characters [`push_number`] prints for `v`.
pub(crate) fn number_chars(v: f64) -> usize {
    let mut text = String::new();
    push_number(&mut text, v);
    text.len()
}

/// The rounding by integer arithmetic: the decimal text of `|value|` to
/// `decimals` is the integer `n` nearest `|value| · 10^decimals` (exactly,
/// the residual of the product from a fused multiply-add), and the reader's
/// correctly rounded parse of it is the correctly rounded `n / 10^decimals`.
/// `None` for a tie, whose rounding direction is the formatter's to choose,
/// and for magnitudes the test cannot decide.
fn scaled_rounding(value: f64, decimals: usize) -> Option<Rounding> {
    let scale = *POW10.get(decimals)?;
    let magnitude = value.abs();
    let scaled = magnitude * scale;
    // Also rejects NaN.
    if scaled.partial_cmp(&EXACT_BELOW) != Some(std::cmp::Ordering::Less) {
        return None;
    }
    let residual = magnitude.mul_add(scale, -scaled);
    // `scaled` is in [0, 2^52): truncation is its floor, without a libm call.
    let whole = scaled as u64;
    let floor = whole as f64;
    // Both terms are multiples of the scaled value's ulp, so this is exact,
    // and when not zero it outweighs the residual (at most half an ulp).
    let above_half = (scaled - floor) - 0.5;
    let up = if above_half != 0.0 {
        above_half > 0.0
    } else if residual != 0.0 {
        residual > 0.0
    } else {
        return None;
    };
    let n = whole + u64::from(up);
    let value = (n as f64 / scale).copysign(value);
    // At most 16 digits, a point and 12 decimals: never the exponent form.
    let magnitude_chars = fixed_chars(n, decimals);
    Some(Rounding {
        value,
        magnitude_chars,
        chars: magnitude_chars + usize::from(value.is_sign_negative()),
    })
}

/// Characters of the shortest text of `n / 10^decimals` (`n` < 2^52): its
/// digits without trailing zeros in the fraction and without a leading
/// zero before the point (`.25`). No shorter decimal parses to the same
/// value, since neighbouring multiples of 10^-decimals lie further apart
/// than the value's ulp.
fn fixed_chars(mut n: u64, mut decimals: usize) -> usize {
    while decimals > 0 && n % 10 == 0 {
        n /= 10;
        decimals -= 1;
    }
    // `n` < 2^52 < 10^16: beyond the table the integer part is 0.
    let integer = POW10_U64.get(decimals).map_or(0, |&p| n / p);
    let integer_chars = match (integer, decimals) {
        (0, 0) => 1,
        (0, _) => 0,
        (i, _) => i.ilog10() as usize + 1,
    };
    integer_chars + if decimals > 0 { decimals + 1 } else { 0 }
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;

    /// The writer's former rounding, through text: the oracle.
    fn rounding_by_text(value: f64, decimals: usize) -> (f64, usize) {
        let parsed: f64 = format!("{value:.decimals$}").parse().unwrap();
        let mut text = String::new();
        push_number(&mut text, parsed);
        (parsed, text.len())
    }

    fn assert_same(value: f64, decimals: usize) {
        let fast = rounding(value, decimals);
        let (parsed, chars) = rounding_by_text(value, decimals);
        assert_eq!(
            fast.value.to_bits(),
            parsed.to_bits(),
            "{value:e} to {decimals}"
        );
        assert_eq!(fast.chars, chars, "{value:e} to {decimals}");
    }

    #[test]
    fn ties_signs_and_zeros_match_the_text() {
        for v in [
            0.0, -0.0, 0.5, 1.5, 2.5, -2.5, 0.125, 0.25, 0.3, -0.3, 0.05, 0.15, 9.995, 99.5, 1e-7,
            123456.789, 4.5e15, 1e300, -1e-300,
        ] {
            for k in 0..=12 {
                assert_same(v, k);
            }
        }
    }

    proptest! {
        #[test]
        fn matches_the_text_rounding(
            mantissa in -1.0e4f64..1.0e4,
            exponent in -8i32..8,
            decimals in 0usize..=12,
        ) {
            assert_same(mantissa * 10f64.powi(exponent), decimals);
        }

        #[test]
        fn matches_on_any_bits(bits in any::<u64>(), decimals in 0usize..=12) {
            let v = f64::from_bits(bits);
            prop_assume!(v.is_finite());
            assert_same(v, decimals);
        }
    }
}
