//! Clean-up before the neighbourhood graph: near-duplicate removal and, for
//! very large clouds, voxel downsampling.
//!
//! AdTree removes duplicate points first for robustness
//! (multi-temporal-tree-growth §3.2.1). A k-nearest-neighbour graph needs it
//! too: more than `k` copies of one point would form an isolated clique.
//! Downsampling bounds memory: the graph holds about `2·k` edges per point,
//! so capping the point count caps the graph (a 5-million-point scan is
//! thinned to [`super::Params::max_points`] on a voxel grid first).

use glam::{DVec3, Vec3};

/// Largest voxel index per axis (21 bits each pack into one `u64` key).
const AXIS_CELLS: f32 = (1u32 << 21) as f32 - 1.0;

/// Replaces the points in each cube of side `voxel_m` by their centroid.
/// The voxel grows if the cloud is too large for 2^21 cells per axis.
/// Returns the points and the voxel size used.
pub(super) fn voxel_centroids(points: &[Vec3], voxel_m: f32) -> (Vec<Vec3>, f32) {
    let Some(lo) = points.iter().copied().reduce(Vec3::min) else {
        return (Vec::new(), voxel_m);
    };
    let hi = points.iter().copied().fold(lo, Vec3::max);
    let voxel_m = voxel_m.max((hi - lo).max_element() / AXIS_CELLS);
    let key = |p: Vec3| {
        let c = ((p - lo) / voxel_m).floor().min(Vec3::splat(AXIS_CELLS));
        ((c.x as u64) << 42) | ((c.y as u64) << 21) | c.z as u64
    };
    let mut keyed: Vec<(u64, u32)> = points
        .iter()
        .enumerate()
        .map(|(i, &p)| (key(p), i as u32))
        .collect();
    keyed.sort_unstable();
    let mut out = Vec::new();
    let mut i = 0;
    while i < keyed.len() {
        let mut j = i;
        let mut sum = DVec3::ZERO;
        while j < keyed.len() && keyed[j].0 == keyed[i].0 {
            sum += points[keyed[j].1 as usize].as_dvec3();
            j += 1;
        }
        out.push((sum / (j - i) as f64).as_vec3());
        i = j;
    }
    (out, voxel_m)
}

/// Removes near-duplicates (points within `duplicate_m`), then thins on a
/// coarser voxel grid until at most `max_points` remain. Returns the points
/// and the final voxel size when thinning beyond de-duplication was needed.
pub(super) fn thin(
    points: &[Vec3],
    duplicate_m: f32,
    max_points: usize,
) -> (Vec<Vec3>, Option<f32>) {
    let (mut out, mut voxel) = voxel_centroids(points, duplicate_m);
    let mut thinned = None;
    while out.len() > max_points.max(1) {
        // Tree surfaces are two-dimensional: the count falls with voxel².
        let factor = ((out.len() as f32 / max_points.max(1) as f32).sqrt() * 1.05).max(1.1);
        let (next, v) = voxel_centroids(points, voxel * factor);
        out = next;
        voxel = v;
        thinned = Some(voxel);
    }
    (out, thinned)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn duplicates_merge_and_distinct_points_survive() {
        let pts = vec![
            Vec3::ZERO,
            Vec3::ZERO,
            Vec3::new(0.0001, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
        ];
        let (out, _) = voxel_centroids(&pts, 0.001);
        assert_eq!(out.len(), 2);
    }

    #[test]
    fn thinning_respects_the_point_cap() {
        let pts: Vec<Vec3> = (0..10_000)
            .map(|i| Vec3::new((i % 100) as f32 * 0.01, (i / 100) as f32 * 0.01, 0.0))
            .collect();
        let (out, voxel) = thin(&pts, 0.001, 1000);
        assert!(out.len() <= 1000 && out.len() > 100, "{}", out.len());
        assert!(voxel.is_some());
    }
}
