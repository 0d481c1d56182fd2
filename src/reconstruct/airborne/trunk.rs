//! Trunk insertion: Hu et al. §4.2, Eq. 3/4 and the λ1/λ2 rule.
//!
//! Airborne scans hit a trunk a few times at most, yet the skeleton has to
//! start at a trunk base on the ground. The lowest tree point v_low is taken
//! as a trunk point; the mean direction n_avg from it to its neighbours
//! within a sphere approximates the trunk axis. When that axis is close to
//! the crown's vertical centreline (λ1 ≤ 30°) and v_low is near it
//! (λ2 ≤ 0.5), the trunk is extended down along n_avg to the ground (Eq. 3).
//! Otherwise v_low is a low branch, not the trunk, and the root is put at the
//! centre of the crown's ground footprint g_b, with trunk points interpolated
//! up to the crown centroid v_c (Eq. 4).

use glam::{Vec2, Vec3};

use super::Params;
use crate::reconstruct::ground::Terrain;
use crate::spatial::PointIndex;

/// Which of the paper's equations placed the trunk.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum TrunkRule {
    /// Eq. 3: extended down from the lowest point along n_avg.
    FromLowestPoint,
    /// Eq. 4: from the footprint centre up to the crown centroid.
    FromCrownCentre,
}

/// The inserted trunk.
#[derive(Debug, Clone)]
pub(super) struct Trunk {
    /// The root (trunk base on the ground) first, then trunk points upward
    /// at voxel spacing; the second point is Algorithm 2's first `end`.
    pub(super) points: Vec<Vec3>,
    /// The rule that placed it.
    pub(super) rule: TrunkRule,
    /// λ1 in degrees (NaN when n_avg could not be formed).
    pub(super) lambda1_deg: f32,
    /// λ2 (NaN when n_avg could not be formed).
    pub(super) lambda2: f32,
}

impl Trunk {
    /// One line for the result's notes.
    pub(super) fn note(&self) -> String {
        let eq = match self.rule {
            TrunkRule::FromLowestPoint => "Eq. 3 (down from the lowest point)",
            TrunkRule::FromCrownCentre => "Eq. 4 (footprint centre to crown centroid)",
        };
        format!(
            "trunk: {} points by {eq}, λ1 = {:.0}°, λ2 = {:.2}",
            self.points.len(),
            self.lambda1_deg,
            self.lambda2
        )
    }
}

/// Places the trunk base and trunk points for tree points `tree` (ground
/// removed, at least one point) standing on `terrain` (the lowest tree point
/// is taken as ground level when there is none). §4.2.
pub(super) fn add_trunk(tree: &[Vec3], terrain: Option<&Terrain>, params: &Params) -> Trunk {
    let v_low = tree
        .iter()
        .copied()
        .min_by(|a, b| a.z.total_cmp(&b.z))
        .unwrap_or(Vec3::ZERO);
    let ground_at = |xy: Vec2| terrain.map_or(v_low.z, |t| t.height_at(xy.x, xy.y).min(v_low.z));
    let (v_min, v_max) = tree
        .iter()
        .fold((v_low, v_low), |(lo, hi), &p| (lo.min(p), hi.max(p)));
    let centre_xy = ((v_min + v_max) * 0.5).truncate();
    let g_b = centre_xy.extend(ground_at(centre_xy));
    let v_c = tree.iter().copied().sum::<Vec3>() / tree.len().max(1) as f32;

    let n_avg = mean_direction(tree, v_low, params.trunk_sphere_m);
    let half_diagonal = (v_max.truncate() - centre_xy).length().max(f32::EPSILON);
    let lambda2 = (v_low.truncate() - centre_xy).length() / half_diagonal;
    let lambda1_deg = n_avg.map_or(f32::NAN, |n| n.angle_between(Vec3::Z).to_degrees());
    let eq3 = n_avg.filter(|n| {
        lambda1_deg <= params.lambda1_max_deg && lambda2 <= params.lambda2_max && n.z > 1e-3
    });
    let (rule, points) = match eq3 {
        Some(n) => {
            // Eq. 3: v_t = v_low − n_avg·t, t = h / n_avg.z reaches the ground.
            let h = v_low.z - ground_at(v_low.truncate());
            let mut root = v_low - n * (h / n.z);
            root.z = ground_at(root.truncate());
            (
                TrunkRule::FromLowestPoint,
                line(root, above(root, v_low, params.voxel_m), params.voxel_m),
            )
        }
        None => {
            // Eq. 4: v_t = v_c − (v_c − g_b)/‖v_c − g_b‖·t between g_b and v_c.
            (
                TrunkRule::FromCrownCentre,
                line(g_b, above(g_b, v_c, params.voxel_m), params.voxel_m),
            )
        }
    };
    Trunk {
        points,
        rule,
        lambda1_deg,
        lambda2,
    }
}

/// n_avg: the normalised mean of the unit directions from `v_low` to its
/// neighbours within `radius_m`; `None` without neighbours or when the
/// directions cancel.
fn mean_direction(tree: &[Vec3], v_low: Vec3, radius_m: f32) -> Option<Vec3> {
    let index = PointIndex::new(tree);
    let sum: Vec3 = index
        .within(v_low, radius_m)
        .iter()
        .map(|n| tree[n.index] - v_low)
        .filter(|d| d.length_squared() > 1e-8)
        .map(Vec3::normalize)
        .sum();
    sum.try_normalize()
}

/// `top`, or a point one step straight above `base` when `top` is not at
/// least that high: the first trunk segment must point up for Algorithm 2's
/// bending angles to be defined.
fn above(base: Vec3, top: Vec3, step_m: f32) -> Vec3 {
    if top.z > base.z + step_m {
        top
    } else {
        base + Vec3::Z * step_m
    }
}

/// Points from `from` (included) to `to` (included) at about `step_m`
/// spacing; at least the two ends.
fn line(from: Vec3, to: Vec3, step_m: f32) -> Vec<Vec3> {
    let length = from.distance(to);
    let steps = ((length / step_m).ceil() as usize).clamp(1, 100_000);
    (0..=steps)
        .map(|s| from.lerp(to, s as f32 / steps as f32))
        .collect()
}
