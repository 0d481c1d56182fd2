//! How well a skeleton's cylinders fit a real cloud that has no ground truth
//! (issue 3, "Dense, fit"): the share of points within 2 cm and 5 cm of the
//! reconstructed branch surfaces, the mean point-to-surface distance, and
//! the share of the surface area with a point within 5 cm, i.e. the surface
//! the data supports (the model's surface is the boundary of the union of
//! its cones: a piece of one cone inside another is not surface).
//!
//! Each internode is a truncated cone from the parent's radius to the
//! child's ([`crate::reconstruct::metrics::wood_volume_m3`] uses the same
//! cones, except that a lateral's first internode is a cylinder there).
//! A point's distance to the model is its distance to the nearest cone's
//! lateral surface (or to its end disc beyond the ends). Candidate cones are
//! found through [`PointIndex`] over samples along the axes.

use glam::Vec3;
use serde::{Deserialize, Serialize};

use crate::cloud::PointCloud;
use crate::skeleton::Skeleton;
use crate::spatial::PointIndex;

/// Spacing of the axis samples used to find candidate cones, in metres.
const AXIS_STEP_M: f32 = 0.05;
/// Spacing of the surface samples for the supported share, in metres.
pub(super) const SURFACE_STEP_M: f32 = 0.02;
/// At most this many surface samples; coarser spacing for huge models.
pub(super) const MAX_SURFACE_SAMPLES: f32 = 2.0e6;
/// A point this close to the surface fits tightly (the 2 cm figure).
pub(super) const TIGHT_M: f32 = 0.02;
/// A point this close to the surface is near it (the 5 cm figures).
pub(super) const NEAR_M: f32 = 0.05;

/// Point-to-surface fit of a skeleton to a cloud.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SurfaceFit {
    /// Points compared.
    pub points: usize,
    /// Share (0–1) of the points within 2 cm of the surface.
    pub within_2cm: f32,
    /// Share (0–1) of the points within 5 cm of the surface.
    pub within_5cm: f32,
    /// Mean point-to-surface distance, in metres.
    pub mean_distance_m: f32,
    /// Share (0–1) of the surface area with a point within 5 cm.
    pub supported_share: f32,
    /// Area of the fitted surface (the cones, or the mesh triangles), in m².
    pub surface_area_m2: f32,
}

impl SurfaceFit {
    /// The fit when there is no surface or no point: no share, an undefined
    /// (NaN) mean distance.
    pub(crate) fn nothing_to_fit(points: usize, surface_area_m2: f32) -> Self {
        SurfaceFit {
            points,
            within_2cm: 0.0,
            within_5cm: 0.0,
            mean_distance_m: f32::NAN,
            supported_share: 0.0,
            surface_area_m2,
        }
    }
}

/// One internode as a truncated cone.
#[derive(Debug, Clone, Copy)]
struct Cone {
    a: Vec3,
    b: Vec3,
    ra: f32,
    rb: f32,
}

impl Cone {
    /// Distance from `p` to the cone's surface (lateral surface, or the end
    /// discs for points beyond the ends).
    fn distance(&self, p: Vec3) -> f32 {
        let axis = self.b - self.a;
        let len = axis.length();
        if len <= f32::EPSILON {
            return (p.distance(self.a) - self.ra).abs();
        }
        let u = axis / len;
        let s = (p - self.a).dot(u);
        let radial = ((p - self.a) - u * s).length();
        if s < 0.0 || s > len {
            let (over, r) = if s < 0.0 {
                (-s, self.ra)
            } else {
                (s - len, self.rb)
            };
            return if radial <= r {
                over
            } else {
                (over * over + (radial - r) * (radial - r)).sqrt()
            };
        }
        let r = self.ra + (self.rb - self.ra) * s / len;
        (radial - r).abs()
    }

