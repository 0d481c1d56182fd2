//! Where a branch's tip goes: to the scan's last point of the branch, and
//! on a twig a little beyond it.
//!
//! A tip node is the centroid of its branch's last cross-section, so it
//! stops short of the last points the scan holds of that branch by up to a
//! bin width. AdTree's skeleton ends on a point, because its graph's
//! vertices are the points (lsystem-from-adtree-skeletons §2.1.1). The first
//! step, [`TipRule::reach_last_points`], moves every tip forward along its
//! internode to the farthest point ahead of it within the branch's reach.
//!
//! A twig's true end lies farther still: a scanner samples a twig's bark
//! at random, and the last sample falls short of the end. If the points
//! along a twig form a Poisson process with rate λ (points per metre), the
//! distance from the last point to the end is exponential with rate λ
//! (memorylessness), whatever the twig's length; its median is ln 2 / λ.
//! The second step, [`TipRule::expected_gap`], extends each thin tip by that
//! median, with λ counted over the twig's last [`GAP_SPAN_BINS`] bin widths
//! and the extension capped at [`MAX_GAP_BINS`] and [`MAX_GAP_M`]. The airborne pipeline does
//! the same for the tree's height (`metrics::apex_gap`). Short laterals
//! near a thick stem are left alone: most are patches of the stem's own
//! bark, which have no end to extrapolate.

use glam::Vec3;

use crate::skeleton::{NodeId, Skeleton};
use crate::spatial::PointIndex;

/// The points that set a twig's rate λ lie within this many bin widths
/// behind its end.
pub(super) const GAP_SPAN_BINS: f32 = 10.0;

/// A twig's end moves at most this many bin widths beyond its last point.
pub(super) const MAX_GAP_BINS: f32 = 3.0;

/// …and at most this far, in metres. On a sparse cloud (an airborne scan
/// run through the dense pipeline) bins are decimetres wide, and a gap of
/// several of them is missing data, not a twig's last sampling gap: with
/// the bin cap alone, tiny.xyz in `--mode dense` lost 4 points of its
/// points within 2 cm of the cylinders.
pub(super) const MAX_GAP_M: f32 = 0.1;

/// How [`place_tips`] treats the tips.
#[derive(Debug, Clone, Copy)]
pub(super) struct TipRule {
    /// Width of the geodesic bins, in metres.
    pub(super) bin_m: f32,
    /// Move tips to the last point ahead of them.
    pub(super) reach_last_points: bool,
    /// Extend twigs by the median gap to their true end.
    pub(super) expected_gap: bool,
}

/// A tip, the direction it grows in, and how far across that direction
/// its branch's points may lie.
struct TipLine {
    at: Vec3,
    direction: Vec3,
    reach: f32,
}

/// Places every tip of `skeleton` (radii still holding the sections'
/// spread) as `rule` says, from the cleaned `points` that `index` holds.
pub(super) fn place_tips(
    skeleton: &mut Skeleton,
    points: &[Vec3],
    index: &PointIndex,
    rule: &TipRule,
) {
    let tips: Vec<NodeId> = skeleton
        .ids()
        .filter(|&id| id != NodeId::ROOT && skeleton.is_tip(id))
        .collect();
    for tip in tips {
        let Some(mut line) = TipLine::of(skeleton, tip, rule.bin_m) else {
            continue;
        };
        if rule.reach_last_points {
            line.at += line.direction * line.farthest_ahead(points, index, rule.bin_m);
        }
        if rule.expected_gap && is_twig(skeleton, tip, line.at, rule.bin_m) {
            line.at += line.direction * line.median_gap(points, index, rule.bin_m);
        }
        skeleton.set_position(tip, line.at);
    }
}

impl TipLine {
    /// The line of `tip`'s incoming internode; its reach is the tip's
    /// spread or one bin width, whichever is larger. `None` at a tip
    /// without a direction.
    fn of(skeleton: &Skeleton, tip: NodeId, bin_m: f32) -> Option<TipLine> {
        let at = skeleton.position(tip);
        let from = skeleton.position(skeleton.parent(tip)?);
        Some(TipLine {
            at,
            direction: (at - from).try_normalize()?,
            reach: skeleton.radius(tip).max(bin_m),
        })
    }

    /// Offsets from the tip of the points within `radius` of it and within
    /// the reach of its line.
    fn offsets(&self, points: &[Vec3], index: &PointIndex, radius: f32) -> Vec<Vec3> {
        index
            .within(self.at, radius)
            .into_iter()
            .map(|n| points[n.index] - self.at)
            .filter(|d| (*d - self.direction * d.dot(self.direction)).length() <= self.reach)
            .collect()
    }

    /// How far ahead of the tip the branch's last point lies (0 if none
    /// does); only points within the reach plus a bin width count.
    fn farthest_ahead(&self, points: &[Vec3], index: &PointIndex, bin_m: f32) -> f32 {
        self.offsets(points, index, self.reach + bin_m)
            .iter()
            .map(|d| d.dot(self.direction))
            .fold(0.0, f32::max)
    }

