//! Skeleton-to-skeleton comparison: recall, precision and distances of a
//! reconstruction against a known (synthetic) truth.
//!
//! Both skeletons are sampled along their internodes every
//! [`SAMPLE_STEP_M`], in absolute coordinates (their anchors differ: a
//! reconstruction is anchored at its estimated trunk base). A truth sample is
//! *recalled* when a reconstruction sample lies within the tolerance; a
//! reconstruction sample is *precise* when a truth sample does. Because
//! samples are evenly spaced, the shares are shares of branch length. Recall
//! counts only truth internodes whose radius (mean of the two end radii)
//! reaches `min_truth_radius_m`, so that twigs no scanner resolves do not
//! dilute it; precision is measured against the whole truth, since a
//! reconstructed twig is right wherever a real one is.

use glam::{DVec3, Vec3};

use crate::skeleton::Skeleton;
use crate::spatial::PointIndex;

/// Spacing of the samples along internodes, in metres. Distances are
/// measured between samples, so they overestimate by at most half of this.
pub const SAMPLE_STEP_M: f32 = 0.05;

/// The comparison of a reconstruction with its truth.
#[derive(Debug, Clone, PartialEq)]
pub struct SkeletonComparison {
    /// Share of the (radius-filtered) truth length within the tolerance of
    /// the reconstruction.
    pub recall: f32,
    /// Share of the reconstruction length within the tolerance of the truth.
    pub precision: f32,
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
    // Work relative to the truth's anchor, in f32 (sub-mm for tree sizes).
    let origin = truth.anchor().origin;
    let truth_all = samples(truth, origin, 0.0);
    let truth_thick = samples(truth, origin, min_truth_radius_m);
    let recon_all = samples(recon, origin, 0.0);
    let to_recon = distances(&truth_thick, &recon_all);
    let to_truth = distances(&recon_all, &truth_all);
    let within = |d: &[f32]| {
        if d.is_empty() {
            0.0
        } else {
            d.iter().filter(|&&x| x <= tolerance_m).count() as f32 / d.len() as f32
        }
    };
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
        mean_distance_m: mean,
        p95_distance_m: p95,
        truth_length_m: length(truth, min_truth_radius_m),
        recon_length_m: recon.total_length(),
        tolerance_m,
    }
}

/// Samples every [`SAMPLE_STEP_M`] along the internodes whose mean radius is
/// at least `min_radius_m`, relative to `origin`. A skeleton without
/// internodes is sampled at its root.
fn samples(s: &Skeleton, origin: DVec3, min_radius_m: f32) -> Vec<Vec3> {
    let at = |id| (s.absolute_position(id) - origin).as_vec3();
    if s.internode_count() == 0 {
        return vec![at(crate::skeleton::NodeId::ROOT)];
    }
    let mut out = Vec::new();
    for (p, c) in s.internodes() {
        if (s.radius(p) + s.radius(c)) * 0.5 < min_radius_m {
            continue;
        }
        let (a, b) = (at(p), at(c));
        let n = ((a.distance(b) / SAMPLE_STEP_M).ceil() as usize).clamp(1, 1_000_000);
        out.extend((0..n).map(|k| a.lerp(b, (k as f32 + 0.5) / n as f32)));
    }
    out
}

/// Summed length of the internodes whose mean radius is at least
/// `min_radius_m`.
fn length(s: &Skeleton, min_radius_m: f32) -> f32 {
    s.internodes()
        .filter(|&(p, c)| (s.radius(p) + s.radius(c)) * 0.5 >= min_radius_m)
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
