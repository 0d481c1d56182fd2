//! Skeleton-to-skeleton comparison: recall, precision and distances of a
//! reconstruction against a known (synthetic) truth.
//!
//! Both skeletons are sampled along their internodes every
//! [`SAMPLE_STEP_M`], in absolute coordinates (their anchors differ: a
//! reconstruction is anchored at its estimated trunk base). A truth sample is
//! *recalled* when a reconstruction sample lies within the tolerance; a
//! reconstruction sample is *precise* when a truth sample does. Because
//! samples are evenly spaced, the shares are shares of branch length. Recall
//! counts only truth internodes whose radius (mean of the two end radii,
//! a lateral's first internode its own radius: see
//! [`Skeleton::internode_radii`])
//! reaches `min_truth_radius_m`, so that twigs no scanner resolves do not
//! dilute it; precision is measured against the whole truth, since a
//! reconstructed twig is right wherever a real one is.
//!
//! A scan sees bark, never wood inside other wood: a truth lateral starts
//! on its parent's axis, and its first decimetres inside a thick stem carry
//! no point. [`SkeletonComparison::visible_recall`] leaves such *hidden*
//! truth out (a sample inside the cylinder of a thicker truth internode) as
//! a diagnostic of what the data can show; `recall` stays the figure of
//! record.
//!
//! A scan also misses what its scanners never hit: on an occluded
//! terrestrial scan most thin twigs carry no point. Given the scan,
//! [`compare_scanned`] also reports the recall over the truth that has a
//! scan point on its bark ([`SkeletonComparison::scanned_recall`]): what
//! the pipeline made of the data it had.

use glam::{DVec3, Vec3};

use crate::cloud::PointCloud;
use crate::skeleton::{NodeId, Skeleton};
use crate::spatial::PointIndex;

/// Spacing of the samples along internodes, in metres. Distances are
/// measured between samples, so they overestimate by at most half of this.
pub const SAMPLE_STEP_M: f32 = 0.05;

/// A truth sample is *scanned* when a scan point lies within its
/// internode's radius (at the child end) plus this margin, in metres: bark
/// seen through millimetres of noise, between points centimetres apart.
pub const BARK_MARGIN_M: f32 = 0.02;

/// The comparison of a reconstruction with its truth.
#[derive(Debug, Clone, PartialEq)]
pub struct SkeletonComparison {
    /// Share of the (radius-filtered) truth length within the tolerance of
    /// the reconstruction.
    pub recall: f32,
    /// Share of the reconstruction length within the tolerance of the truth.
    pub precision: f32,
    /// Recall over the visible (radius-filtered) truth only: samples inside
    /// thicker truth wood (see the module docs) left out. A diagnostic, not a
    /// target.
    pub visible_recall: f32,
    /// Share of the radius-filtered truth length that is hidden inside
    /// thicker truth wood.
    pub hidden_share: f32,
    /// Mean of the symmetric nearest-sample distances (truth → reconstruction
    /// over the filtered truth, and reconstruction → truth), in metres.
    pub mean_distance_m: f32,
    /// 95th percentile of the same distances, in metres.
    pub p95_distance_m: f32,
    /// Length of the radius-filtered truth, in metres.
    pub truth_length_m: f32,
    /// Length of the reconstruction, in metres.
    pub recon_length_m: f32,
    /// The tolerance used, in metres.
    pub tolerance_m: f32,
    /// Recall over the (radius-filtered) truth that has a scan point on its
    /// bark ([`BARK_MARGIN_M`]); `None` without a scan ([`compare`]) or
    /// when no truth has a point on its bark. A diagnostic, not a target.
    pub scanned_recall: Option<f32>,
    /// Share of the radius-filtered truth length that has a scan point on
    /// its bark; `None` without a scan.
    pub scanned_share: Option<f32>,
}

/// Compares `recon` with `truth` (module docs).
///
/// ```
/// use glam::{DVec3, Vec3};
/// use silva::eval::compare::compare;
/// use silva::{Anchor, NodeId, Skeleton};
///
/// let mut truth = Skeleton::new(Anchor::at(DVec3::new(100.0, 200.0, 1.0)), 0.2);
/// truth.add_child(NodeId::ROOT, Vec3::new(0.0, 0.0, 3.0), 0.1);
/// // The same trunk, anchored elsewhere and 0.2 m off to the side.
/// let mut recon = Skeleton::new(Anchor::at(DVec3::new(100.2, 200.0, 1.0)), 0.2);
/// recon.add_child(NodeId::ROOT, Vec3::new(0.0, 0.0, 3.0), 0.1);
/// let c = compare(&truth, &recon, 0.5, 0.0);
/// assert!(c.recall > 0.99 && c.precision > 0.99);
/// assert!((c.mean_distance_m - 0.2).abs() < 0.03);
/// assert_eq!(compare(&truth, &recon, 0.1, 0.0).recall, 0.0);
/// ```
pub fn compare(
    truth: &Skeleton,
    recon: &Skeleton,
    tolerance_m: f32,
    min_truth_radius_m: f32,
) -> SkeletonComparison {
    compare_with(truth, recon, None, tolerance_m, min_truth_radius_m)
}

