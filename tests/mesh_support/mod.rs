//! Synthetic test trees for the mesh and CityJSON tests and benchmarks:
//! random branching skeletons whose radii follow the pipe model, so they
//! taper from trunk to twigs like reconstructed trees do.

use std::collections::VecDeque;

use glam::{DVec3, Quat, Vec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use silva::{Anchor, NodeId, Skeleton};

/// Radius of a twig tip, in metres.
const TIP_RADIUS_M: f32 = 0.006;

/// A georeferenced random tree of about `internodes` internodes (EPSG:28992,
/// anchored near Delft), deterministic for `seed`.
pub fn random_tree(seed: u64, internodes: usize) -> Skeleton {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let anchor = Anchor {
        origin: DVec3::new(84_512.345 + seed as f64 * 10.0, 447_123.678, -0.42),
        crs: Some("EPSG:28992".into()),
    };
    let mut tree = Skeleton::new(anchor, 0.0);
    // (fork node, direction, branch order, remaining length in metres)
    let mut branches = VecDeque::from([(NodeId::ROOT, Vec3::Z, 0u32, 12.0f32)]);
    while let Some((fork, dir, order, length)) = branches.pop_front() {
        let mut node = fork;
        let mut dir = dir;
        let mut grown = 0.0;
        while grown < length && tree.len() <= internodes {
            let step = rng.random_range(0.2..0.45f32).min(length - grown + 0.05);
            // Wander a little, and bend laterals upward (gravitropism).
            let wander = Vec3::new(
                rng.random_range(-0.1..0.1),
                rng.random_range(-0.1..0.1),
                rng.random_range(-0.1..0.1),
            );
            dir = (dir + wander + Vec3::Z * 0.05 * order as f32).normalize();
            let position = tree.position(node) + dir * step;
            node = tree.add_child(node, position, 0.0);
            grown += step;
            let chance = if order == 0 && grown < 2.5 { 0.0 } else { 0.35 };
            if order < 4 && rng.random::<f32>() < chance {
                let azimuth = rng.random_range(0.0..std::f32::consts::TAU);
                let tilt = rng.random_range(0.5..1.1f32);
                let axis = Quat::from_rotation_arc(Vec3::Z, dir)
                    * Vec3::new(azimuth.cos(), azimuth.sin(), 0.0);
                let lateral =
                    Quat::from_axis_angle(axis.cross(dir).normalize_or(Vec3::X), tilt) * dir;
                let remaining = (length - grown) * rng.random_range(0.4..0.8);
                branches.push_back((node, lateral.normalize(), order + 1, remaining.max(0.5)));
            }
        }
    }
    pipe_model_radii(&mut tree);
    tree
}

/// Radius from the number of tips a node carries: `r = r_tip * sqrt(tips)`.
fn pipe_model_radii(tree: &mut Skeleton) {
    let mut tips = vec![0u32; tree.len()];
    for id in tree.ids().rev() {
        if tree.is_tip(id) {
            tips[id.index()] = 1;
        }
        if let Some(p) = tree.parent(id) {
            tips[p.index()] += tips[id.index()];
        }
    }
    for id in tree.ids() {
        tree.set_radius(id, TIP_RADIUS_M * (tips[id.index()] as f32).sqrt());
    }
}