    /// True when `p` lies inside the cone, more than 1 mm within its
    /// lateral surface and between its end discs.
    fn contains(&self, p: Vec3) -> bool {
        let axis = self.b - self.a;
        let len = axis.length();
        if len <= f32::EPSILON {
            return false;
        }
        let u = axis / len;
        let s = (p - self.a).dot(u);
        if !(0.0..=len).contains(&s) {
            return false;
        }
        let r = self.ra + (self.rb - self.ra) * s / len;
        ((p - self.a) - u * s).length() < r - 0.001
    }

    fn lateral_area(&self) -> f32 {
        let slant = ((self.ra - self.rb).powi(2) + self.a.distance_squared(self.b)).sqrt();
        std::f32::consts::PI * (self.ra + self.rb) * slant
    }
}

/// Compares `skeleton`'s cylinders with `cloud` (both georeferenced; the
/// cloud is rebased to the skeleton's anchor when they differ).
pub fn surface_fit(skeleton: &Skeleton, cloud: &PointCloud) -> SurfaceFit {
    let rebased;
    let cloud = if cloud.offset == skeleton.anchor().origin {
        cloud
    } else {
        rebased = cloud.rebased(skeleton.anchor().origin);
        &rebased
    };
    let cones: Vec<Cone> = skeleton
        .internodes()
        .map(|(p, c)| Cone {
            a: skeleton.position(p),
            b: skeleton.position(c),
            ra: skeleton.radius(p),
            rb: skeleton.radius(c),
        })
        .collect();
    let surface_area_m2: f32 = cones.iter().map(Cone::lateral_area).sum();
    if cones.is_empty() || cloud.is_empty() {
        return SurfaceFit::nothing_to_fit(cloud.len(), surface_area_m2);
    }
    let (d2, d5, mean) = point_distances(&cones, &cloud.points);
    SurfaceFit {
        points: cloud.len(),
        within_2cm: d2,
        within_5cm: d5,
        mean_distance_m: mean,
        supported_share: supported_share(&cones, &cloud.points, surface_area_m2),
        surface_area_m2,
    }
}

/// Shares within 2 cm and 5 cm and the mean distance of the points.
fn point_distances(cones: &[Cone], points: &[Vec3]) -> (f32, f32, f32) {
    let (index, owner) = axis_index(cones);
    let max_r = cones.iter().map(|c| c.ra.max(c.rb)).fold(0.0, f32::max);
    // Any cone whose surface is within 5 cm of a point has an axis sample
    // within max radius + half a step + 5 cm of it.
    let reach = max_r + 0.5 * AXIS_STEP_M + NEAR_M;
    let (mut n2, mut n5, mut sum) = (0usize, 0usize, 0.0f64);
    let mut seen: Vec<u32> = Vec::new();
    for &p in points {
        seen.clear();
        let mut best = f32::INFINITY;
        for n in index.within(p, reach) {
            let k = owner[n.index];
            if !seen.contains(&k) {
                seen.push(k);
                best = best.min(cones[k as usize].distance(p));
            }
        }
        if best > NEAR_M {
            // Far from every surface: the nearest axis sample's cone gives
            // the distance (an upper bound off by at most a few cm).
            if let Some(n) = index.nearest(p) {
                best = best.min(cones[owner[n.index] as usize].distance(p));
            }
        }
        n2 += usize::from(best <= TIGHT_M);
        n5 += usize::from(best <= NEAR_M);
        sum += f64::from(best);
    }
    let n = points.len() as f32;
    (
        n2 as f32 / n,
        n5 as f32 / n,
        (sum / points.len() as f64) as f32,
    )
}

/// Samples along every cone's axis, every [`AXIS_STEP_M`] or closer, in an
/// index, and the cone each belongs to.
fn axis_index(cones: &[Cone]) -> (PointIndex, Vec<u32>) {
    let mut samples = Vec::new();
    let mut owner = Vec::new();
    for (k, c) in cones.iter().enumerate() {
        let steps = (c.a.distance(c.b) / AXIS_STEP_M).ceil().max(1.0) as usize;
        for i in 0..=steps {
            samples.push(c.a.lerp(c.b, i as f32 / steps as f32));
            owner.push(k as u32);
        }
    }
    (PointIndex::new(&samples), owner)
}

