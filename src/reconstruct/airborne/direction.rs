//! The direction field: Hu et al. §5.3, Eq. 5.
//!
//! Natural branches grow upward near the trunk and turn outward toward the
//! crown's edge, more so low in the crown than high up. Eq. 5 gives each
//! point a growth angle θ_i above the horizontal from its height and its
//! distance to the vertical centreline of the bounding box:
//!
//! θ_i = 90° − (90° − θ_l − μ1 (θ_u − θ_l)) μ2,
//! μ1 = ((z_i − z_min) / (z_max − z_min))^k1, μ2 = (d_i / L_c)^k2,
//!
//! with d_i the horizontal distance to the centreline and L_c that of the
//! box corner p_min. The 2D field is rotated about the centreline: the
//! direction u_i points outward by cos θ_i and up by sin θ_i (the paper's
//! y-up vector (p.x − c.x, ‖p − c‖ tan θ_i, p.z − c.z), normalised).

use glam::{Vec2, Vec3};

use super::Params;

/// Growth direction u_i (unit) of every point (Eq. 5).
pub(super) fn direction_field(points: &[Vec3], params: &Params) -> Vec<Vec3> {
    let Some((lo, hi)) = points
        .iter()
        .map(|&p| (p, p))
        .reduce(|(a, b), (c, d)| (a.min(c), b.max(d)))
    else {
        return Vec::new();
    };
    let centre = ((lo + hi) * 0.5).truncate();
    let l_c = (lo.truncate() - centre).length();
    let height = hi.z - lo.z;
    let (theta_l, theta_u) = (params.theta_lower_deg, params.theta_upper_deg);
    points
        .iter()
        .map(|p| {
            let outward: Vec2 = p.truncate() - centre;
            let mu1 = ratio(p.z - lo.z, height).powf(params.k1);
            let mu2 = ratio(outward.length(), l_c).powf(params.k2);
            let theta_deg = 90.0 - (90.0 - theta_l - mu1 * (theta_u - theta_l)) * mu2;
            let (sin, cos) = theta_deg.to_radians().sin_cos();
            match outward.try_normalize() {
                Some(out) => (out * cos).extend(sin).normalize_or(Vec3::Z),
                None => Vec3::Z,
            }
        })
        .collect()
}

/// `num / den` clamped to [0, 1]; 0 for an empty range.
fn ratio(num: f32, den: f32) -> f32 {
    if den > f32::EPSILON {
        (num / den).clamp(0.0, 1.0)
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vertical_on_the_centreline_and_outward_at_the_lower_edge() {
        let pts = [
            Vec3::new(-5.0, -5.0, 0.0),
            Vec3::new(5.0, 5.0, 10.0),
            Vec3::new(0.0, 0.0, 5.0),
            Vec3::new(5.0, 5.0, 0.0),
            Vec3::new(5.0, 5.0, 10.0),
        ];
        let u = direction_field(&pts, &Params::default());
        assert!(u[2].distance(Vec3::Z) < 1e-6);
        // Lower outer corner: θ_l = −40°, pointing outward and down.
        let down = u[3].z.asin().to_degrees();
        assert!((down + 40.0).abs() < 0.1, "{down}");
        assert!(u[3].x > 0.0 && u[3].y > 0.0);
        // Upper outer corner: θ_u = 80°.
        assert!((u[4].z.asin().to_degrees() - 80.0).abs() < 0.1);
    }
}
