//! Cross-sections that hold both stems of a narrow fork.
//!
//! Where a thick limb parts from its stem at a narrow angle, the two stems'
//! bark rings touch for a metre or more above the fork: the limb's axis
//! moves away from the stem's by only `sin θ` per metre. The points of one
//! geodesic bin there are linked across the crotch, so
//! [`super::skeletonize`] makes one section of both rings, a peanut-shaped
//! band whose centroid (or fitted circle) lies in the crotch, on the bark
//! between the two axes. On the clean synthetic oak s1 the trunk's skeleton
//! ran 0.1–0.2 m off its axis over most of the crown's height this way, and
//! 27 % of the skeleton length of stems 0.1–0.2 m thick lay more than 0.1 m
//! from any true branch.
//!
//! [`split_two_stem_sections`] splits a thick section in two when two
//! circles fit its points much better than one (the ring fit of
//! lsystem-from-adtree-skeletons §2.1.1's centring, applied per stem). Each
//! half then becomes a node on its own stem's axis, and the fork appears
//! where the rings first part.

use foldhash::{HashMap, HashMapExt};

use glam::{Vec2, Vec3};

use super::graph::UnionFind;
use super::skeletonize::{Across, band_axis};
use crate::reconstruct::principal_spreads;
use crate::reconstruct::radii::{Circle, kasa_fit};

/// Which sections [`split_two_stem_sections`] tries, and when it splits.
#[derive(Debug, Clone, Copy)]
pub(super) struct TwoStemRule {
    /// Sections whose points spread less than this from their centroid
    /// (RMS, metres) are thin and kept whole.
    pub(super) min_spread_m: f32,
    /// Each stem needs at least this many points.
    pub(super) min_points: usize,
    /// Split only when the two circles' mean deviation is at most this
    /// share of the single circle's.
    pub(super) max_deviation_share: f32,
}

/// The points of a split section lie, on average, within this share of the
/// thinner circle's radius from their circles. On the clean synthetic oaks
/// real two-stem sections deviate by 2–10 % of it; the sections of pine
/// whorls that two circles fitted better than one, by 15–25 %.
const RING_DEVIATION_SHARE: f32 = 0.15;

/// How far short of a circle's far side, as a share of its radius, a split
/// section's points may end ([`spans_both`]).
const SPAN_SLACK: f32 = 0.2;

/// Rounds of assigning points to the nearer circle and refitting.
const ROUNDS: usize = 8;

/// Splits the sections of `uf` (one set per cross-section) that hold two
/// stems' rings and returns the new sets. Each half's parent is found as
/// any section's is (the section below its lowest point).
pub(super) fn split_two_stem_sections(
    points: &[Vec3],
    uf: &mut UnionFind,
    rule: &TwoStemRule,
) -> UnionFind {
    let n = points.len();
    let root: Vec<u32> = (0..n as u32).map(|i| uf.find(i)).collect();
    let mut count = vec![0usize; n];
    for &r in &root {
        count[r as usize] += 1;
    }
    // Only sections big enough for two stems are gathered.
    let mut members: HashMap<u32, Vec<u32>> = HashMap::new();
    for (i, &r) in root.iter().enumerate() {
        if count[r as usize] >= 2 * rule.min_points {
            members.entry(r).or_default().push(i as u32);
        }
    }
    let mut second = vec![false; n];
    for group in members.values() {
        let pts: Vec<Vec3> = group.iter().map(|&i| points[i as usize]).collect();
        let Some(halves) = two_stems(&pts, rule) else {
            continue;
        };
        for (&i, &h) in group.iter().zip(&halves) {
            second[i as usize] = h;
        }
    }
    let mut out = UnionFind::new(n);
    let mut first_of: HashMap<(u32, bool), u32> = HashMap::new();
    for i in 0..n as u32 {
        let key = (root[i as usize], second[i as usize]);
        match first_of.get(&key) {
            Some(&f) => out.union(f, i),
            None => {
                first_of.insert(key, i);
            }
        }
    }
    out
}

/// For each point of a thick section that forms a flat band (see
/// [`band_axis`]), which of two stems it belongs to, or `None` when one
/// ring explains the section as well.
fn two_stems(pts: &[Vec3], rule: &TwoStemRule) -> Option<Vec<bool>> {
    let [largest, middle, least] = principal_spreads(pts);
    let spread = (largest * largest + middle * middle + least * least).sqrt();
    if spread < f64::from(rule.min_spread_m) {
        return None;
    }
    let flat = Across::new(pts, band_axis(pts)?).flat(pts);
    let one = kasa_fit(&flat)?;
    let one_deviation = flat.iter().map(|&q| deviation(q, &one)).sum::<f32>() / flat.len() as f32;
    let mut halves = initial_halves(&flat);
    let mut circles = (one, one);
    for _ in 0..ROUNDS {
        circles = (
            fit_part(&flat, &halves, false)?,
            fit_part(&flat, &halves, true)?,
        );
        let next: Vec<bool> = flat
            .iter()
            .map(|&q| deviation(q, &circles.1) < deviation(q, &circles.0))
            .collect();
        if next == halves {
            break;
        }
        halves = next;
    }
    let (a, b) = circles;
    let count_b = halves.iter().filter(|&&h| h).count();
    let count_a = halves.len() - count_b;
    let two_deviation = flat
        .iter()
        .map(|&q| deviation(q, &a).min(deviation(q, &b)))
        .sum::<f32>()
        / flat.len() as f32;
    let apart = a.centre.distance(b.centre) > 0.5 * (a.radius + b.radius);
    let (thin, thick) = (a.radius.min(b.radius), a.radius.max(b.radius));
    // Two rings, each thinner than the one that would hold both, and each
    // followed closely by its points: a whorl's lumps of branch bases fit
    // two wide circles loosely.
    let plausible = thick < one.radius
        && two_deviation <= RING_DEVIATION_SHARE * thin
        && spans_both(&flat, &a, &b);
    (count_a.min(count_b) >= rule.min_points
        && apart
        && plausible
        && two_deviation <= rule.max_deviation_share * one_deviation)
        .then_some(halves)
}