/// Per cone, the other cones that can overlap it (an axis sample within
/// both cones' largest radii and a step of its axis).
fn overlapping_cones(cones: &[Cone]) -> Vec<Vec<u32>> {
    let (index, owner) = axis_index(cones);
    let max_r = cones.iter().map(|c| c.ra.max(c.rb)).fold(0.0, f32::max);
    cones
        .iter()
        .enumerate()
        .map(|(k, c)| {
            let reach = c.ra.max(c.rb) + max_r + AXIS_STEP_M;
            let steps = (c.a.distance(c.b) / AXIS_STEP_M).ceil().max(1.0) as usize;
            let mut near: Vec<u32> = (0..=steps)
                .flat_map(|i| index.within(c.a.lerp(c.b, i as f32 / steps as f32), reach))
                .map(|n| owner[n.index])
                .filter(|&j| j as usize != k)
                .collect();
            near.sort_unstable();
            near.dedup();
            near
        })
        .collect()
}

/// Area-weighted share of surface samples with a cloud point within 5 cm.
/// Samples inside another cone (a lateral's first internode inside the
/// stem it starts on, the overlap at a bend) are not on the model's
/// surface, the boundary of the union of its cones, and do not count.
fn supported_share(cones: &[Cone], points: &[Vec3], area_m2: f32) -> f32 {
    if area_m2 <= 0.0 {
        return 0.0;
    }
    let step = surface_step_m(area_m2);
    let mut tally = SupportTally::new(points);
    let overlapping = overlapping_cones(cones);
    for (c, others) in cones.iter().zip(&overlapping) {
        let axis = c.b - c.a;
        let len = axis.length();
        if len <= f32::EPSILON {
            continue;
        }
        let u = axis / len;
        let e1 = u.any_orthonormal_vector();
        let e2 = u.cross(e1);
        let along = (len / step).ceil().max(1.0) as usize;
        let around = ((std::f32::consts::TAU * c.ra.max(c.rb) / step).ceil() as usize).max(6);
        for i in 0..along {
            let t = (i as f32 + 0.5) / along as f32;
            let r = c.ra + (c.rb - c.ra) * t;
            let centre = c.a + axis * t;
            // Each sample stands for an equal share of this ring's area.
            let weight = f64::from(c.lateral_area()) / (along * around) as f64;
            for j in 0..around {
                let phi = j as f32 / around as f32 * std::f32::consts::TAU;
                let sample = centre + (e1 * phi.cos() + e2 * phi.sin()) * r;
                if !others.iter().any(|&o| cones[o as usize].contains(sample)) {
                    tally.add(sample, weight);
                }
            }
        }
    }
    tally.share()
}

/// Spacing of the surface samples for a surface of this area: 2 cm, coarser
/// when that would exceed [`MAX_SURFACE_SAMPLES`].
pub(super) fn surface_step_m(area_m2: f32) -> f32 {
    SURFACE_STEP_M.max((area_m2 / MAX_SURFACE_SAMPLES).sqrt())
}

/// Area-weighted count of surface samples that have a cloud point within
/// [`NEAR_M`]: the "supported surface" of both the cylinder and the mesh fit.
pub(super) struct SupportTally {
    index: PointIndex,
    supported: f64,
    total: f64,
}

impl SupportTally {
    pub(super) fn new(points: &[Vec3]) -> Self {
        Self {
            index: PointIndex::new(points),
            supported: 0.0,
            total: 0.0,
        }
    }

    /// Counts one surface sample standing for `weight` square metres.
    pub(super) fn add(&mut self, sample: Vec3, weight: f64) {
        self.total += weight;
        if self
            .index
            .nearest(sample)
            .is_some_and(|n| n.distance_sq <= NEAR_M * NEAR_M)
        {
            self.supported += weight;
        }
    }

