//! Burrows–Wheeler transform over small alphabets (chain-code paper §3.3,
//! step 1; Burrows & Wheeler 1994).
//!
//! The string is closed by a virtual end marker that sorts before every
//! symbol, so the transform is a suffix sort. The output is the last column
//! without the marker plus the marker's row (the key `n` of the paper); the
//! inverse walks the last-to-first mapping in linear time.

/// The BWT of `symbols` (each < `alphabet`): the permuted symbols and the
/// index at which the end marker was removed from the last column.
///
/// # Panics
/// If a symbol is not below `alphabet` (a caller bug: codes are produced by
/// this crate).
pub fn bwt_forward(symbols: &[u8], alphabet: usize) -> (Vec<u8>, usize) {
    assert!(symbols.iter().all(|&s| usize::from(s) < alphabet));
    let sa = suffix_array(symbols);
    let mut last = Vec::with_capacity(symbols.len());
    let mut primary = 0;
    for (row, &start) in sa.iter().enumerate() {
        if start == 0 {
            primary = row;
        } else {
            last.push(symbols[start as usize - 1]);
        }
    }
    (last, primary)
}

/// Inverts [`bwt_forward`]. Returns `None` if `primary` is out of range, a
/// symbol is not below `alphabet` or the alphabet exceeds 255 symbols. Any other input yields some string of the
/// same length (possibly not the original): the walk is over a permutation,
/// so it always terminates.
pub fn bwt_inverse(last: &[u8], primary: usize, alphabet: usize) -> Option<Vec<u8>> {
    let n = last.len();
    if primary > n || alphabet > 255 || n >= u32::MAX as usize {
        return None;
    }
    // The full last column, with the end marker (any value ≥ alphabet) in
    // row `primary`.
    let marker = alphabet as u8;
    let mut column = Vec::with_capacity(n + 1);
    column.extend_from_slice(&last[..primary]);
    column.push(marker);
    column.extend_from_slice(&last[primary..]);
    // First row of each symbol in the sorted first column (marker in row 0).
    let mut start = vec![0u32; alphabet + 1];
    for &s in last {
        let s = usize::from(s);
        if s >= alphabet {
            return None;
        }
        start[s + 1] += 1;
    }
    start[0] = 1;
    for s in 1..=alphabet {
        start[s] += start[s - 1];
    }
    // Last-to-first mapping; the marker's row maps to row 0.
    let mut lf = vec![0u32; n + 1];
    let mut next = start;
    for (slot, &s) in lf.iter_mut().zip(&column) {
        if s != marker {
            let s = usize::from(s);
            *slot = next[s];
            next[s] += 1;
        }
    }
    // Row 0 starts with the marker; its last symbol ends the string.
    let mut out = vec![0u8; n];
    let mut row = 0usize;
    for slot in out.iter_mut().rev() {
        let s = column[row];
        if s == marker {
            // A corrupt key or column closed the cycle early.
            return None;
        }
        *slot = s;
        row = lf[row] as usize;
    }
    Some(out)
}

/// Suffix array of `s` with a virtual smallest end marker, by prefix
/// doubling (Manber & Myers 1993); includes the empty suffix `s.len()` in
/// row 0.
///
/// Each round sorts the suffixes by the ranks of their first `2k` symbols,
/// the pair (rank of the first `k`, rank of the next `k`), with two linear
/// passes instead of a comparison sort: the suffixes in the order of their
/// second halves are read off the previous round's order, then a stable
/// counting sort by the first half's rank finishes the round. It stops
/// once every rank is distinct: after about log2 of the longest repeated
/// substring's length rounds.
fn suffix_array(s: &[u8]) -> Vec<u32> {
    let n = s.len() + 1;
    // Rank 0 is the end marker; ranks stay below n.
    let mut rank: Vec<u32> = s.iter().map(|&c| u32::from(c) + 1).collect();
    rank.push(0);
    let mut by_second: Vec<u32> = (0..n as u32).collect();
    let mut sa = vec![0u32; n];
    let mut next = vec![0u32; n];
    let mut bucket = vec![0u32; n.max(257) + 1];
    counting_sort(&by_second, &rank, &mut bucket, &mut sa);
    let mut k = 1usize;
    loop {
        // A suffix whose second half starts past the marker has an empty
        // second half, which sorts first; its first half already holds the
        // marker, so its rank is unique and their order among each other
        // does not matter.
        by_second.clear();
        by_second.extend((n.saturating_sub(k)..n).map(|i| i as u32));
        by_second.extend(
            sa.iter()
                .filter(|&&i| i as usize >= k)
                .map(|&i| i - k as u32),
        );
        counting_sort(&by_second, &rank, &mut bucket, &mut sa);
        let key = |i: u32| {
            let i = i as usize;
            let second = if i + k < n { rank[i + k] + 1 } else { 0 };
            (rank[i], second)
        };
        next[sa[0] as usize] = 0;
        for w in 1..n {
            let bump = u32::from(key(sa[w - 1]) != key(sa[w]));
            next[sa[w] as usize] = next[sa[w - 1] as usize] + bump;
        }
        std::mem::swap(&mut rank, &mut next);
        if rank[sa[n - 1] as usize] as usize == n - 1 || k >= n {
            return sa;
        }
        k *= 2;
    }
}

