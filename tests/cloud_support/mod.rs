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

/// `cloud` as exported with the `up` axis (`'x'` or `'y'`) pointing up, as
/// mesh and game tools write it: the tree lies on its side, its top towards
/// +`up`, and z runs across it.
pub fn lying_with_up(cloud: &PointCloud, up: char) -> PointCloud {
    let turn = |p: Vec3| match up {
        'x' => Vec3::new(p.z, p.y, -p.x),
        'y' => Vec3::new(p.x, p.z, -p.y),
        _ => panic!("up is 'x' or 'y', not {up:?}"),
    };
    PointCloud::from_points(
        cloud.offset,
        cloud.points.iter().map(|&p| turn(p)).collect(),
    )
}