    /// The supported share of the area counted so far (0 for no area).
    pub(super) fn share(&self) -> f32 {
        if self.total > 0.0 {
            (self.supported / self.total) as f32
        } else {
            0.0
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::skeleton::{Anchor, NodeId};
    use glam::DVec3;

    #[test]
    fn points_on_a_cylinder_fit_it_and_support_it() {
        let mut s = Skeleton::new(Anchor::at(DVec3::new(10.0, 20.0, 0.0)), 0.2);
        s.add_child(NodeId::ROOT, Vec3::new(0.0, 0.0, 2.0), 0.2);
        let mut pts = Vec::new();
        for i in 0..200 {
            for j in 0..64 {
                let a = j as f32 / 64.0 * std::f32::consts::TAU;
                pts.push(Vec3::new(0.2 * a.cos(), 0.2 * a.sin(), i as f32 * 0.01));
            }
        }
        pts.push(Vec3::new(1.0, 0.0, 1.0)); // 0.8 m off the surface
        let cloud = PointCloud::from_points(DVec3::new(10.0, 20.0, 0.0), pts);
        let fit = surface_fit(&s, &cloud);
        assert!(fit.within_2cm > 0.999 && fit.within_2cm < 1.0);
        assert!((fit.mean_distance_m - 0.8 / fit.points as f32).abs() < 1e-4);
        assert!(fit.supported_share > 0.99);
        assert!((fit.surface_area_m2 - std::f32::consts::TAU * 0.2 * 2.0).abs() < 1e-3);
    }

    /// A 5 cm branch that starts on the axis of a 30 cm stem: the part of
    /// its cylinder inside the stem is not surface, so the bark points of
    /// both cover all of the model's surface.
    #[test]
    fn a_cylinder_inside_another_is_not_unsupported_surface() {
        let mut s = Skeleton::new(Anchor::at(DVec3::ZERO), 0.3);
        s.add_child(NodeId::ROOT, Vec3::new(0.0, 0.0, 1.0), 0.3);
        let base = s.add_child(NodeId::ROOT, Vec3::ZERO, 0.05);
        s.add_child(base, Vec3::new(1.5, 0.0, 1.0), 0.05);
        let mut pts = Vec::new();
        for i in 0..100 {
            for j in 0..96 {
                let a = j as f32 / 96.0 * std::f32::consts::TAU;
                pts.push(Vec3::new(0.3 * a.cos(), 0.3 * a.sin(), i as f32 * 0.01));
            }
        }
        let (a, b) = (Vec3::ZERO, Vec3::new(1.5, 0.0, 1.0));
        let (e1, e2) = (b - a).normalize().any_orthonormal_pair();
        for i in 0..180 {
            let c = a.lerp(b, i as f32 / 180.0);
            for j in 0..24 {
                let phi = j as f32 / 24.0 * std::f32::consts::TAU;
                pts.push(c + (e1 * phi.cos() + e2 * phi.sin()) * 0.05);
            }
        }
        let pts: Vec<Vec3> = pts
            .into_iter()
            .filter(|p| p.truncate().length() >= 0.29)
            .collect();
        let fit = surface_fit(&s, &PointCloud::from_points(DVec3::ZERO, pts));
        assert!(fit.supported_share > 0.99, "{}", fit.supported_share);
    }

    #[test]
    fn a_too_fat_cylinder_is_not_supported() {
        let mut s = Skeleton::new(Anchor::at(DVec3::ZERO), 0.5);
        s.add_child(NodeId::ROOT, Vec3::new(0.0, 0.0, 1.0), 0.5);
        let pts = (0..100)
            .map(|i| Vec3::new(0.1, 0.0, i as f32 * 0.01))
            .collect();
        let fit = surface_fit(&s, &PointCloud::from_points(DVec3::ZERO, pts));
        assert_eq!(fit.within_5cm, 0.0);
        assert!(fit.supported_share < 0.05);
    }
}
