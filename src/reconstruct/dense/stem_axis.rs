//! The trunk's axis through the centres of circles fitted to tall slices.
//!
//! A cross-section of [`super::skeletonize`] is one geodesic bin deep (a
//! few centimetres). On a thick stem seen from one side its node is the
//! centroid of the visible arc, up to a radius short of the axis, unless
//! the section holds enough points for `skeletonize`'s circle fit (12). A
//! sparse scan of a thick trunk holds fewer: tree13's trunk (radius about
//! 20 cm, scanned on about half its girth) gives 5–9 points per section;
//! its skeleton ran 15–19 cm off the axis from 0.1 to 1.4 m, and the radii
//! measured around that line came out at 0.11 m against the fitted DBH's
//! 0.20 m.
//!
//! AdTree fits its cylinders along the skeleton (lsystem-from-adtree-
//! skeletons §2.1.1, "Branch fitting"); here the trunk's nodes are moved
//! onto circles fitted, as for the DBH ([`robust_circle`]), to the points of
//! a slice [`StemRule::half_window_m`] above and below each node, projected
//! across the stem's local direction. In a crown such a slice also holds
//! twigs, through which large circles fit as tightly as the bark's; so the
//! trunk is tracked: from a seed fit low on the stem that is as well
//! supported as a fitted DBH, up and down the main stem for as long as each
//! fit is plausible and continues the last one (`Slices::track`). Each
//! slice after the seed is taken around the axis the tracked centres
//! predict, so the tracking goes on where the chain strays onto the bark or
//! a branch hugging it, as it does inside crowns. Nodes between tracked ones
//! are moved by the interpolated offset, and the offset fades out over
//! [`StemRule::fade_m`] beyond the last tracked node, so the stem does not
//! kink. The root, the tree's anchor, stays. Tracked nodes take their
//! circle's radius, which the radius stage reads as the stem's wood
//! (`radii::StemWood`) and as their measured radius: within 1–2 % of the
//! truth along clean synthetic pines' stems, whose sections, ringed by
//! whorls, read them 15–25 % thick.

use glam::{Vec2, Vec3};

use crate::reconstruct::radii::{
    Circle, MIN_TRUNK_SECTORS, circle_from, circle_rms, robust_circle, trunk_sectors_seen,
};
use crate::skeleton::{NodeId, Skeleton};
use crate::spatial::PointIndex;

/// How [`recentre_stem`] tracks the trunk.
#[derive(Debug, Clone, Copy)]
pub(super) struct StemRule {
    /// The slice reaches this far above and below a node along the stem,
    /// in metres (0: off).
    pub(super) half_window_m: f32,
    /// The stem's direction at a node is taken between the chain's nodes
    /// this far below and above it, in metres: a sparse one-sided trunk's
    /// chain zigzags between sections (tree13: 8–15 cm sideways over
    /// 5–30 cm), and a slice across a zigzag is an ellipse. With the slice's
    /// own half-height, 3 of tree13's trunk nodes below 1.3 m were tracked;
    /// with 1 m, 6.
    pub(super) axis_window_m: f32,
    /// Points are taken within this distance of the node across the stem,
    /// in metres: a trunk's radius and the node's offset from its axis.
    pub(super) reach_m: f32,
    /// Circles thinner than this (radius, metres) are left to the sections:
    /// a twig's few points fit any small circle.
    pub(super) min_radius_m: f32,
    /// Fewest inliers of a plausible circle…
    pub(super) min_points: usize,
    /// …and of the seed, the first plausible fit within
    /// [`StemRule::seed_height_m`] of the root: as many as a fitted DBH.
    pub(super) seed_points: usize,
    /// See [`StemRule::seed_points`], in metres above the root.
    pub(super) seed_height_m: f32,
    /// A fit whose radius differs from the last tracked one by more than
    /// this share of it is not the trunk.
    pub(super) max_change: f32,
    /// The offset fades out over this length of stem beyond the tracked
    /// nodes, in metres.
    pub(super) fade_m: f32,
}

