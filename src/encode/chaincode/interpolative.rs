//! Binary interpolative coding of non-decreasing integer sequences (Moffat &
//! Stuiver 2000; chain-code paper §2.3 and §3.3).
//!
//! The middle element of a range is coded relative to the values its
//! neighbours allow, then both halves recurse. Two refinements from the paper
//! are used: a known maximal gap narrows each range from both sides, and
//! values are written in a *centred* minimal binary code, which gives the
//! shorter codewords to the middle of the range (where a smooth sequence's
//! middle element most likely lies). A range that admits a single value costs
//! no bits at all, which is what makes long runs (zeros after BWT and MTF)
//! nearly free.
//!
//! The decoder knows the count `n` and the last value; the sequence starts
//! from a virtual 0 before its first element.

use super::bits::{BitReader, BitSink, BitWriter};

/// Largest value a sequence may hold; keeps every range size in `u64`.
pub(crate) const MAX_VALUE: u64 = 1 << 62;

/// Encodes a non-decreasing sequence whose first element and successive
/// differences are at most `max_gap`. The decoder needs `sorted.len()`,
/// the last element and `max_gap`.
///
/// # Panics
/// If the sequence decreases, a gap exceeds `max_gap` or a value exceeds 2^62.
pub fn bic_encode(sorted: &[u64], max_gap: u64) -> Vec<u8> {
    let mut w = BitWriter::new();
    encode_into(&mut w, sorted, max_gap);
    w.finish()
}

/// Decodes what [`bic_encode`] wrote; `None` if `last` is inconsistent with
/// `n` and `max_gap`, or the bytes run out.
pub fn bic_decode(bytes: &[u8], n: usize, last: u64, max_gap: u64) -> Option<Vec<u64>> {
    let mut r = BitReader::new(bytes);
    let out = decode_from(&mut r, n, last, max_gap)?;
    (!r.overrun()).then_some(out)
}

pub(crate) fn encode_into(w: &mut impl BitSink, sorted: &[u64], max_gap: u64) {
    let mut prev = 0;
    for &v in sorted {
        assert!(
            v >= prev && v - prev <= max_gap && v <= MAX_VALUE,
            "interpolative coding needs a non-decreasing sequence with bounded gaps"
        );
        prev = v;
    }
    let n = sorted.len();
    if n < 2 {
        return;
    }
    // Positions 0..=n: position 0 is the virtual zero, position i is sorted[i-1].
    let at = |i: usize| if i == 0 { 0 } else { sorted[i - 1] };
    encode_range(w, &at, 0, n, 0, sorted[n - 1], max_gap);
}

fn encode_range(
    w: &mut impl BitSink,
    at: &impl Fn(usize) -> u64,
    lo_i: usize,
    hi_i: usize,
    lo_v: u64,
    hi_v: u64,
    max_gap: u64,
) {
    if hi_i - lo_i < 2 || determined(lo_i, hi_i, lo_v, hi_v, max_gap) {
        return;
    }
    let m = lo_i + (hi_i - lo_i) / 2;
    let (low, high) = bounds(lo_i, m, hi_i, lo_v, hi_v, max_gap);
    let v = at(m);
    write_centred(w, v - low, high - low + 1);
    encode_range(w, at, lo_i, m, lo_v, v, max_gap);
    encode_range(w, at, m, hi_i, v, hi_v, max_gap);
}

/// Decodes `n` values ending in `last` from a shared bit stream. `None` if
/// `last` cannot be reached with `n` gaps of at most `max_gap`.
pub(crate) fn decode_from(
    r: &mut BitReader<'_>,
    n: usize,
    last: u64,
    max_gap: u64,
) -> Option<Vec<u64>> {
    if n == 0 {
        return (last == 0).then(Vec::new);
    }
    if last > MAX_VALUE || last > (n as u64).saturating_mul(max_gap) {
        return None;
    }
    // out[i] is position i + 1; position 0 is the virtual zero.
    let mut out = vec![0u64; n];
    out[n - 1] = last;
    decode_range(r, &mut out, 0, n, 0, last, max_gap);
    Some(out)
}

/// Decodes the values strictly between positions `lo_i` and `hi_i`, in the
/// encoder's order: a range's middle value, then its left half, then its
/// right half.
///
/// The right half is decoded by the loop rather than by a second call, and a
/// half without inner values is never entered: half of all calls of the
/// plain recursion returned at once.
fn decode_range(
    r: &mut BitReader<'_>,
    out: &mut [u64],
    mut lo_i: usize,
    hi_i: usize,
    mut lo_v: u64,
    hi_v: u64,
    max_gap: u64,
) {
    while hi_i - lo_i >= 2 {
        if lo_v == hi_v {
            out[lo_i..hi_i - 1].fill(lo_v);
            return;
        }
        if determined(lo_i, hi_i, lo_v, hi_v, max_gap) {
            for (k, slot) in out[lo_i..hi_i - 1].iter_mut().enumerate() {
                *slot = lo_v + (k as u64 + 1) * max_gap;
            }
            return;
        }
        let m = lo_i + (hi_i - lo_i) / 2;
        let (low, high) = bounds(lo_i, m, hi_i, lo_v, hi_v, max_gap);
        let v = low + read_centred(r, high - low + 1);
        out[m - 1] = v;
        if m - lo_i >= 2 {
            decode_range(r, out, lo_i, m, lo_v, v, max_gap);
        }
        lo_i = m;
        lo_v = v;
    }
}

