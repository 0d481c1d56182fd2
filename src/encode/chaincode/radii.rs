//! Radius quantisation and the radius sequence transform of chain-code paper
//! §3.3: per branch, inverted (tip to base) and turned into d-gaps, then
//! concatenated and made non-negative so that its cumulative sum can be
//! interpolatively coded.
//!
//! Radii are stored as integers `q = round(radius_m / step)`, so the decoded
//! radius `q·step` is within `step/2` of the original (plus `f32` rounding).
//! The paper's radii were bud counts that never grow towards the tip; real
//! radii can, so a gap may be negative. Two ways to make the list
//! non-negative are tried and the shorter kept: subtracting the smallest
//! value (the paper's zero alignment) or zigzag mapping (0, −1, 1, −2, … →
//! 0, 1, 2, 3, …), which does not let one outlier shift every value.

use super::ChainError;

/// Largest quantised radius; keeps cumulative sums far below 2^62.
const MAX_Q: u64 = 1 << 30;

/// `round(radius_m / step_m)`, or an error if it does not fit.
/// True if a quantised radius is within the range the byte forms carry.
pub(crate) fn in_range(q: u32) -> bool {
    u64::from(q) <= MAX_Q
}

pub(crate) fn quantise(radius_m: f32, step_m: f32) -> Result<u32, ChainError> {
    let q = (f64::from(radius_m) / f64::from(step_m)).round();
    if q.is_finite() && (0.0..=MAX_Q as f64).contains(&q) {
        Ok(q as u32)
    } else {
        Err(ChainError::RadiusOutOfRange { radius_m, step_m })
    }
}

/// How the signed gap list was made non-negative.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum GapMapping {
    /// `value - min`, with `min` (≤ every value) stored.
    Offset(i64),
    /// Zigzag: `2v` for `v ≥ 0`, `-2v - 1` for `v < 0`.
    Zigzag,
}

impl GapMapping {
    pub(crate) fn apply(self, v: i64) -> u64 {
        match self {
            GapMapping::Offset(min) => (v - min) as u64,
            GapMapping::Zigzag => ((v << 1) ^ (v >> 63)) as u64,
        }
    }

    /// The inverse; `None` if the result leaves the radius range.
    pub(crate) fn invert(self, u: u64) -> Option<i64> {
        if u > 4 * MAX_Q {
            return None;
        }
        let u = u as i64;
        match self {
            GapMapping::Offset(min) => u.checked_add(min),
            GapMapping::Zigzag => Some((u >> 1) ^ -(u & 1)),
        }
    }
}

/// Signed per-branch gaps: for each chain (contiguous in `radii`), its tip
/// radius followed by the increases from tip towards base.
pub(crate) fn branch_gaps(radii: &[u32], chains: &[usize]) -> Vec<i64> {
    let mut out = Vec::with_capacity(radii.len());
    let mut start = 0;
    for &len in chains {
        let chain = &radii[start..start + len];
        let mut prev = None;
        for &r in chain.iter().rev() {
            let r = i64::from(r);
            out.push(prev.map_or(r, |p| r - p));
            prev = Some(r);
        }
        start += len;
    }
    out
}

/// Inverts [`branch_gaps`]; `None` if a radius leaves `0..=2^30`.
pub(crate) fn radii_from_gaps(gaps: &[i64], chains: &[usize]) -> Option<Vec<u32>> {
    let mut out = vec![0u32; gaps.len()];
    let mut start = 0;
    for &len in chains {
        let chain = out.get_mut(start..start + len)?;
        let mut prev: Option<i64> = None;
        for (slot, &g) in chain.iter_mut().rev().zip(&gaps[start..start + len]) {
            let r = prev.map_or(Some(g), |p| p.checked_add(g))?;
            if !(0..=MAX_Q as i64).contains(&r) {
                return None;
            }
            *slot = r as u32;
            prev = Some(r);
        }
        start += len;
    }
    (start == gaps.len()).then_some(out)
}

