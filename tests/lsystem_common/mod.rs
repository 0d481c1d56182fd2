//! Skeleton generators for the LsJSON tests: hostile random trees and
//! tree-like synthetic ones. Deterministic per seed.
#![allow(dead_code)]

use glam::{DVec3, Quat, Vec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use silva::{Anchor, NodeId, Skeleton};

/// A direction that is often exactly or nearly along ±Z (the poles where
/// Euler-angle turtles flip), otherwise uniform.
fn hostile_direction(rng: &mut ChaCha8Rng) -> Vec3 {
    match rng.random_range(0..6) {
        0 => Vec3::Z,
        1 => -Vec3::Z,
        2 => {
            let eps = 10f32.powf(rng.random_range(-7.0..-2.0));
            Vec3::new(
                eps,
                rng.random_range(-eps..eps),
                if rng.random_bool(0.5) { 1.0 } else { -1.0 },
            )
            .normalize()
        }
        3 => [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y][rng.random_range(0..4)],
        _ => loop {
            let v = Vec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            );
            if v.length() > 0.1 {
                break v.normalize();
            }
        },
    }
}

/// A random tree of `nodes` nodes: random parents (often the newest node, so
/// chains get long), hostile directions, internodes from 0 (coincident
/// nodes) and 0.1 mm to 5 m, a national-grid anchor.
pub fn random_tree(seed: u64, nodes: usize, chain_bias: f64) -> Skeleton {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let anchor = Anchor {
        origin: DVec3::new(
            rng.random_range(0.0..300_000.0),
            rng.random_range(300_000.0..625_000.0),
            rng.random_range(-10.0..100.0),
        ),
        crs: Some("EPSG:28992".into()),
    };
    let root = Vec3::new(
        rng.random_range(-2.0..2.0),
        rng.random_range(-2.0..2.0),
        rng.random_range(-1.0..1.0),
    );
    let mut s = Skeleton::new(anchor, rng.random_range(0.0..0.8));
    s.set_position(NodeId::ROOT, root);
    for i in 1..nodes {
        let parent = if rng.random_bool(chain_bias) {
            NodeId::from_index(i - 1)
        } else {
            NodeId::from_index(rng.random_range(0..i))
        };
        let length = match rng.random_range(0..10) {
            0 => 0.0,
            1 => 10f32.powf(rng.random_range(-4.0..-2.0)),
            2 => rng.random_range(1.0..5.0),
            _ => rng.random_range(0.02..0.8),
        };
        let position = s.position(parent) + hostile_direction(&mut rng) * length;
        let radius = rng.random_range(0.0..0.5) * if rng.random_bool(0.1) { 0.001 } else { 1.0 };
        s.add_child(parent, position, radius);
    }
    s
}

/// A tree-like skeleton: a trunk of ~0.3 m internodes that wanders upward,
/// laterals at 30–70° with random phyllotaxis, recursively up to order 3,
/// radii tapering by the pipe model. About `internodes` internodes.
pub fn synthetic_tree(seed: u64, internodes: usize) -> Skeleton {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let anchor = Anchor::at(DVec3::new(
        155_000.0 + rng.random_range(0.0..1000.0),
        463_000.0,
        2.0,
    ));
    let mut s = Skeleton::new(anchor, 0.35);
    // (start node, direction, internodes left, order)
    let trunk_len = (internodes as f64).sqrt() as usize + 10;
    let mut queue = vec![(NodeId::ROOT, Vec3::Z, trunk_len, 0u32)];
    while let Some((mut node, mut dir, steps, order)) = queue.pop() {
        for step in 0..steps {
            if s.internode_count() >= internodes {
                break;
            }
            let wobble =
                Quat::from_axis_angle(dir.any_orthonormal_vector(), rng.random_range(-0.15..0.15))
                    * Quat::from_axis_angle(dir, rng.random_range(-3.0..3.0));
            dir = (wobble * dir + Vec3::Z * 0.05 * (order as f32 == 0.0) as i32 as f32).normalize();
            let length = rng.random_range(0.15..0.45) * 0.8f32.powi(order as i32);
            let taper = 1.0 - step as f32 / (steps as f32 + 1.0);
            let radius = (0.3 * 0.45f32.powi(order as i32) * taper).max(0.003);
            node = s.add_child(node, s.position(node) + dir * length, radius);
            if order < 3 && step > 1 && rng.random_bool(0.45) {
                let axis = dir.any_orthonormal_vector();
                let spin = Quat::from_axis_angle(dir, rng.random_range(0.0..std::f32::consts::TAU));
                let lateral =
                    spin * (Quat::from_axis_angle(axis, rng.random_range(0.5..1.2)) * dir);
                let left = ((steps - step) as f32 * rng.random_range(0.4..0.8)) as usize + 2;
                queue.push((node, lateral, left, order + 1));
            }
        }
    }
    s.order_main_extension_first();
    s.canonical()
}

/// Largest absolute node distance and radius difference between two
/// skeletons with the same canonical node order.
pub fn max_errors(original: &Skeleton, decoded: &Skeleton) -> (f64, f32) {
    let a = original.canonical();
    assert_eq!(a.len(), decoded.len(), "node count");
    let mut worst = (0.0f64, 0.0f32);
    for id in a.ids() {
        assert_eq!(a.parent(id), decoded.parent(id), "topology at {id:?}");
        assert_eq!(
            a.children(id),
            decoded.children(id),
            "child order at {id:?}"
        );
        let d = a
            .absolute_position(id)
            .distance(decoded.absolute_position(id));
        worst.0 = worst.0.max(d);
        worst.1 = worst.1.max((a.radius(id) - decoded.radius(id)).abs());
    }
    worst
}
