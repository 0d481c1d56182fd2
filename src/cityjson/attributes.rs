//! The CityGML vegetation attributes of a SolitaryVegetationObject, derived
//! from the skeleton when the caller has no better value.
//!
//! CityGML 2.0/3.0 (and CityJSON, which reuses the names) define `species`,
//! `height`, `trunkDiameter` (at breast height, 1.3 m) and `crownDiameter`,
//! all lengths in metres. Measured metrics (e.g. from the point cloud) passed
//! in by the caller take precedence over these skeleton estimates.

use crate::skeleton::{NodeId, Skeleton};

/// Breast height above the trunk base, in metres, where `trunkDiameter` is
/// measured (forestry's DBH convention, as CityGML specifies).
pub const BREAST_HEIGHT_M: f32 = 1.3;

/// Tree height: the highest node above the trunk base, in metres.
pub fn height_m(skeleton: &Skeleton) -> f32 {
    let base = skeleton.position(NodeId::ROOT).z;
    skeleton.bounds().1.z - base
}

/// Trunk diameter at breast height: twice the radius interpolated along the
/// trunk (the root's main-extension chain) where it passes 1.3 m above the
/// base; twice the top trunk radius if the trunk is shorter.
pub fn trunk_diameter_m(skeleton: &Skeleton) -> f32 {
    let base = skeleton.position(NodeId::ROOT).z;
    let target = base + BREAST_HEIGHT_M;
    let mut node = NodeId::ROOT;
    while let Some(&next) = skeleton.children(node).first() {
        let (z0, z1) = (skeleton.position(node).z, skeleton.position(next).z);
        if z0 <= target && target <= z1 && z1 > z0 {
            let t = (target - z0) / (z1 - z0);
            let r = skeleton.radius(node) + t * (skeleton.radius(next) - skeleton.radius(node));
            return 2.0 * r;
        }
        node = next;
    }
    2.0 * skeleton.radius(node)
}

/// Crown diameter: the mean of the east–west and north–south extents of
/// the skeleton, in metres.
pub fn crown_diameter_m(skeleton: &Skeleton) -> f32 {
    let (lo, hi) = skeleton.bounds();
    0.5 * ((hi.x - lo.x) + (hi.y - lo.y))
}

#[cfg(test)]
mod tests {
    use glam::{DVec3, Vec3};

    use super::*;
    use crate::skeleton::Anchor;

    #[test]
    fn dimensions_of_a_simple_tree() {
        let mut s = Skeleton::new(Anchor::at(DVec3::ZERO), 0.3);
        let a = s.add_child(NodeId::ROOT, Vec3::new(0.0, 0.0, 2.6), 0.1);
        s.add_child(a, Vec3::new(0.0, 0.0, 8.0), 0.05);
        s.add_child(a, Vec3::new(3.0, 1.0, 5.0), 0.05);
        assert_eq!(height_m(&s), 8.0);
        // Half way up the first internode: r = 0.2.
        assert!((trunk_diameter_m(&s) - 0.4).abs() < 1e-6);
        assert_eq!(crown_diameter_m(&s), 2.0);
    }
}
