//! Point clouds turned the wrong way, as the upright tests feed them to
//! the pipelines.

use glam::{Quat, Vec3};
use silva::cloud::PointCloud;

/// `cloud` turned by `degrees` about the x axis through its centroid, its
/// offset kept: a cloud tilted (or, at 180°, turned upside down) in its
/// own place.
pub fn turned_about_x(cloud: &PointCloud, degrees: f32) -> PointCloud {
    let centre = cloud.points.iter().copied().sum::<Vec3>() / cloud.len().max(1) as f32;
    let turn = Quat::from_rotation_x(degrees.to_radians());
    let points = cloud
        .points
        .iter()
        .map(|&p| turn * (p - centre) + centre)
        .collect();
    PointCloud::from_points(cloud.offset, points)
}