/// [`compare`], and the recall over the truth that `scan` (the cloud the
/// reconstruction was made from) has points on (module docs).
///
/// ```
/// use glam::{DVec3, Vec3};
/// use silva::cloud::PointCloud;
/// use silva::eval::compare::compare_scanned;
/// use silva::{Anchor, NodeId, Skeleton};
///
/// // A 2 m trunk with a 1 m lateral; the scan saw the trunk's far side only.
/// let mut truth = Skeleton::new(Anchor::at(DVec3::ZERO), 0.1);
/// let top = truth.add_child(NodeId::ROOT, Vec3::new(0.0, 0.0, 2.0), 0.1);
/// truth.add_child(top, Vec3::new(1.0, 0.0, 2.0), 0.02);
/// let bark = (0..200).map(|i| Vec3::new(-0.1, 0.0, i as f32 * 0.01)).collect();
/// let scan = PointCloud::from_points(DVec3::ZERO, bark);
/// let mut recon = Skeleton::new(Anchor::at(DVec3::ZERO), 0.1);
/// recon.add_child(NodeId::ROOT, Vec3::new(0.0, 0.0, 2.0), 0.1);
///
/// let c = compare_scanned(&truth, &recon, &scan, 0.1, 0.0);
/// assert!((c.recall - 2.0 / 3.0).abs() < 0.05);
/// assert_eq!(c.scanned_recall, Some(1.0));
/// assert!((c.scanned_share.unwrap() - 2.0 / 3.0).abs() < 0.05);
/// // Without the scan, the same figures and none on scanned truth.
/// let plain = silva::eval::compare::compare(&truth, &recon, 0.1, 0.0);
/// assert_eq!((plain.recall, plain.scanned_recall), (c.recall, None));
/// ```
pub fn compare_scanned(
    truth: &Skeleton,
    recon: &Skeleton,
    scan: &PointCloud,
    tolerance_m: f32,
    min_truth_radius_m: f32,
) -> SkeletonComparison {
    compare_with(truth, recon, Some(scan), tolerance_m, min_truth_radius_m)
}

fn compare_with(
    truth: &Skeleton,
    recon: &Skeleton,
    scan: Option<&PointCloud>,
    tolerance_m: f32,
    min_truth_radius_m: f32,
) -> SkeletonComparison {
    // Work relative to the truth's anchor, in f32 (sub-mm for tree sizes).
    let origin = truth.anchor().origin;
    let truth_all = samples(truth, origin, 0.0);
    let truth_thick = samples(truth, origin, min_truth_radius_m);
    let recon_all = samples(recon, origin, 0.0);
    let to_recon = distances(&truth_thick.at, &recon_all.at);
    let to_truth = distances(&recon_all.at, &truth_all.at);
    let within = |d: &[f32]| share(d.iter().map(|&x| x <= tolerance_m));
    let hidden = hidden(truth, origin, &truth_thick);
    let recall_where = |counted: &[bool]| {
        share(
            to_recon
                .iter()
                .zip(counted)
                .filter(|&(_, &c)| c)
                .map(|(&d, _)| d <= tolerance_m),
        )
    };
    let visible: Vec<bool> = hidden.iter().map(|&h| !h).collect();
    let scanned = scan.map(|cloud| scanned(truth, origin, cloud, &truth_thick));
    let mut all: Vec<f32> = to_recon.iter().chain(&to_truth).copied().collect();
    all.sort_by(f32::total_cmp);
    let mean = if all.is_empty() {
        0.0
    } else {
        all.iter().sum::<f32>() / all.len() as f32
    };
    let p95 = all
        .get(((all.len() as f32 * 0.95).ceil() as usize).saturating_sub(1))
        .copied()
        .unwrap_or(0.0);
    SkeletonComparison {
        recall: within(&to_recon),
        precision: within(&to_truth),
        visible_recall: recall_where(&visible),
        hidden_share: share(hidden.iter().copied()),
        mean_distance_m: mean,
        p95_distance_m: p95,
        truth_length_m: length(truth, min_truth_radius_m),
        recon_length_m: recon.total_length(),
        tolerance_m,
        scanned_recall: scanned
            .as_deref()
            .filter(|s| s.contains(&true))
            .map(recall_where),
        scanned_share: scanned.as_deref().map(|s| share(s.iter().copied())),
    }
}