/// Inliers must lie within this share of the circle's radius (RMS).
const MAX_RMS_SHARE: f32 = 0.1;

/// A tracked trunk ends after this many nodes in a row without a fit
/// that continues it.
const MAX_MISSES: usize = 2;

/// The least tolerance for a tracked centre's shift from its prediction,
/// and the margin of a tracked slice's reach, in metres.
const MIN_SHIFT_M: f32 = 0.02;

/// Tracked centres at least this far apart give the trunk's direction, in
/// metres.
const MIN_TRAIL_M: f32 = 0.3;

/// How [`Slices::fit`] finds a slice's circle.
#[derive(Debug, Clone, Copy)]
enum Start {
    /// Searched for ([`robust_circle`], a RANSAC), as for the seed: at
    /// least as large as the section's `spread` (an arc's centroid lies
    /// inside its circle).
    Search { spread: f32 },
    /// Refined ([`circle_from`]) from the circle of this radius about the
    /// predicted axis, as along the tracked trunk.
    From { radius: f32 },
}

/// One plausible circle fit of a slice.
#[derive(Debug, Clone, Copy)]
struct SliceFit {
    centre: Vec3,
    radius: f32,
    inliers: usize,
}

/// Moves the main stem's nodes onto the trunk's tracked axis and gives the
/// tracked ones their fitted radii (module docs).
/// `points` are the tree's points relative to the anchor, `index` their
/// index; children are in main-extension-first order. Returns the nodes
/// whose slice fit tracked the trunk.
pub(super) fn recentre_stem(
    skeleton: &mut Skeleton,
    points: &[Vec3],
    index: &PointIndex,
    rule: &StemRule,
) -> Vec<NodeId> {
    let chain = main_stem(skeleton);
    let slices = Slices {
        skeleton,
        chain: &chain,
        points,
        index,
        rule,
    };
    let base_z = skeleton.position(NodeId::ROOT).z;
    let seed = (1..chain.len())
        .take_while(|&k| skeleton.position(chain[k]).z - base_z <= rule.seed_height_m)
        .find_map(|k| {
            slices
                .at_node(k)
                .filter(|f| f.inliers >= rule.seed_points)
                .map(|f| (k, f))
        });
    let Some((seed, seed_fit)) = seed else {
        return Vec::new();
    };
    let tracked = slices.both_ways((seed, seed_fit), f32::INFINITY);
    for &(k, fit) in &tracked {
        skeleton.set_radius(chain[k], fit.radius);
    }
    move_onto_axis(skeleton, &chain, &tracked, rule.fade_m);
    tracked.into_iter().map(|(k, _)| chain[k]).collect()
}

/// How [`recentre_limbs`] picks and bounds the limbs it tracks.
#[derive(Debug, Clone, Copy)]
pub(super) struct LimbRule {
    /// A limb's circles may be at most this share of its fork's fitted
    /// radius (0: off).
    pub(super) max_share: f32,
    /// The seed fit is looked for at the limb's nodes within this distance
    /// of its fork, in metres.
    pub(super) seed_reach_m: f32,
    /// Laterals with less branch length than this behind them (metres)
    /// are not limbs: a branch as thick as a tracked circle carries more.
    pub(super) min_subtree_m: f32,
    /// Forks whose share would cap their limbs' circles below this radius
    /// (metres) are passed over: the excess length lies along limbs of 10
    /// to 30 cm, and thin limbs are what the sections already follow.
    pub(super) min_radius_m: f32,
}

