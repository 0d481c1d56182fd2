//! Move-to-front transform (chain-code paper §3.3, step 2; Ryabko's "book
//! stack"): after the BWT, runs of equal symbols become runs of zeros.

/// Replaces each symbol by its index in a table that starts as
/// `0, 1, …, alphabet-1` and moves each symbol to the front once used.
///
/// # Panics
/// If a symbol is not below `alphabet` or `alphabet > 256`.
pub fn mtf_forward(symbols: &[u8], alphabet: usize) -> Vec<u8> {
    let mut table = initial_table(alphabet);
    symbols
        .iter()
        .map(|&s| {
            let idx = table[..alphabet]
                .iter()
                .position(|&t| t == s)
                .expect("symbol within the alphabet");
            table.copy_within(0..idx, 1);
            table[0] = s;
            idx as u8
        })
        .collect()
}

/// Inverts [`mtf_forward`]; `None` if an index is not below `alphabet`.
pub fn mtf_inverse(indices: &[u8], alphabet: usize) -> Option<Vec<u8>> {
    let mut table = initial_table(alphabet);
    let mut out = vec![0u8; indices.len()];
    for (slot, &i) in out.iter_mut().zip(indices) {
        // After the BWT most indices are 0: the table does not change.
        if i != 0 {
            let i = usize::from(i);
            if i >= alphabet {
                return None;
            }
            let s = table[i];
            table.copy_within(0..i, 1);
            table[0] = s;
        }
        *slot = table[0];
    }
    Some(out)
}

fn initial_table(alphabet: usize) -> [u8; 256] {
    assert!(alphabet <= 256, "alphabet of at most 256 symbols");
    let mut table = [0u8; 256];
    for (i, t) in table.iter_mut().enumerate() {
        *t = i as u8;
    }
    table
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn runs_become_zeros() {
        assert_eq!(mtf_forward(&[2, 2, 2, 1, 1, 2], 9), vec![2, 0, 0, 2, 0, 1]);
        assert_eq!(mtf_inverse(&[9], 9), None);
    }

    proptest! {
        #[test]
        fn round_trip(s in proptest::collection::vec(0u8..9, 0..500)) {
            let m = mtf_forward(&s, 9);
            prop_assert!(m.iter().all(|&i| i < 9));
            prop_assert_eq!(mtf_inverse(&m, 9), Some(s));
        }
    }
}