/// For each of `of` (samples of `truth`), whether a point of `scan` lies
/// on its bark: within its internode's radius plus [`BARK_MARGIN_M`].
fn scanned(truth: &Skeleton, origin: DVec3, scan: &PointCloud, of: &Samples) -> Vec<bool> {
    let shift = (scan.offset - origin).as_vec3();
    let points: Vec<Vec3> = scan.points.iter().map(|&p| p + shift).collect();
    let index = PointIndex::new(&points);
    of.at
        .iter()
        .zip(&of.internode)
        .map(|(&p, &own)| {
            index
                .nearest(p)
                .is_some_and(|n| n.distance_sq.sqrt() <= truth.radius(own) + BARK_MARGIN_M)
        })
        .collect()
}

/// Points along a skeleton's internodes, each with the internode (named by
/// its child node) it lies on.
struct Samples {
    at: Vec<Vec3>,
    internode: Vec<NodeId>,
}

/// Samples every [`SAMPLE_STEP_M`] along the internodes whose mean radius is
/// at least `min_radius_m`, relative to `origin`. A skeleton without
/// internodes is sampled at its root.
fn samples(s: &Skeleton, origin: DVec3, min_radius_m: f32) -> Samples {
    if s.internode_count() == 0 {
        return Samples {
            at: vec![relative(s, origin, NodeId::ROOT)],
            internode: vec![NodeId::ROOT],
        };
    }
    let mut out = Samples {
        at: Vec::new(),
        internode: Vec::new(),
    };
    for (p, c) in s.internodes() {
        if mean_radius(s, c) < min_radius_m {
            continue;
        }
        let (a, b) = (relative(s, origin, p), relative(s, origin, c));
        let n = ((a.distance(b) / SAMPLE_STEP_M).ceil() as usize).clamp(1, 1_000_000);
        out.at
            .extend((0..n).map(|k| a.lerp(b, (k as f32 + 0.5) / n as f32)));
        out.internode.extend(std::iter::repeat_n(c, n));
    }
    out
}

/// Position of node `id` relative to `origin`.
fn relative(s: &Skeleton, origin: DVec3, id: NodeId) -> Vec3 {
    (s.absolute_position(id) - origin).as_vec3()
}

/// Mean of the end radii of the internode ending at `child`
/// ([`Skeleton::internode_radii`]: a lateral's first internode has its own
/// radius, not the stem's it leaves).
fn mean_radius(s: &Skeleton, child: NodeId) -> f32 {
    let (base, tip) = s.internode_radii(child);
    (base + tip) * 0.5
}

/// For each of `of` (samples of `truth`), whether it lies inside the
/// cylinder of a thicker internode of `truth` (axis between its end nodes,
/// radius [`mean_radius`], flat ends): wood no scan can see.
fn hidden(truth: &Skeleton, origin: DVec3, of: &Samples) -> Vec<bool> {
    let axes = truth.internodes().map(|(p, c)| {
        let (a, b) = (relative(truth, origin, p), relative(truth, origin, c));
        (c, a, b, mean_radius(truth, c))
    });
    let axes: Vec<_> = axes.collect();
    let Some(widest) = axes.iter().map(|a| a.3).reduce(f32::max) else {
        return vec![false; of.at.len()];
    };
    // Index the axes' midpoints: a sample inside a cylinder is within half
    // its length plus its radius of the midpoint.
    let mids: Vec<Vec3> = axes.iter().map(|&(_, a, b, _)| a.midpoint(b)).collect();
    let longest = axes
        .iter()
        .map(|&(_, a, b, _)| a.distance(b))
        .fold(0.0, f32::max);
    let index = PointIndex::new(&mids);
    of.at
        .iter()
        .zip(&of.internode)
        .map(|(&p, &own)| {
            let own_r = mean_radius(truth, own);
            index
                .within(p, 0.5 * longest + widest)
                .iter()
                .map(|n| axes[n.index])
                .any(|(c, a, b, r)| c != own && r > own_r && in_cylinder(p, a, b, r))
        })
        .collect()
}

/// Whether `p` lies inside the cylinder of radius `r` on the axis `a`–`b`
/// (flat ends: wood just beyond a joint continues the branch, it is not
/// inside it).
fn in_cylinder(p: Vec3, a: Vec3, b: Vec3, r: f32) -> bool {
    let ab = b - a;
    let len2 = ab.length_squared();
    if len2 <= 0.0 {
        return false;
    }
    let t = (p - a).dot(ab) / len2;
    (0.0..=1.0).contains(&t) && p.distance(a + ab * t) < r
}