/// Tracks the thick laterals of the tracked stem, and theirs in turn, as
/// [`recentre_stem`] tracks the trunk: each lateral chain (the lateral and
/// its first children) is seeded by a well-supported circle near its fork,
/// followed both ways, moved onto the fitted centres and given their radii.
/// `tracked` are the nodes already tracked (the trunk's); returns the
/// nodes newly tracked.
///
/// A limb seen from a few sides breaks into cross-sections on its bark:
/// the skeleton runs along the bark rather than the axis, in parallel
/// chains, with the radii of thin branches (stop 39's finding on occluded
/// oaks: nodes at 1.01 times the limb's radius from its axis, radii a
/// fifth of the truth). A slice half a metre tall holds enough of the
/// limb's returns for a circle where a 3 cm section does not. A crown's
/// slices also hold twigs, through which large circles fit: tracking every
/// heavy lateral from anywhere (tried: volume 3 to 6 times the truth) let
/// those through. So a limb must hang from a tracked node, and its circles
/// stay under [`LimbRule::max_share`] of that node's radius (pipe model:
/// a child is thinner than its parent).
///
/// Measured with `simplify::bark_strands` on limbs only (release build, `silva eval
/// --synthetic 20 --scan tls --repeat 1`, before → after): on the occluded
/// scans the oaks' precision rose by 0.5–1.7 points and their volume / true
/// from 0.80–0.87 to 0.90–0.98, poplars 3, 7 and 15 gained 2.3–4.2 points
/// of precision; the medians moved 0.9132 → 0.9160 (precision), 0.8512 →
/// 0.8509 (recall). Clean scans (`--density 1000 --no-occlusion`): recall
/// 0.9966 → 0.9963, precision 0.9949 → 0.9952. tree1 and tree13 are
/// unchanged (`silva eval --data`).
pub(super) fn recentre_limbs(
    skeleton: &mut Skeleton,
    points: &[Vec3],
    index: &PointIndex,
    tracked: &[NodeId],
    rule: (&StemRule, &LimbRule),
) -> Vec<NodeId> {
    let (stem, limb) = rule;
    if limb.max_share <= 0.0 {
        return Vec::new();
    }
    let mut fitted = vec![false; skeleton.len()];
    for id in tracked {
        fitted[id.index()] = true;
    }
    let mut limbs = Vec::new();
    let sub = skeleton.subtree_lengths();
    // Ids run parents first, so a limb tracked here can carry its own
    // limbs further on.
    for fork in skeleton.ids() {
        if !fitted[fork.index()] {
            continue;
        }
        let max_radius = limb.max_share * skeleton.radius(fork);
        if max_radius < limb.min_radius_m.max(stem.min_radius_m) {
            continue;
        }
        let laterals: Vec<NodeId> = skeleton.children(fork).iter().skip(1).copied().collect();
        for lateral in laterals {
            if sub[lateral.index()] < limb.min_subtree_m {
                continue;
            }
            let chain = branch_chain(skeleton, fork, lateral);
            let slices = Slices {
                skeleton,
                chain: &chain,
                points,
                index,
                rule: stem,
            };
            let found = slices.track_limb(limb.seed_reach_m, max_radius);
            for &(k, fit) in &found {
                skeleton.set_radius(chain[k], fit.radius);
                fitted[chain[k].index()] = true;
                limbs.push(chain[k]);
            }
            move_onto_axis(skeleton, &chain, &found, stem.fade_m);
        }
    }
    limbs
}

/// `fork`, then `first` and its chain of first children to a tip.
fn branch_chain(skeleton: &Skeleton, fork: NodeId, first: NodeId) -> Vec<NodeId> {
    first_children_from(skeleton, vec![fork, first])
}

/// Moves the chain's nodes (all but its first) by [`offsets`].
fn move_onto_axis(
    skeleton: &mut Skeleton,
    chain: &[NodeId],
    tracked: &[(usize, SliceFit)],
    fade_m: f32,
) {
    if tracked.is_empty() {
        return;
    }
    let offsets = offsets(skeleton, chain, tracked, fade_m);
    for (k, offset) in offsets.into_iter().enumerate().skip(1) {
        let node = chain[k];
        skeleton.set_position(node, skeleton.position(node) + offset);
    }
}