/// Whether the points reach the far sides of both circles along the line
/// through their centres, as a section across two stems does. Circles fitted
/// to arcs of a whorl's branch bases run beyond the points.
fn spans_both(flat: &[Vec2], a: &Circle, b: &Circle) -> bool {
    let line = (b.centre - a.centre).normalize_or_zero();
    let (lo, hi) = flat
        .iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), q| {
            let t = (*q - a.centre).dot(line);
            (lo.min(t), hi.max(t))
        });
    let (far_a, far_b) = (-a.radius, a.centre.distance(b.centre) + b.radius);
    lo <= far_a + SPAN_SLACK * a.radius && hi >= far_b - SPAN_SLACK * b.radius
}

/// The two ends of the band's long direction.
fn initial_halves(flat: &[Vec2]) -> Vec<bool> {
    let (mut sxx, mut sxy, mut syy) = (0f32, 0f32, 0f32);
    for q in flat {
        sxx += q.x * q.x;
        sxy += q.x * q.y;
        syy += q.y * q.y;
    }
    // Direction of the larger eigenvalue of the 2×2 scatter matrix.
    let angle = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    let long = Vec2::from_angle(angle);
    flat.iter().map(|q| q.dot(long) > 0.0).collect()
}

fn fit_part(flat: &[Vec2], halves: &[bool], which: bool) -> Option<Circle> {
    let part: Vec<Vec2> = flat
        .iter()
        .zip(halves)
        .filter(|&(_, &h)| h == which)
        .map(|(&q, _)| q)
        .collect();
    if part.len() < 3 {
        return None;
    }
    kasa_fit(&part).filter(|c| c.radius.is_finite())
}

fn deviation(q: Vec2, c: &Circle) -> f32 {
    (q.distance(c.centre) - c.radius).abs()
}

#[cfg(test)]
mod tests {
    use super::*;

    const RULE: TwoStemRule = TwoStemRule {
        min_spread_m: 0.06,
        min_points: 12,
        max_deviation_share: 0.5,
    };

    /// `n` points on a horizontal circle, in a band 2 cm deep.
    fn ring(centre: Vec2, radius: f32, n: usize) -> Vec<Vec3> {
        (0..n)
            .map(|k| {
                let a = k as f32 * std::f32::consts::TAU / n as f32;
                let z = 0.02 * ((k * 7) % 5) as f32 / 4.0;
                (centre + radius * Vec2::from_angle(a)).extend(z)
            })
            .collect()
    }

    /// Two rings that overlap, without the points of each inside the other.
    fn peanut(a: (Vec2, f32), b: (Vec2, f32)) -> Vec<Vec3> {
        let outside = |p: &Vec3, (c, r): (Vec2, f32)| p.truncate().distance(c) > r;
        let mut pts: Vec<Vec3> = ring(a.0, a.1, 80)
            .into_iter()
            .filter(|p| outside(p, b))
            .collect();
        pts.extend(ring(b.0, b.1, 70).into_iter().filter(|p| outside(p, a)));
        pts
    }

    #[test]
    fn one_ring_stays_whole() {
        assert!(two_stems(&ring(Vec2::ZERO, 0.2, 120), &RULE).is_none());
    }

    #[test]
    fn two_touching_rings_part_along_the_crotch() {
        let (a, b) = ((Vec2::ZERO, 0.2), (Vec2::new(0.3, 0.0), 0.15));
        let pts = peanut(a, b);
        let halves = two_stems(&pts, &RULE).expect("two stems");
        // Each half holds the points of one ring: those nearer to its centre.
        let first = |p: &Vec3| p.truncate().distance(a.0) - a.1 < p.truncate().distance(b.0) - b.1;
        let agree = pts
            .iter()
            .zip(&halves)
            .filter(|&(p, &h)| first(p) != h)
            .count();
        assert!(agree == pts.len() || agree == 0, "{agree} of {}", pts.len());
    }

    #[test]
    fn a_whorl_is_no_second_stem() {
        // A stem's ring with four branches leaving it across the bin: each
        // cut lengthwise, two lines of bark either side of its axis. Two
        // wide circles through the branches' ends fit it better than one.
        let mut pts = ring(Vec2::ZERO, 0.14, 100);
        for b in 0..4 {
            let dir = Vec2::from_angle(0.3 + b as f32 * std::f32::consts::FRAC_PI_2);
            for k in 0..60 {
                let along = dir * (0.14 + 0.01 * (k / 2) as f32);
                let side = dir.perp() * if k % 2 == 0 { 0.03 } else { -0.03 };
                pts.push((along + side).extend(0.01));
            }
        }
        assert!(two_stems(&pts, &RULE).is_none());
    }

    #[test]
    fn splitting_gives_each_stem_its_own_section() {
        let pts = peanut((Vec2::ZERO, 0.2), (Vec2::new(0.3, 0.0), 0.15));
        let mut uf = UnionFind::new(pts.len());
        for i in 1..pts.len() as u32 {
            uf.union(0, i);
        }
        let mut out = split_two_stem_sections(&pts, &mut uf, &RULE);
        let roots: foldhash::HashSet<u32> = (0..pts.len() as u32).map(|i| out.find(i)).collect();
        assert_eq!(roots.len(), 2);
    }
}