/// Stable counting sort of the positions `order` by `rank` into `out`;
/// `bucket` has room for every rank value plus one.
fn counting_sort(order: &[u32], rank: &[u32], bucket: &mut [u32], out: &mut [u32]) {
    bucket.fill(0);
    for &i in order {
        bucket[rank[i as usize] as usize + 1] += 1;
    }
    for r in 1..bucket.len() {
        bucket[r] += bucket[r - 1];
    }
    for &i in order {
        let slot = &mut bucket[rank[i as usize] as usize];
        out[*slot as usize] = i;
        *slot += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn known_transform() {
        // "banana" with a=0, b=1, n=2: rotations of "banana$" sorted give
        // last column "annb$aa" -> without marker "annbaa", marker at row 4.
        let s = [1, 0, 2, 0, 2, 0];
        let (last, primary) = bwt_forward(&s, 3);
        assert_eq!(last, vec![0, 2, 2, 1, 0, 0]);
        assert_eq!(primary, 4);
        assert_eq!(bwt_inverse(&last, primary, 3).unwrap(), s.to_vec());
    }

    #[test]
    fn empty_and_bad_keys() {
        assert_eq!(bwt_forward(&[], 9), (vec![], 0));
        assert_eq!(bwt_inverse(&[], 0, 9), Some(vec![]));
        assert_eq!(bwt_inverse(&[1, 2], 3, 9), None);
        assert_eq!(bwt_inverse(&[1, 9], 0, 9), None);
    }

    proptest! {
        #[test]
        fn round_trip(s in proptest::collection::vec(0u8..9, 0..400)) {
            let (last, primary) = bwt_forward(&s, 9);
            prop_assert_eq!(bwt_inverse(&last, primary, 9), Some(s));
        }

        #[test]
        fn runs_round_trip(runs in proptest::collection::vec((0u8..3, 1usize..50), 0..30)) {
            let s: Vec<u8> = runs.iter().flat_map(|&(c, k)| std::iter::repeat_n(c, k)).collect();
            let (last, primary) = bwt_forward(&s, 3);
            prop_assert_eq!(bwt_inverse(&last, primary, 3), Some(s));
        }

        #[test]
        fn suffixes_come_in_order(s in proptest::collection::vec(0u8..3, 0..300)) {
            // A slice sorts before every longer slice it begins: the end
            // marker sorts before every symbol.
            let mut naive: Vec<u32> = (0..=s.len() as u32).collect();
            naive.sort_by(|&a, &b| s[a as usize..].cmp(&s[b as usize..]));
            prop_assert_eq!(suffix_array(&s), naive);
        }

        #[test]
        fn arbitrary_input_never_panics(last in proptest::collection::vec(0u8..9, 0..100), primary in 0usize..110) {
            // Whatever it returns is a string of the same length over the
            // same alphabet.
            if let Some(s) = bwt_inverse(&last, primary, 9) {
                prop_assert_eq!(s.len(), last.len());
                prop_assert!(s.iter().all(|&c| c < 9));
            }
        }
    }
}