/// The slices of the main stem's points that [`recentre_stem`] fits.
struct Slices<'a> {
    skeleton: &'a Skeleton,
    chain: &'a [NodeId],
    points: &'a [Vec3],
    index: &'a PointIndex,
    rule: &'a StemRule,
}

impl Slices<'_> {
    /// The plausible circle of the slice around `chain[k]` across the
    /// chain's local direction, with the node inside it: how the seed is
    /// found.
    fn at_node(&self, k: usize) -> Option<SliceFit> {
        let at = self.skeleton.position(self.chain[k]);
        let dir = local_direction(self.skeleton, self.chain, k, self.rule.axis_window_m)?;
        let search = Start::Search {
            spread: self.spread(k),
        };
        self.fit(at, dir, self.rule.reach_m, search)
            .filter(|f| f.centre.distance(at) <= f.radius)
    }

    /// The fits of a limb's chain (`chain[0]` its fork): seeded at the
    /// first node within `seed_reach_m` of the fork whose slice gives a
    /// circle as well supported as the trunk's seed, then tracked both
    /// ways while the circles stay at most `max_radius`. Sorted along the
    /// chain; empty when nothing seeds.
    fn track_limb(&self, seed_reach_m: f32, max_radius: f32) -> Vec<(usize, SliceFit)> {
        let fork = self.skeleton.position(self.chain[0]);
        let at = |k: usize| self.skeleton.position(self.chain[k]);
        // Slices overlap: one try per half slice along the chain.
        let mut last_try: Option<Vec3> = None;
        let seed = (1..self.chain.len())
            .take_while(|&k| at(k).distance(fork) <= seed_reach_m)
            .filter(|&k| {
                let fresh = last_try.is_none_or(|p| p.distance(at(k)) >= self.rule.half_window_m);
                if fresh {
                    last_try = Some(at(k));
                }
                fresh
            })
            .find_map(|k| {
                self.at_node(k)
                    .filter(|f| f.inliers >= self.rule.seed_points && f.radius <= max_radius)
                    .map(|f| (k, f))
            });
        let Some((seed, fit)) = seed else {
            return Vec::new();
        };
        self.both_ways((seed, fit), max_radius)
    }

    /// The seed and the fits that continue it up and down the chain
    /// ([`Slices::track`]), each way only while the circles stay at most
    /// `max_radius`; sorted along the chain.
    fn both_ways(&self, seed: (usize, SliceFit), max_radius: f32) -> Vec<(usize, SliceFit)> {
        let thin_enough = |found: &(usize, SliceFit)| found.1.radius <= max_radius;
        let up = self.track(seed, seed.0 + 1..self.chain.len());
        let down = self.track(seed, (1..seed.0).rev());
        let mut tracked = vec![seed];
        tracked.extend(up.into_iter().take_while(thin_enough));
        tracked.extend(down.into_iter().take_while(thin_enough));
        tracked.sort_by_key(|&(k, _)| k);
        tracked
    }

    /// The fits that continue the trunk from `seed` along the chain's
    /// nodes `ks` (in walking order), until [`MAX_MISSES`] nodes in a row
    /// do not.
    ///
    /// Each slice is taken around the axis the tracked centres predict at
    /// the node's level, not around the node: in a crown the chain may run
    /// along the bark or out to a bark-hugging branch (a synthetic poplar's
    /// ran 0.18–0.26 m off its axis from 8 to 12 m, where its trunk is
    /// 0.2 m thick) and the tracking, needing the node inside the circle,
    /// stopped at the crown base. A fit continues the trunk when its radius
    /// and its centre's distance from the prediction are both within
    /// [`StemRule::max_change`] of the last radius, and the node lies
    /// within twice the radius of it (else the chain has left the trunk).
    fn track(
        &self,
        seed: (usize, SliceFit),
        ks: impl Iterator<Item = usize>,
    ) -> Vec<(usize, SliceFit)> {
        let mut trail = vec![seed];
        let mut last = seed.1.radius;
        let mut misses = 0;
        for k in ks {
            let at = self.skeleton.position(self.chain[k]);
            let found = self.predicted(&trail, k).and_then(|(guess, dir)| {
                let tolerance = (self.rule.max_change * last).max(MIN_SHIFT_M);
                let reach = self.rule.reach_m.min(2.0 * last + MIN_SHIFT_M);
                self.fit(guess, dir, reach, Start::From { radius: last })
                    .filter(|f| {
                        (f.radius - last).abs() <= self.rule.max_change * last
                            && f.centre.distance(guess) <= tolerance
                            && f.centre.distance(at) <= 2.0 * f.radius
                    })
            });
            match found {
                Some(f) => {
                    trail.push((k, f));
                    last = f.radius;
                    misses = 0;
                }
                None => misses += 1,
            }
            if misses >= MAX_MISSES {
                break;
            }
        }
        trail.split_off(1)
    }

    /// The trunk's axis at the level of `chain[k]` as the `trail` of
    /// tracked centres predicts it, and its direction: the line through the
    /// last centre and the earliest one within [`StemRule::axis_window_m`]
    /// of it when they are at least [`MIN_TRAIL_M`] apart, else the last
    /// centre along the chain's own direction.
    fn predicted(&self, trail: &[(usize, SliceFit)], k: usize) -> Option<(Vec3, Vec3)> {
        let last = trail.last()?.1.centre;
        let back = trail
            .iter()
            .map(|(_, f)| f.centre)
            .find(|c| c.distance(last) <= self.rule.axis_window_m)
            .filter(|c| c.distance(last) >= MIN_TRAIL_M);
        let dir = match back {
            Some(c) => (last - c).try_normalize()?,
            None => local_direction(self.skeleton, self.chain, k, self.rule.axis_window_m)?,
        };
        let at = self.skeleton.position(self.chain[k]);
        Some((last + dir * (at - last).dot(dir), dir))
    }

    /// The section's spread at `chain[k]` (its radius so far).
    fn spread(&self, k: usize) -> f32 {
        self.skeleton.radius(self.chain[k])
    }

    /// The circle fitted to the points within [`StemRule::half_window_m`]
    /// of `centre` along `dir` and within `reach` of it across, found as
    /// `start` says, if it is plausible: enough inliers over a third of the
    /// girth, tight, at least [`StemRule::min_radius_m`] (and the section's
    /// spread, for a search), with `centre` inside it.
    fn fit(&self, centre: Vec3, dir: Vec3, reach: f32, start: Start) -> Option<SliceFit> {
        let rule = self.rule;
        let (e1, e2) = dir.any_orthonormal_pair();
        let flat: Vec<Vec2> = self
            .index
            .within(centre, reach.hypot(rule.half_window_m))
            .iter()
            .map(|n| self.points[n.index] - centre)
            .filter(|d| d.dot(dir).abs() <= rule.half_window_m)
            .map(|d| Vec2::new(d.dot(e1), d.dot(e2)))
            .filter(|f| f.length() <= reach)
            .collect();
        if flat.len() < rule.min_points {
            return None;
        }
        let (circle, inliers, spread) = match start {
            Start::From { radius } => {
                let guess = Circle {
                    centre: Vec2::ZERO,
                    radius,
                };
                let (circle, inliers) = circle_from(&flat, guess, reach)?;
                (circle, inliers, 0.0)
            }
            Start::Search { spread } => {
                let (circle, inliers) = robust_circle(&flat, reach)?;
                (circle, inliers, spread)
            }
        };
        let plausible = inliers.len() >= rule.min_points
            && circle.radius >= spread.max(rule.min_radius_m)
            && circle.centre.length() <= circle.radius
            && circle_rms(&inliers, circle) <= MAX_RMS_SHARE * circle.radius
            && trunk_sectors_seen(&inliers, circle.centre) >= MIN_TRUNK_SECTORS;
        plausible.then(|| SliceFit {
            centre: centre + e1 * circle.centre.x + e2 * circle.centre.y,
            radius: circle.radius,
            inliers: inliers.len(),
        })
    }
}