/// Share of `true` in `flags` (0 when there are none).
fn share(flags: impl Iterator<Item = bool>) -> f32 {
    let (mut yes, mut all) = (0usize, 0usize);
    for f in flags {
        yes += usize::from(f);
        all += 1;
    }
    if all == 0 {
        0.0
    } else {
        yes as f32 / all as f32
    }
}

/// Summed length of the internodes whose mean radius is at least
/// `min_radius_m`.
fn length(s: &Skeleton, min_radius_m: f32) -> f32 {
    s.internodes()
        .filter(|&(_, c)| mean_radius(s, c) >= min_radius_m)
        .map(|(_, c)| s.internode_length(c))
        .sum()
}

/// For each of `from`, the distance to the nearest of `to` (infinite when
/// `to` is empty).
fn distances(from: &[Vec3], to: &[Vec3]) -> Vec<f32> {
    let index = PointIndex::new(to);
    from.iter()
        .map(|&p| {
            index
                .nearest(p)
                .map_or(f32::INFINITY, |n| n.distance_sq.sqrt())
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::skeleton::Anchor;

    /// A 0.3 m thick trunk 3 m tall with a node at `fork_z`, returned with
    /// it.
    fn trunk(fork_z: f32) -> (Skeleton, NodeId) {
        let mut s = Skeleton::new(Anchor::at(DVec3::ZERO), 0.3);
        let fork = s.add_child(NodeId::ROOT, Vec3::new(0.0, 0.0, fork_z), 0.3);
        s.add_child(fork, Vec3::new(0.0, 0.0, 3.0), 0.3);
        (s, fork)
    }

    /// [`trunk`] with a thin lateral that starts on its axis at 1 m and
    /// leaves the bark at 45°.
    fn trunk_with_lateral() -> Skeleton {
        let (mut s, fork) = trunk(1.0);
        let out = s.add_child(fork, Vec3::new(1.0, 0.0, 2.0), 0.02);
        s.add_child(out, Vec3::new(2.0, 0.0, 3.0), 0.01);
        s
    }

    #[test]
    fn a_lateral_inside_its_trunk_is_hidden_and_left_out_of_visible_recall() {
        let truth = trunk_with_lateral();
        // The reconstruction sees the trunk and the lateral from the bark
        // out, joined across the wood at right angles.
        let (mut recon, fork) = trunk(1.3);
        let bark = recon.add_child(fork, Vec3::new(0.3, 0.0, 1.3), 0.02);
        recon.add_child(bark, Vec3::new(2.0, 0.0, 3.0), 0.01);
        let c = compare(&truth, &recon, 0.1, 0.0);
        // The lateral's first 0.42 m (to r = 0.3 from the axis) is hidden.
        let truth_m = 3.0 + 2.0 * 2f32.sqrt();
        assert!(
            (c.hidden_share - 0.3 * 2f32.sqrt() / truth_m).abs() < 0.02,
            "{}",
            c.hidden_share
        );
        assert!(c.recall < 0.985, "recall {}", c.recall);
        assert!(c.visible_recall > 0.999, "visible {}", c.visible_recall);
    }

    #[test]
    fn a_thin_lateral_does_not_hide_its_thicker_parent() {
        // Only the lateral's first 0.42 m, inside the trunk, is hidden: none
        // of the trunk's 3 m, though the lateral's cylinder reaches into it.
        let truth = trunk_with_lateral();
        let c = compare(&truth, &truth, 0.1, 0.0);
        let truth_m = 3.0 + 2.0 * 2f32.sqrt();
        assert!(
            (c.hidden_share - 0.3 * 2f32.sqrt() / truth_m).abs() < 0.02,
            "{}",
            c.hidden_share
        );
        let trunk = samples(&truth, DVec3::ZERO, 0.2);
        assert_eq!(trunk.at.len(), 60);
        assert!(hidden(&truth, DVec3::ZERO, &trunk).iter().all(|h| !h));
    }

    #[test]
    fn a_thin_lateral_is_not_counted_as_thick_by_the_stem_it_leaves() {
        // Recall over branches of at least 5 cm: the 2 cm lateral does not
        // count, its first internode included (the mean of the trunk's
        // 0.3 m and its own 0.02 m made it a 16 cm branch).
        let truth = trunk_with_lateral();
        let c = compare(&truth, &trunk(1.0).0, 0.1, 0.05);
        assert_eq!(c.recall, 1.0);
        assert!(
            (c.truth_length_m - 3.0).abs() < 1e-3,
            "{}",
            c.truth_length_m
        );
    }
}
