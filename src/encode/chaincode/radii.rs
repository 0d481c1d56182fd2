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

/// The largest first-node radius of the lateral branches at each node (0
/// where none grows), for [`child_gaps`].
fn thickest_laterals(
    radii_of_first: impl Iterator<Item = u32>,
    parents: &[Option<usize>],
    n: usize,
) -> Option<Vec<u32>> {
    let mut out = vec![0u32; n];
    for (q, parent) in radii_of_first.zip(parents) {
        if let Some(p) = *parent {
            let slot = out.get_mut(p)?;
            *slot = (*slot).max(q);
        }
    }
    Some(out)
}

/// Child-predicted radius gaps (container kind 3, radius layout 2): a node
/// is predicted to be as thick as its thickest child, because radii never
/// grow towards the tips (the pipe model of airborne-lidar-tree-modeling
/// §5.5: a segment's cross-section feeds all of its children's, so it is at
/// least each one's; the reconstruction enforces it). Returns `(tips,
/// inner)`: each branch's tip radius (the same values as the tip-first
/// layout's), and for every other node, in decoding order, its radius minus
/// the largest radius among its children (main extension and laterals):
/// mostly 0, and at a fork what the pipe adds to the thickest child.
/// Integer `max` and subtraction only, so every machine decodes the same.
pub(crate) fn child_gaps(
    radii: &[u32],
    chains: &[usize],
    parents: &[Option<usize>],
) -> (Vec<i64>, Vec<i64>) {
    let firsts = chain_starts(chains).map(|s| radii[s]);
    let laterals =
        thickest_laterals(firsts, parents, radii.len()).expect("parents are nodes of the code");
    let mut tips = Vec::with_capacity(chains.len());
    let mut inner = Vec::with_capacity(radii.len());
    for (start, &len) in chain_starts(chains).zip(chains) {
        for i in start..start + len - 1 {
            let thickest = radii[i + 1].max(laterals[i]);
            inner.push(i64::from(radii[i]) - i64::from(thickest));
        }
        tips.push(i64::from(radii[start + len - 1]));
    }
    (tips, inner)
}

/// The first node of each chain, in decoding order.
fn chain_starts(chains: &[usize]) -> impl Iterator<Item = usize> + '_ {
    chains.iter().scan(0usize, |start, &len| {
        let s = *start;
        *start += len;
        Some(s)
    })
}

/// Inverts [`child_gaps`], from the last branch back to the trunk and from
/// each tip back to its branch's base (every child is decoded before its
/// parent). `None` if a radius leaves `0..=2^30`, a parent is not a node of
/// an earlier branch, a chain is empty or a list has the wrong length.
pub(crate) fn radii_from_child_gaps(
    (tips, inner): (&[i64], &[i64]),
    chains: &[usize],
    parents: &[Option<usize>],
) -> Option<Vec<u32>> {
    let n = inner.len().checked_add(tips.len())?;
    if tips.len() != chains.len() || parents.len() != chains.len() || chains.contains(&0) {
        return None;
    }
    let starts: Vec<usize> = chain_starts(chains).collect();
    if chains.iter().try_fold(0usize, |a, &l| a.checked_add(l)) != Some(n) {
        return None;
    }
    let checked = |r: i64| (0..=MAX_Q as i64).contains(&r).then_some(r as u32);
    let mut out = vec![0u32; n];
    let mut laterals = vec![0u32; n];
    for b in (0..chains.len()).rev() {
        let (start, len) = (starts[b], chains[b]);
        let last = (start + len).checked_sub(1)?;
        let mut next = checked(tips[b])?;
        out[last] = next;
        for i in (start..last).rev() {
            // `inner` skips each earlier branch's tip: `b` of them.
            let gap = inner[i - b];
            next = checked(i64::from(next.max(laterals[i])).checked_add(gap)?)?;
            out[i] = next;
        }
        if let Some(p) = parents[b] {
            if p >= start {
                return None;
            }
            laterals[p] = laterals[p].max(out[start]);
        }
    }
    Some(out)
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

    #[test]
    fn child_gaps_predict_a_node_from_its_thickest_child() {
        // Trunk 30, 28, 27 (the root first); laterals 9, 8 and 12 forking
        // at node 1, which is predicted from max(27, 9, 12) = 27.
        let (radii, chains, parents) =
            ([30, 28, 27, 9, 8, 12], [3, 2, 1], [None, Some(1), Some(1)]);
        let (tips, inner) = child_gaps(&radii, &chains, &parents);
        assert_eq!(tips, vec![27, 8, 12]);
        assert_eq!(inner, vec![2, 1, 1]);
        let back = radii_from_child_gaps((&tips, &inner), &chains, &parents);
        assert_eq!(back.unwrap(), radii);
        // A parent on the same or a later branch, a wrong count or a radius
        // out of range is refused.
        assert!(
            radii_from_child_gaps((&tips, &inner), &chains, &[None, Some(3), Some(1)]).is_none()
        );
        assert!(radii_from_child_gaps((&tips, &inner[1..]), &chains, &parents).is_none());
        assert!(radii_from_child_gaps((&tips, &[2, 1, -30]), &chains, &parents).is_none());
        assert!(radii_from_child_gaps((&tips, &[i64::MAX, 1, 1]), &chains, &parents).is_none());
        // An empty chain would shift the tips' count off the nodes.
        let (tips, inner) = ([27, 8, 0, 12], [2, 1]);
        let empty = radii_from_child_gaps(
            (&tips, &inner),
            &[3, 1, 0, 2],
            &[None, Some(1), Some(1), Some(1)],
        );
        assert!(empty.is_none());
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
            prop_assert_eq!(&radii_from_gaps(&gaps, &lens).unwrap(), &radii);
            // Child-predicted, with each lateral forking from an earlier
            // branch's first node.
            let starts: Vec<usize> = chain_starts(&lens).collect();
            let parents: Vec<Option<usize>> = (0..lens.len())
                .map(|b| (b > 0).then(|| starts[b / 2]))
                .collect();
            let (tips, inner) = child_gaps(&radii, &lens, &parents);
            prop_assert_eq!(radii_from_child_gaps((&tips, &inner), &lens, &parents).unwrap(), radii);
        }
    }
}