/// Per node of `chain`, how far it moves: to its fitted centre where
/// tracked, interpolated (by length along the chain) between tracked nodes
/// and between the root (which stays) and the first, and fading to nothing
/// over `fade_m` beyond the last.
fn offsets(
    skeleton: &Skeleton,
    chain: &[NodeId],
    tracked: &[(usize, SliceFit)],
    fade_m: f32,
) -> Vec<Vec3> {
    let mut along = vec![0.0f32; chain.len()];
    for k in 1..chain.len() {
        along[k] = along[k - 1]
            + skeleton
                .position(chain[k])
                .distance(skeleton.position(chain[k - 1]));
    }
    let known: Vec<(f32, Vec3)> = std::iter::once((0.0, Vec3::ZERO))
        .chain(
            tracked
                .iter()
                .map(|&(k, f)| (along[k], f.centre - skeleton.position(chain[k]))),
        )
        .collect();
    let (end_s, end_offset) = known[known.len() - 1];
    along
        .iter()
        .map(|&s| {
            if s >= end_s {
                let fade = if fade_m > 0.0 {
                    1.0 - (s - end_s) / fade_m
                } else {
                    0.0
                };
                return end_offset * fade.max(0.0);
            }
            let j = known.partition_point(|&(t, _)| t <= s).max(1);
            let ((s0, o0), (s1, o1)) = (known[j - 1], known[j]);
            let t = if s1 > s0 { (s - s0) / (s1 - s0) } else { 1.0 };
            o0.lerp(o1, t)
        })
        .collect()
}