/// Parent-predicted radius gaps (container kind 3): each lateral branch's
/// base radius as a decrease from its fork node's radius (the pipe model:
/// a lateral is rarely thicker than its parent), then the decreases from
/// base towards the tip along every branch. Returns `(bases, along)`: one
/// base per lateral branch (the trunk's base is the root radius, stored on
/// its own), one decrease per node after a branch's first.
pub(crate) fn parent_gaps(
    radii: &[u32],
    chains: &[usize],
    parents: &[Option<usize>],
) -> (Vec<i64>, Vec<i64>) {
    let mut bases = Vec::with_capacity(chains.len());
    let mut along = Vec::with_capacity(radii.len());
    let mut start = 0;
    for (&len, parent) in chains.iter().zip(parents) {
        let chain = &radii[start..start + len];
        if let Some(p) = *parent {
            bases.push(i64::from(radii[p]) - i64::from(chain[0]));
        }
        along.extend(chain.windows(2).map(|w| i64::from(w[0]) - i64::from(w[1])));
        start += len;
    }
    (bases, along)
}

/// Inverts [`parent_gaps`]; `None` if a radius leaves `0..=2^30`, a parent
/// is not an earlier node or a list has the wrong length.
pub(crate) fn radii_from_parent_gaps(
    root_q: u64,
    (bases, along): (&[i64], &[i64]),
    chains: &[usize],
    parents: &[Option<usize>],
) -> Option<Vec<u32>> {
    let mut out: Vec<u32> = Vec::with_capacity(along.len() + bases.len() + 1);
    let (mut bases, mut along) = (bases.iter(), along.iter());
    let checked = |r: i64| (0..=MAX_Q as i64).contains(&r).then_some(r as u32);
    for (&len, parent) in chains.iter().zip(parents) {
        let first = match *parent {
            None if out.is_empty() => checked(i64::try_from(root_q).ok()?)?,
            None => return None,
            Some(p) => checked(i64::from(*out.get(p)?) - bases.next()?)?,
        };
        out.push(first);
        for _ in 1..len {
            let prev = i64::from(*out.last()?);
            out.push(checked(prev - along.next()?)?);
        }
    }
    (bases.next().is_none() && along.next().is_none()).then_some(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn quantisation_bounds() {
        assert_eq!(quantise(0.0126, 0.001).unwrap(), 13);
        assert_eq!(quantise(0.0124, 0.001).unwrap(), 12);
        assert_eq!(quantise(0.0, 0.001).unwrap(), 0);
        assert!(quantise(1e30, 0.001).is_err());
    }

    #[test]
    fn gaps_of_a_tapering_branch_are_small() {
        // Two chains: trunk 30, 28, 27 and a lateral 9, 8.
        let g = branch_gaps(&[30, 28, 27, 9, 8], &[3, 2]);
        assert_eq!(g, vec![27, 1, 2, 8, 1]);
        assert_eq!(
            radii_from_gaps(&g, &[3, 2]).unwrap(),
            vec![30, 28, 27, 9, 8]
        );
    }

    #[test]
    fn parent_gaps_of_a_lateral_start_at_its_fork() {
        // Trunk 30, 28, 27 (the root first); a lateral 9, 8 forking at node 1.
        let (radii, chains, parents) = ([30, 28, 27, 9, 8], [3, 2], [None, Some(1)]);
        let (bases, along) = parent_gaps(&radii, &chains, &parents);
        assert_eq!(bases, vec![19]);
        assert_eq!(along, vec![2, 1, 1]);
        let back = radii_from_parent_gaps(30, (&bases, &along), &chains, &parents);
        assert_eq!(back.unwrap(), radii);
        // A parent that is not an earlier node is rejected.
        assert!(radii_from_parent_gaps(30, (&bases, &along), &chains, &[None, Some(3)]).is_none());
    }

    proptest! {
        #[test]
        fn round_trip(chains in proptest::collection::vec(
            proptest::collection::vec(0u32..5000, 1..20), 1..20)) {
            let radii: Vec<u32> = chains.iter().flatten().copied().collect();
            let lens: Vec<usize> = chains.iter().map(Vec::len).collect();
            let gaps = branch_gaps(&radii, &lens);
            let min = gaps.iter().copied().min().unwrap();
            for mapping in [GapMapping::Offset(min), GapMapping::Zigzag] {
                let mapped: Vec<u64> = gaps.iter().map(|&g| mapping.apply(g)).collect();
                let back: Vec<i64> = mapped.iter().map(|&u| mapping.invert(u).unwrap()).collect();
                prop_assert_eq!(&back, &gaps);
            }
            prop_assert_eq!(radii_from_gaps(&gaps, &lens).unwrap(), radii);
        }
    }
}
