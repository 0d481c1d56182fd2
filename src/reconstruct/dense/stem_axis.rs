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
//! fit is plausible and its radius within [`StemRule::max_change`] of the
//! last one. Nodes between tracked ones are moved by the interpolated
//! offset, and the offset fades out over [`StemRule::fade_m`] beyond the
//! last tracked node, so the stem does not kink. The root, the tree's
//! anchor, stays.

use glam::{Vec2, Vec3};

use crate::reconstruct::radii::{circle_rms, robust_circle, trunk_sectors_seen};
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

/// Sectors (of 12) around the fitted centre that must hold at least two
/// inliers: a third of the girth, as for the fitted DBH.
const MIN_SECTORS: u32 = 4;

/// Inliers must lie within this share of the circle's radius (RMS).
const MAX_RMS_SHARE: f32 = 0.1;

/// A tracked trunk ends after this many nodes in a row without a fit
/// that continues it.
const MAX_MISSES: usize = 2;

/// One plausible circle fit of a slice.
#[derive(Debug, Clone, Copy)]
struct SliceFit {
    centre: Vec3,
    radius: f32,
    inliers: usize,
}

/// Moves the main stem's nodes onto the trunk's tracked axis (module docs).
/// `points` are the tree's points relative to the anchor, `index` their
/// index; children are in main-extension-first order. Returns the number of
/// nodes whose slice fit tracked the trunk.
pub(super) fn recentre_stem(
    skeleton: &mut Skeleton,
    points: &[Vec3],
    index: &PointIndex,
    rule: &StemRule,
) -> usize {
    let chain = main_stem(skeleton);
    let fit = |k: usize| slice_fit(skeleton, &chain, k, points, index, rule);
    let base_z = skeleton.position(NodeId::ROOT).z;
    // The nodes below the seed, with their fits, for the walk down.
    let mut below = Vec::new();
    let mut seed = None;
    for (k, &node) in chain.iter().enumerate().skip(1) {
        if skeleton.position(node).z - base_z > rule.seed_height_m {
            break;
        }
        match fit(k) {
            Some(f) if f.inliers >= rule.seed_points => {
                seed = Some((k, f));
                break;
            }
            other => below.push((k, other)),
        }
    }
    let Some((seed, seed_fit)) = seed else {
        return 0;
    };
    let mut tracked = vec![(seed, seed_fit.centre)];
    tracked.extend(track(
        seed_fit,
        (seed + 1..chain.len()).map(|k| (k, fit(k))),
        rule,
    ));
    tracked.extend(track(seed_fit, below.into_iter().rev(), rule));
    tracked.sort_by_key(|&(k, _)| k);
    let offsets = offsets(skeleton, &chain, &tracked, rule.fade_m);
    for (k, offset) in offsets.into_iter().enumerate().skip(1) {
        let node = chain[k];
        skeleton.set_position(node, skeleton.position(node) + offset);
    }
    tracked.len()
}

/// The fits that continue the trunk from `seed` along `fits` (in walking
/// order), until [`MAX_MISSES`] nodes in a row do not.
fn track(
    seed: SliceFit,
    fits: impl Iterator<Item = (usize, Option<SliceFit>)>,
    rule: &StemRule,
) -> Vec<(usize, Vec3)> {
    let mut last = seed.radius;
    let mut misses = 0;
    let mut tracked = Vec::new();
    for (k, fit) in fits {
        match fit.filter(|f| (f.radius - last).abs() <= rule.max_change * last) {
            Some(f) => {
                tracked.push((k, f.centre));
                last = f.radius;
                misses = 0;
            }
            None => misses += 1,
        }
        if misses >= MAX_MISSES {
            break;
        }
    }
    tracked
}

/// Per node of `chain`, how far it moves: to its fitted centre where
/// tracked, interpolated (by length along the chain) between tracked nodes
/// and between the root (which stays) and the first, and fading to nothing
/// over `fade_m` beyond the last.
fn offsets(
    skeleton: &Skeleton,
    chain: &[NodeId],
    tracked: &[(usize, Vec3)],
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
                .map(|&(k, c)| (along[k], c - skeleton.position(chain[k]))),
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
    let mut chain = vec![NodeId::ROOT];
    while let Some(&next) = skeleton.children(chain[chain.len() - 1]).first() {
        chain.push(next);
    }
    chain
}

/// The circle fitted to the slice around `chain[k]`, if it is plausible:
/// enough inliers over a third of the girth, tight, at least
/// [`StemRule::min_radius_m`] and the node's own spread (an arc's centroid
/// lies inside its circle), with the node inside it.
fn slice_fit(
    skeleton: &Skeleton,
    chain: &[NodeId],
    k: usize,
    points: &[Vec3],
    index: &PointIndex,
    rule: &StemRule,
) -> Option<SliceFit> {
    let at = skeleton.position(chain[k]);
    let spread = skeleton.radius(chain[k]);
    let dir = local_direction(skeleton, chain, k, rule.axis_window_m)?;
    let (e1, e2) = dir.any_orthonormal_pair();
    let flat: Vec<Vec2> = index
        .within(at, rule.reach_m.hypot(rule.half_window_m))
        .iter()
        .map(|n| points[n.index] - at)
        .filter(|d| d.dot(dir).abs() <= rule.half_window_m)
        .map(|d| Vec2::new(d.dot(e1), d.dot(e2)))
        .filter(|f| f.length() <= rule.reach_m)
        .collect();
    if flat.len() < rule.min_points {
        return None;
    }
    let (circle, inliers) = robust_circle(&flat, rule.reach_m)?;
    let plausible = inliers.len() >= rule.min_points
        && circle.radius >= spread.max(rule.min_radius_m)
        && circle.centre.length() <= circle.radius
        && circle_rms(&inliers, circle) <= MAX_RMS_SHARE * circle.radius
        && trunk_sectors_seen(&inliers, circle.centre) >= MIN_SECTORS;
    plausible.then(|| SliceFit {
        centre: at + e1 * circle.centre.x + e2 * circle.centre.y,
        radius: circle.radius,
        inliers: inliers.len(),
    })
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
        let moved = recentre_stem(&mut skeleton, &points, &index, &rule());
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

    #[test]
    fn no_seed_no_move() {
        let points: Vec<Vec3> = (0..10).map(|i| Vec3::new(0.0, 0.0, i as f32)).collect();
        let index = PointIndex::new(&points);
        let mut skeleton = chain_on_the_bark(3.0);
        let before = skeleton.clone();
        assert_eq!(recentre_stem(&mut skeleton, &points, &index, &rule()), 0);
        assert_eq!(skeleton, before);
    }
}
