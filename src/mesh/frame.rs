//! A branch's smoothed axis and its rotation-minimising frames.
//!
//! Skeleton polylines are jagged (lsystem-from-adtree-skeletons §4.5 shows
//! pipes swept along them unsmoothed). The axis is therefore an interpolating
//! cubic Hermite spline through the nodes, Catmull–Rom style: the tangent at
//! a node is the bisector of its two internode directions, scaled by each
//! segment's length (chord-length parametrisation). Using unit directions
//! rather than raw differences keeps a short internode next to a long one
//! from bending the long one into a bulge. A segment is subdivided only where
//! the axis turns, so straight stems cost one ring per node.
//!
//! Rings are oriented by the double-reflection rotation-minimising frame
//! (Wang, Jüttler, Zheng & Liu 2008), a discrete parallel transport: the ring
//! normal is reflected across the bisector plane of each step and then across
//! the plane that maps the reflected tangent onto the next one, so it never
//! spins about the axis and the quads between rings do not twist.

use glam::Vec3;

use super::lod::RingResolution;

/// One sample of a swept axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AxisSample {
    /// Centre of the ring, relative to the skeleton anchor.
    pub centre: Vec3,
    /// Unit tangent of the axis.
    pub tangent: Vec3,
    /// Tube radius here, in metres.
    pub radius_m: f32,
    /// Change of radius per metre along the axis (negative where the branch
    /// tapers); tilts the surface normals of a cone.
    pub radius_slope: f32,
}

/// Samples the smoothed axis through `points` with per-point radii, radius
/// interpolated linearly along each internode. Consecutive points must be
/// distinct and there must be at least two; `out` is cleared first.
pub fn smooth_axis(
    points: &[Vec3],
    radii: &[f32],
    resolution: &RingResolution,
    out: &mut Vec<AxisSample>,
) {
    out.clear();
    debug_assert!(points.len() >= 2 && points.len() == radii.len());
    let lengths: Vec<f32> = points.windows(2).map(|w| w[0].distance(w[1])).collect();
    let tangents = node_tangents(points, &lengths);
    for i in 0..lengths.len() {
        let (p0, p1, l) = (points[i], points[i + 1], lengths[i]);
        let (m0, m1) = (tangents[i] * l, tangents[i + 1] * l);
        let chord = (p1 - p0) / l;
        let slope = (radii[i + 1] - radii[i]) / l;
        let turn = tangents[i].angle_between(tangents[i + 1]);
        let steps = if turn.is_finite() {
            ((turn / resolution.max_turn_rad).ceil() as u32)
                .clamp(1, 1 + resolution.max_subdivisions)
        } else {
            1
        };
        let first = if i == 0 { 0 } else { 1 };
        for j in first..=steps {
            let u = j as f32 / steps as f32;
            let (centre, derivative) = hermite(p0, m0, p1, m1, u);
            let tangent = derivative.try_normalize().unwrap_or(chord);
            out.push(AxisSample {
                centre,
                tangent,
                radius_m: radii[i] + u * (radii[i + 1] - radii[i]),
                radius_slope: slope,
            });
        }
    }
}

/// Unit tangents at every point: one-sided at the ends, the bisector of the
/// adjacent internode directions in between.
fn node_tangents(points: &[Vec3], lengths: &[f32]) -> Vec<Vec3> {
    let n = points.len();
    let dir = |i: usize| (points[i + 1] - points[i]) / lengths[i];
    (0..n)
        .map(|i| {
            if i == 0 {
                dir(0)
            } else if i == n - 1 {
                dir(n - 2)
            } else {
                // A reversal (180° turn) has no bisector; keep the outgoing direction.
                (dir(i - 1) + dir(i)).try_normalize().unwrap_or(dir(i))
            }
        })
        .collect()
}

/// Cubic Hermite point and derivative at `u` in `[0, 1]`.
fn hermite(p0: Vec3, m0: Vec3, p1: Vec3, m1: Vec3, u: f32) -> (Vec3, Vec3) {
    let (u2, u3) = (u * u, u * u * u);
    let point = p0 * (2.0 * u3 - 3.0 * u2 + 1.0)
        + m0 * (u3 - 2.0 * u2 + u)
        + p1 * (-2.0 * u3 + 3.0 * u2)
        + m1 * (u3 - u2);
    let derivative = p0 * (6.0 * u2 - 6.0 * u)
        + m0 * (3.0 * u2 - 4.0 * u + 1.0)
        + p1 * (-6.0 * u2 + 6.0 * u)
        + m1 * (3.0 * u2 - 2.0 * u);
    (point, derivative)
}