/// True when every value strictly between the two ends is forced: all equal,
/// or all gaps at their maximum.
fn determined(lo_i: usize, hi_i: usize, lo_v: u64, hi_v: u64, max_gap: u64) -> bool {
    lo_v == hi_v || hi_v - lo_v == ((hi_i - lo_i) as u64).saturating_mul(max_gap)
}

/// The values position `m` can take between its neighbours' values.
fn bounds(lo_i: usize, m: usize, hi_i: usize, lo_v: u64, hi_v: u64, max_gap: u64) -> (u64, u64) {
    let up = ((m - lo_i) as u64).saturating_mul(max_gap);
    let down = ((hi_i - m) as u64).saturating_mul(max_gap);
    let low = lo_v.max(hi_v.saturating_sub(down));
    let high = hi_v.min(lo_v.saturating_add(up));
    (low, high)
}

/// Writes `v < size` in a centred minimal binary code: `⌊log2 size⌋` bits for
/// the `2^(k+1) - size` values around the middle, one more bit for the rest.
fn write_centred(w: &mut impl BitSink, v: u64, size: u64) {
    if size < 2 {
        return;
    }
    let k = 63 - size.leading_zeros();
    let short = (2u64 << k) - size;
    let shift = (size - short) / 2;
    let x = if v >= shift {
        v - shift
    } else {
        v + size - shift
    };
    if x < short {
        w.write(x, k);
    } else {
        w.write(x + short, k + 1);
    }
}

#[inline]
fn read_centred(r: &mut BitReader<'_>, size: u64) -> u64 {
    if size < 2 {
        return 0;
    }
    let k = 63 - size.leading_zeros();
    let short = (2u64 << k) - size;
    let shift = (size - short) / 2;
    let x = if k < 56 {
        // One look at the next k + 1 bits decides the codeword's length
        // without a second read (and without a branch the data steers).
        let y = r.peek(k + 1);
        let long = (y >> 1) >= short;
        r.skip(k + u32::from(long));
        if long { y - short } else { y >> 1 }
    } else {
        let x = r.read(k);
        if x >= short {
            ((x << 1) | r.bit()) - short
        } else {
            x
        }
    };
    let v = x + shift;
    if v >= size { v - size } else { v }
}

#[cfg(test)]
mod tests {
    use super::super::bits::BitCounter;
    use super::*;
    use proptest::prelude::*;

    fn cumsum(gaps: &[u64]) -> Vec<u64> {
        gaps.iter()
            .scan(0u64, |acc, &g| {
                *acc += g;
                Some(*acc)
            })
            .collect()
    }

    #[test]
    fn runs_of_zeros_cost_nothing() {
        let q = cumsum(&[0; 1000]);
        assert!(bic_encode(&q, 8).is_empty());
        assert_eq!(bic_decode(&[], 1000, 0, 8), Some(q));
    }

    #[test]
    fn centred_code_round_trips_every_value() {
        for size in 1..70u64 {
            let mut w = BitWriter::new();
            for v in 0..size {
                write_centred(&mut w, v, size);
            }
            let bytes = w.finish();
            let mut r = BitReader::new(&bytes);
            for v in 0..size {
                assert_eq!(read_centred(&mut r, size), v, "size {size}");
            }
        }
    }

    #[test]
    fn inconsistent_last_is_rejected() {
        assert_eq!(bic_decode(&[], 3, 100, 8), None);
        assert_eq!(bic_decode(&[], 0, 1, 8), None);
    }

    proptest! {
        #[test]
        fn round_trip_bounded_gaps(gaps in proptest::collection::vec(0u64..9, 0..600)) {
            let q = cumsum(&gaps);
            let bytes = bic_encode(&q, 8);
            let last = q.last().copied().unwrap_or(0);
            prop_assert_eq!(bic_decode(&bytes, q.len(), last, 8), Some(q));
        }

        #[test]
        fn counting_the_bits_matches_writing_them(gaps in proptest::collection::vec(0u64..40, 0..400)) {
            let q = cumsum(&gaps);
            let max_gap = gaps.iter().copied().max().unwrap_or(0);
            let mut written = BitWriter::new();
            encode_into(&mut written, &q, max_gap);
            let mut counted = BitCounter::default();
            encode_into(&mut counted, &q, max_gap);
            prop_assert_eq!(counted.bit_len(), written.bit_len());
        }

        #[test]
        fn round_trip_large_gaps(gaps in proptest::collection::vec(0u64..(1 << 40), 0..200)) {
            let q = cumsum(&gaps);
            let bytes = bic_encode(&q, u64::MAX);
            let last = q.last().copied().unwrap_or(0);
            prop_assert_eq!(bic_decode(&bytes, q.len(), last, u64::MAX), Some(q));
        }

        #[test]
        fn hostile_streams_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..64),
                                       n in 0usize..500, last in any::<u64>(), gap in any::<u64>()) {
            if let Some(v) = bic_decode(&bytes, n, last, gap) {
                prop_assert_eq!(v.len(), n);
                prop_assert!(v.windows(2).all(|w| w[0] <= w[1]));
            }
        }
    }
}
