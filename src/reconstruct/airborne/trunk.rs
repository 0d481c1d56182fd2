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
//!
//! Two additions for AHN densities, where a trunk is hit once or not at all:
//! a lowest point without neighbours (n_avg undefined) is taken as a trunk
//! hit on a vertical trunk when it lies within half the λ2 limit of the
//! centreline; and above v_low the Eq. 3 trunk continues vertically to the
//! height of the crown centroid, as the Eq. 4 trunk does.

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
    /// λ1 in degrees.
    pub(super) lambda1_deg: f32,
    /// λ2.
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

    // A lowest point without neighbours is an isolated trunk hit below the
    // crown (common at AHN densities); the paper's n_avg is undefined there,
    // and the trunk is taken as vertical (§5.3: trunks grow nearly
    // perpendicular to the ground).
    let measured = mean_direction(tree, v_low, params.trunk_sphere_m);
    let n_avg = measured.unwrap_or(Vec3::Z);
    let half_diagonal = (v_max.truncate() - centre_xy).length().max(f32::EPSILON);
    let lambda2 = (v_low.truncate() - centre_xy).length() / half_diagonal;
    let lambda1_deg = n_avg.angle_between(Vec3::Z).to_degrees();
    // Without a measured direction the point's position is the only
    // evidence, so it has to sit twice as close to the centreline.
    let lambda2_max = if measured.is_some() {
        params.lambda2_max
    } else {
        params.lambda2_max * 0.5
    };
    let eq3 = (lambda1_deg <= params.lambda1_max_deg && lambda2 <= lambda2_max && n_avg.z > 1e-3)
        .then_some(n_avg);
    // The paper leaves the spacing of inserted points open. Half of r_p
    // keeps each trunk point short of k trunk neighbours within r_p, so
    // Algorithm 1's kNN pass links the trunk to the crown points around it
    // instead of letting the trunk form a closed clique.
    let spacing = params.neighbour_radius_m * 0.5;
    let (rule, points) = match eq3 {
        Some(n) => {
            // Eq. 3: v_t = v_low − n_avg·t, t = h / n_avg.z reaches the ground.
            let h = v_low.z - ground_at(v_low.truncate());
            let mut root = v_low - n * (h / n.z);
            root.z = ground_at(root.truncate());
            let low = above(root, v_low, params.voxel_m);
            let mut points = line(root, low, spacing);
            // At AHN densities there are no further trunk hits above v_low,
            // so the trunk continues to the crown's centre of mass as in
            // Eq. 4; without it the skeleton would have to find its way up
            // through the empty space under the crown.
            if v_c.z > low.z + spacing {
                let up = Vec3::new(low.x, low.y, v_c.z);
                points.extend(line(low, up, spacing).into_iter().skip(1));
            }
            (TrunkRule::FromLowestPoint, points)
        }
        None => {
            // Eq. 4: v_t = v_c − (v_c − g_b)/‖v_c − g_b‖·t between g_b and v_c.
            (
                TrunkRule::FromCrownCentre,
                line(g_b, above(g_b, v_c, params.voxel_m), spacing),
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
/// neighbours within `radius_m`; `None` without neighbours (or when the
/// directions cancel).
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