    /// The median distance from the last point to the twig's end, ln 2 / λ,
    /// with λ the points per metre behind the tip (module docs).
    fn median_gap(&self, points: &[Vec3], index: &PointIndex, bin_m: f32) -> f32 {
        let span = GAP_SPAN_BINS * bin_m;
        let behind = self
            .offsets(points, index, span)
            .iter()
            .filter(|d| d.dot(self.direction) <= 0.0)
            .count();
        let rate = behind.max(1) as f32 / span;
        (std::f32::consts::LN_2 / rate)
            .min(MAX_GAP_BINS * bin_m)
            .min(MAX_GAP_M)
    }
}

/// True when `tip`, ending at `end`, is a twig whose end may be
/// extrapolated: thinner than a bin width, and not a short lateral of a
/// thick stem (its fork's spread at least two bin widths, and `end` within
/// that spread plus [`GAP_SPAN_BINS`] bin widths of the fork).
fn is_twig(skeleton: &Skeleton, tip: NodeId, end: Vec3, bin_m: f32) -> bool {
    if skeleton.radius(tip) >= bin_m {
        return false;
    }
    let Some(fork) = fork_below(skeleton, tip) else {
        return true;
    };
    let spread = skeleton.radius(fork);
    spread < 2.0 * bin_m || end.distance(skeleton.position(fork)) >= spread + GAP_SPAN_BINS * bin_m
}

/// The nearest ancestor of `id` with more than one child.
fn fork_below(skeleton: &Skeleton, id: NodeId) -> Option<NodeId> {
    let mut at = skeleton.parent(id)?;
    while skeleton.children(at).len() < 2 {
        at = skeleton.parent(at)?;
    }
    Some(at)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::skeleton::Anchor;

    const BIN: f32 = 0.03;

    fn rule(expected_gap: bool) -> TipRule {
        TipRule {
            bin_m: BIN,
            reach_last_points: true,
            expected_gap,
        }
    }

    /// Points every `step` metres along z down from `top` to the ground, at `x`.
    fn twig(x: f32, top: f32, step: f32) -> Vec<Vec3> {
        let n = (top / step) as usize;
        (0..=n)
            .map(|k| Vec3::new(x, 0.0, top - k as f32 * step))
            .collect()
    }

    /// A twig sampled every 2 cm up to 1.00 m, whose skeleton ends at the
    /// centroid of its last section, 2 cm short. A second twig runs on past
    /// it 5 cm to the side: its points are not this twig's end.
    #[test]
    fn a_tip_moves_to_the_last_point_of_its_own_twig() {
        let mut points = twig(0.0, 1.0, 0.02);
        points.extend(twig(0.05, 1.2, 0.02));
        let index = PointIndex::new(&points);
        let mut s = Skeleton::new(Anchor::default(), 0.004);
        let tip = s.add_child(NodeId::ROOT, Vec3::new(0.0, 0.0, 0.98), 0.004);
        place_tips(&mut s, &points, &index, &rule(false));
        assert!(s.position(tip).distance(Vec3::new(0.0, 0.0, 1.0)) < 1e-5);
        assert_eq!(s.position(NodeId::ROOT), Vec3::ZERO);
    }

    /// A twig sampled every 4 cm (8 points in its last 0.3 m) goes on by
    /// ln 2 · 0.3 / 8 m beyond its last point; one sampled every 1.6 cm
    /// (19 points) by less than half that.
    #[test]
    fn a_twig_ends_the_median_gap_beyond_its_last_point() {
        for (step, behind) in [(0.04, 8.0), (0.016, 19.0)] {
            let points = twig(0.0, 1.0, step);
            let index = PointIndex::new(&points);
            let mut s = Skeleton::new(Anchor::default(), 0.004);
            let tip = s.add_child(NodeId::ROOT, Vec3::new(0.0, 0.0, 1.0), 0.004);
            place_tips(&mut s, &points, &index, &rule(true));
            let gap = std::f32::consts::LN_2 * GAP_SPAN_BINS * BIN / behind;
            assert!((s.position(tip).z - (1.0 + gap)).abs() < 1e-4, "{step}");
        }
    }

    /// A stem of 0.2 m spread with a 10 cm lateral from its axis to its
    /// bark: the lateral reaches its last point, and no farther.
    #[test]
    fn a_short_lateral_of_a_thick_stem_is_not_extrapolated() {
        let points = vec![Vec3::new(0.0, 0.0, 1.0), Vec3::new(0.1, 0.0, 1.0)];
        let index = PointIndex::new(&points);
        let mut s = Skeleton::new(Anchor::default(), 0.2);
        let fork = s.add_child(NodeId::ROOT, Vec3::new(0.0, 0.0, 1.0), 0.2);
        s.add_child(fork, Vec3::new(0.0, 0.0, 2.0), 0.2);
        let lateral = s.add_child(fork, Vec3::new(0.09, 0.0, 1.0), 0.004);
        place_tips(&mut s, &points, &index, &rule(true));
        assert!(s.position(lateral).distance(Vec3::new(0.1, 0.0, 1.0)) < 1e-5);
    }
}
