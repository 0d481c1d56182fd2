//! Tips end on the scan's last points of their branch.
//!
//! A tip node is the centroid of its branch's last cross-section, so it
//! stops short of the last points the scan holds of that branch by up to a
//! bin width (on thin twigs, a few centimetres). AdTree's skeleton ends on a
//! point, because its graph's vertices are the points
//! (lsystem-from-adtree-skeletons §2.1.1), and TreeQSM's last cylinder
//! covers its last points. [`reach_last_points`] moves every tip forward
//! along its internode to the farthest point ahead of it within the
//! branch's reach. It never goes beyond the data: the true tip of a twig
//! lies farther still, by the gap between the scan's points, which nothing
//! here estimates.

use glam::Vec3;

use crate::skeleton::{NodeId, Skeleton};
use crate::spatial::PointIndex;

/// Moves each tip of `skeleton` (radii still holding the sections' spread)
/// to the farthest projection, along its incoming internode, of the
/// `points` ahead of it that lie within `reach` of that internode's line,
/// where `reach` is the tip's spread or `bin_m`, whichever is larger.
/// Only points within `reach + bin_m` of the tip count, so a tip moves at
/// most that far.
pub(super) fn reach_last_points(
    skeleton: &mut Skeleton,
    points: &[Vec3],
    index: &PointIndex,
    bin_m: f32,
) {
    let tips: Vec<NodeId> = skeleton
        .ids()
        .filter(|&id| id != NodeId::ROOT && skeleton.is_tip(id))
        .collect();
    for tip in tips {
        if let Some(end) = last_point_ahead(skeleton, tip, points, index, bin_m) {
            skeleton.set_position(tip, end);
        }
    }
}

/// Where `tip` should end: on its internode's line, level with the farthest
/// point ahead of it within the branch's reach; `None` when no point lies
/// ahead or the internode has no direction.
fn last_point_ahead(
    skeleton: &Skeleton,
    tip: NodeId,
    points: &[Vec3],
    index: &PointIndex,
    bin_m: f32,
) -> Option<Vec3> {
    let at = skeleton.position(tip);
    let from = skeleton.position(skeleton.parent(tip)?);
    let direction = (at - from).try_normalize()?;
    let reach = skeleton.radius(tip).max(bin_m);
    let ahead = index
        .within(at, reach + bin_m)
        .into_iter()
        .map(|n| points[n.index] - at)
        .filter(|d| (*d - direction * d.dot(direction)).length() <= reach)
        .map(|d| d.dot(direction))
        .fold(0.0f32, f32::max);
    (ahead > 0.0).then(|| at + direction * ahead)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::skeleton::Anchor;

    /// A twig sampled every 2 cm up to 1.00 m, whose skeleton ends at the
    /// centroid of its last section, 2 cm short. A second twig runs on past
    /// it 5 cm to the side: its points are not this twig's end.
    #[test]
    fn a_tip_moves_to_the_last_point_of_its_own_twig() {
        let mut points: Vec<Vec3> = (0..=50)
            .map(|k| Vec3::new(0.0, 0.0, k as f32 * 0.02))
            .collect();
        points.extend((0..=60).map(|k| Vec3::new(0.05, 0.0, k as f32 * 0.02)));
        let index = PointIndex::new(&points);
        let mut s = Skeleton::new(Anchor::default(), 0.004);
        let tip = s.add_child(NodeId::ROOT, Vec3::new(0.0, 0.0, 0.98), 0.004);
        reach_last_points(&mut s, &points, &index, 0.03);
        assert!(s.position(tip).distance(Vec3::new(0.0, 0.0, 1.0)) < 1e-5);
        assert_eq!(s.position(NodeId::ROOT), Vec3::ZERO);
    }
}