/// Ring normals along `samples` by double reflection, starting from a normal
/// perpendicular to the first tangent; `out` is cleared first.
pub fn rotation_minimising_normals(samples: &[AxisSample], out: &mut Vec<Vec3>) {
    out.clear();
    let Some(first) = samples.first() else {
        return;
    };
    let mut normal = any_perpendicular(first.tangent);
    out.push(normal);
    for w in samples.windows(2) {
        let (a, b) = (w[0], w[1]);
        let v1 = b.centre - a.centre;
        let c1 = v1.length_squared();
        let (r_l, t_l) = if c1 > 0.0 {
            (
                normal - v1 * (2.0 / c1 * v1.dot(normal)),
                a.tangent - v1 * (2.0 / c1 * v1.dot(a.tangent)),
            )
        } else {
            (normal, a.tangent)
        };
        let v2 = b.tangent - t_l;
        let c2 = v2.length_squared();
        let reflected = if c2 > 0.0 {
            r_l - v2 * (2.0 / c2 * v2.dot(r_l))
        } else {
            r_l
        };
        // Re-orthogonalise against the new tangent so rounding cannot drift.
        normal = (reflected - b.tangent * b.tangent.dot(reflected))
            .try_normalize()
            .unwrap_or_else(|| any_perpendicular(b.tangent));
        out.push(normal);
    }
}

/// A unit vector perpendicular to the unit vector `v`, chosen
/// deterministically from the world axis least aligned with it.
pub fn any_perpendicular(v: Vec3) -> Vec3 {
    let axis = if v.x.abs() < 0.9 { Vec3::X } else { Vec3::Y };
    (axis - v * v.dot(axis)).normalize()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::Lod;

    fn bent_axis() -> Vec<AxisSample> {
        let points = [
            Vec3::ZERO,
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(0.5, 0.2, 1.8),
            Vec3::new(1.5, 0.5, 2.0),
        ];
        let mut samples = Vec::new();
        smooth_axis(
            &points,
            &[0.3, 0.2, 0.15, 0.1],
            &Lod::L3.resolution(),
            &mut samples,
        );
        samples
    }

    #[test]
    fn smoothed_axis_passes_through_the_nodes_and_subdivides_bends() {
        let samples = bent_axis();
        assert!(samples.len() > 4, "bends must be subdivided");
        assert_eq!(samples[0].centre, Vec3::ZERO);
        assert!(
            samples
                .last()
                .unwrap()
                .centre
                .distance(Vec3::new(1.5, 0.5, 2.0))
                < 1e-5
        );
        assert!(
            samples
                .iter()
                .all(|s| (s.tangent.length() - 1.0).abs() < 1e-4)
        );
        assert!((samples.last().unwrap().radius_m - 0.1).abs() < 1e-6);
    }

    #[test]
    fn frames_stay_perpendicular_and_unit() {
        let samples = bent_axis();
        let mut normals = Vec::new();
        rotation_minimising_normals(&samples, &mut normals);
        assert_eq!(normals.len(), samples.len());
        for (s, n) in samples.iter().zip(&normals) {
            assert!(s.tangent.dot(*n).abs() < 1e-4);
            assert!((n.length() - 1.0).abs() < 1e-4);
        }
    }

    #[test]
    fn frames_along_a_planar_curve_do_not_twist() {
        // For a curve in the x-z plane the rotation-minimising frame keeps its
        // binormal on the plane's normal; a twisting frame (e.g. Frenet at an
        // inflection, or a fixed up vector) would not.
        let points = [
            Vec3::ZERO,
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(0.6, 0.0, 1.7),
            Vec3::new(1.6, 0.0, 1.9),
            Vec3::new(2.2, 0.0, 2.8),
        ];
        let mut samples = Vec::new();
        smooth_axis(&points, &[0.1; 5], &Lod::L3.resolution(), &mut samples);
        let mut normals = Vec::new();
        rotation_minimising_normals(&samples, &mut normals);
        for (s, n) in samples.iter().zip(&normals) {
            let binormal = s.tangent.cross(*n);
            assert!(binormal.y.abs() > 0.9999, "binormal {binormal}");
        }
    }

    #[test]
    fn straight_axis_keeps_its_normal() {
        let points = [Vec3::ZERO, Vec3::Z, Vec3::Z * 2.0, Vec3::Z * 3.0];
        let mut samples = Vec::new();
        smooth_axis(&points, &[0.1; 4], &Lod::L3.resolution(), &mut samples);
        assert_eq!(samples.len(), 4);
        let mut normals = Vec::new();
        rotation_minimising_normals(&samples, &mut normals);
        assert!(normals.iter().all(|n| n.distance(normals[0]) < 1e-6));
    }
}
