//! What every reader promises about a cloud it accepts, checked by the
//! reader fuzz targets (`xyz`, `ply`, `las`).

use silva::cloud::{CloudError, PointCloud, ReadOptions};

/// An accepted cloud holds at least one point and at most the limit, all
/// finite, with a finite offset and one attribute value per point.
pub fn check_read(result: Result<PointCloud, CloudError>, opts: &ReadOptions) {
    let Ok(cloud) = result else { return };
    assert!(!cloud.is_empty(), "an empty cloud is an error");
    assert!(cloud.len() <= opts.max_points, "{} points", cloud.len());
    assert!(cloud.offset.is_finite(), "offset {}", cloud.offset);
    assert!(cloud.points.iter().all(|p| p.is_finite()), "a non-finite point");
    if let Some(c) = &cloud.classification {
        assert_eq!(c.len(), cloud.len());
    }
    if let Some(i) = &cloud.intensity {
        assert_eq!(i.len(), cloud.len());
    }
    if let Some(r) = &cloud.return_number {
        assert_eq!(r.len(), cloud.len());
    }
}