/// The root and its chain of first children: the trunk and the leader.
fn main_stem(skeleton: &Skeleton) -> Vec<NodeId> {
    first_children_from(skeleton, vec![NodeId::ROOT])
}

/// `chain` continued through the first children of its last node to a tip.
fn first_children_from(skeleton: &Skeleton, mut chain: Vec<NodeId>) -> Vec<NodeId> {
    while let Some(&next) = chain.last().and_then(|&at| skeleton.children(at).first()) {
        chain.push(next);
    }
    chain
}

/// The stem's direction at `chain[k]`: from the farthest chain node within
/// `half_window_m` below it to the farthest within as far above it (the
/// neighbours when none is that close; `None` if the two coincide).
fn local_direction(
    skeleton: &Skeleton,
    chain: &[NodeId],
    k: usize,
    half_window_m: f32,
) -> Option<Vec3> {
    let at = skeleton.position(chain[k]);
    let within = |i: &usize| skeleton.position(chain[*i]).distance(at) <= half_window_m;
    let below = (0..k).rev().take_while(within).last().unwrap_or(k - 1);
    let above = (k + 1..chain.len())
        .take_while(within)
        .last()
        .unwrap_or((k + 1).min(chain.len() - 1));
    (skeleton.position(chain[above]) - skeleton.position(chain[below])).try_normalize()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::skeleton::Anchor;

    fn rule() -> StemRule {
        StemRule {
            half_window_m: 0.25,
            axis_window_m: 1.0,
            reach_m: 0.6,
            min_radius_m: 0.06,
            min_points: 20,
            seed_points: 30,
            seed_height_m: 2.5,
            max_change: 0.3,
            fade_m: 1.0,
        }
    }

    /// The side of a vertical trunk of `radius` around the z axis that one
    /// scanner sees (a half ring every `dz`), up to `height`.
    fn half_trunk(radius: f32, height: f32, dz: f32) -> Vec<Vec3> {
        let rings = (height / dz) as usize;
        (0..rings)
            .flat_map(|i| {
                (0..12).map(move |j| {
                    let a = std::f32::consts::PI * (j as f32 + 0.5) / 12.0;
                    Vec3::new(radius * a.cos(), radius * a.sin(), i as f32 * dz)
                })
            })
            .collect()
    }

    /// A chain up the visible bark, as the sections' centroids leave it:
    /// 0.13 m off the axis towards the scanner, with a 3 cm zigzag.
    fn chain_on_the_bark(top: f32) -> Skeleton {
        let mut s = Skeleton::new(Anchor::default(), 0.2);
        let mut node = NodeId::ROOT;
        let mut z = 0.2;
        while z <= top {
            let wiggle = if (z * 10.0) as i32 % 2 == 0 {
                0.03
            } else {
                -0.03
            };
            node = s.add_child(node, Vec3::new(wiggle, 0.13, z), 0.07);
            z += 0.2;
        }
        s
    }

    #[test]
    fn a_one_sided_trunk_is_tracked_onto_its_axis() {
        let points = half_trunk(0.2, 4.0, 0.04);
        let index = PointIndex::new(&points);
        let mut skeleton = chain_on_the_bark(3.6);
        let moved = recentre_stem(&mut skeleton, &points, &index, &rule()).len();
        assert!(moved >= 15, "{moved} nodes tracked");
        for id in skeleton.ids().skip(1) {
            let p = skeleton.position(id);
            if p.z > 0.5 && p.z < 3.3 {
                assert!(p.truncate().length() < 0.02, "{p} off the axis");
            }
        }
        // The root, the anchor, stays.
        assert_eq!(skeleton.position(NodeId::ROOT), Vec3::ZERO);
    }

    /// Above the trunk, a crown's twigs fit circles far larger than the
    /// last tracked one: the tracking stops there, and the move fades out
    /// within `fade_m` of stem.
    #[test]
    fn the_tracking_ends_where_the_trunk_does() {
        let mut points = half_trunk(0.2, 2.0, 0.04);
        // A crown of twigs on a 1 m ring from 2 to 4 m, seen all round.
        for i in 0..400 {
            let a = i as f32 * 0.7;
            let z = 2.0 + (i % 50) as f32 * 0.04;
            points.push(Vec3::new(a.cos(), 0.13 + a.sin(), z));
        }
        let index = PointIndex::new(&points);
        let mut skeleton = chain_on_the_bark(4.0);
        let before = skeleton.clone();
        recentre_stem(&mut skeleton, &points, &index, &rule());
        for id in skeleton.ids().skip(1) {
            let (p, q) = (skeleton.position(id), before.position(id));
            if p.z < 1.6 {
                assert!(p.truncate().length() < 0.02, "{p} off the axis");
            }
            if q.z > 3.2 {
                assert_eq!(p, q, "a crown node moved");
            }
        }
    }

    /// Inside a crown the chain strays from the bark onto a branch hugging
    /// it: from 2 m up it runs 0.3 m off the axis of a 0.2 m trunk, outside
    /// the bark. The slices are taken where the tracked axis leads, so the
    /// trunk is followed to its top all the same (the tracking needed the
    /// node inside the circle, and stopped at 2 m).
    #[test]
    fn a_chain_that_strays_off_the_bark_is_tracked_through() {
        let points = half_trunk(0.2, 4.0, 0.04);
        let index = PointIndex::new(&points);
        let mut skeleton = Skeleton::new(Anchor::default(), 0.2);
        let mut node = NodeId::ROOT;
        for i in 1..=18 {
            let z = 0.2 * i as f32;
            let off = if z < 2.0 { 0.13 } else { 0.3 };
            node = skeleton.add_child(node, Vec3::new(0.0, off, z), 0.07);
        }
        let moved = recentre_stem(&mut skeleton, &points, &index, &rule()).len();
        assert!(moved >= 16, "{moved} nodes tracked");
        for id in skeleton.ids().skip(1) {
            let p = skeleton.position(id);
            if p.z > 0.5 {
                assert!(p.truncate().length() < 0.02, "{p} off the axis");
                let r = skeleton.radius(id);
                assert!((r - 0.2).abs() < 0.01, "radius {r} at {p}");
            }
        }
    }

    /// A trunk of radius 0.3 m seen all round up to 3 m, and a limb of
    /// radius 0.15 m leaving it at 2 m along +x, 45° up, seen on its upper
    /// half; with a skeleton whose trunk is tracked (radius 0.3) and whose
    /// limb chain runs on the limb's bark, 0.12 m above its axis, every
    /// 0.1 m for 2 m.
    fn trunk_and_limb() -> (Vec<Vec3>, Skeleton, Vec<NodeId>) {
        let along = Vec3::new(1.0, 0.0, 1.0).normalize();
        let up = Vec3::new(-1.0, 0.0, 1.0).normalize();
        let mut points: Vec<Vec3> = (0..150)
            .flat_map(|i| {
                (0..24).map(move |j| {
                    let a = std::f32::consts::TAU * j as f32 / 24.0;
                    Vec3::new(0.3 * a.cos(), 0.3 * a.sin(), 0.02 * i as f32)
                })
            })
            .collect();
        let base = Vec3::new(0.0, 0.0, 2.0);
        for i in 0..100 {
            for j in 0..12 {
                let a = std::f32::consts::PI * (j as f32 + 0.5) / 12.0;
                let across = up * a.sin() + Vec3::Y * a.cos();
                points.push(base + along * (0.02 * i as f32) + across * 0.15);
            }
        }
        let mut s = Skeleton::new(Anchor::default(), 0.3);
        let mut trunk = vec![NodeId::ROOT];
        for k in 1..=6 {
            let node = s.add_child(trunk[k - 1], Vec3::new(0.0, 0.0, 0.5 * k as f32), 0.3);
            trunk.push(node);
        }
        let mut at = trunk[4];
        for k in 1..=20 {
            at = s.add_child(at, base + along * (0.1 * k as f32) + up * 0.12, 0.05);
        }
        (points, s, trunk)
    }

    fn limb_rule(max_share: f32) -> LimbRule {
        LimbRule {
            max_share,
            seed_reach_m: 1.0,
            min_subtree_m: 1.0,
            min_radius_m: 0.08,
        }
    }

    #[test]
    fn a_limb_seen_from_above_is_tracked_onto_its_axis() {
        let (points, mut skeleton, trunk) = trunk_and_limb();
        let index = PointIndex::new(&points);
        let rules = (&rule(), &limb_rule(0.8));
        let limb = recentre_limbs(&mut skeleton, &points, &index, &trunk, rules);
        assert!(limb.len() >= 10, "{} limb nodes tracked", limb.len());
        let (base, along) = (
            Vec3::new(0.0, 0.0, 2.0),
            Vec3::new(1.0, 0.0, 1.0).normalize(),
        );
        for id in limb {
            let p = skeleton.position(id) - base;
            let off_axis = (p - along * p.dot(along)).length();
            let r = skeleton.radius(id);
            assert!(off_axis < 0.03, "{off_axis} m off the axis at {p}");
            assert!((r - 0.15).abs() < 0.015, "radius {r} at {p}");
        }
    }

    #[test]
    fn a_limb_thicker_than_its_share_of_the_fork_stays_as_it_was() {
        let (points, mut skeleton, trunk) = trunk_and_limb();
        let index = PointIndex::new(&points);
        let before = skeleton.clone();
        // 0.4 × 0.3 m = 0.12 m: the 0.15 m limb's circles are too large.
        let rules = (&rule(), &limb_rule(0.4));
        assert!(recentre_limbs(&mut skeleton, &points, &index, &trunk, rules).is_empty());
        assert_eq!(skeleton, before);
    }

    #[test]
    fn no_seed_no_move() {
        let points: Vec<Vec3> = (0..10).map(|i| Vec3::new(0.0, 0.0, i as f32)).collect();
        let index = PointIndex::new(&points);
        let mut skeleton = chain_on_the_bark(3.0);
        let before = skeleton.clone();
        assert!(recentre_stem(&mut skeleton, &points, &index, &rule()).is_empty());
        assert_eq!(skeleton, before);
    }
}
