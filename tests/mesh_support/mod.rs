//! Synthetic test trees for the mesh and CityJSON tests and benchmarks:
//! random branching skeletons whose radii follow the pipe model, so they
//! taper from trunk to twigs like reconstructed trees do; and the split of a
//! binary PLY file into header and body.

#![allow(dead_code)] // each test binary uses a different subset

use std::collections::VecDeque;

use glam::{DVec3, Quat, Vec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use silva::{Anchor, NodeId, Skeleton};

/// Radius of a twig tip, in metres.
const TIP_RADIUS_M: f32 = 0.006;

/// Length of one internode, in metres.
const STEP_M: f32 = 0.08;

/// A georeferenced random tree of about `internodes` internodes (EPSG:28992,
/// anchored near Delft), deterministic for `seed`. Internodes are about
/// 8 cm, as in reconstructed skeletons; the tree's height is searched so
/// that the crown holds about the requested count.
pub fn random_tree(seed: u64, internodes: usize) -> Skeleton {
    let (mut low, mut high) = (0.5f32, 40.0f32);
    for _ in 0..16 {
        let height = 0.5 * (low + high);
        if grow(seed, height, 2 * internodes).len() > internodes {
            high = height;
        } else {
            low = height;
        }
    }
    grow(seed, high, internodes)
}

/// Grows a tree whose trunk is `height_m` long, stopping at `max_internodes`.
fn grow(seed: u64, height_m: f32, max_internodes: usize) -> Skeleton {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let anchor = Anchor {
        origin: DVec3::new(84_512.345 + seed as f64 * 10.0, 447_123.678, -0.42),
        crs: Some("EPSG:28992".into()),
    };
    let mut tree = Skeleton::new(anchor, 0.0);
    // (fork node, direction, branch order, remaining length in metres)
    let mut branches = VecDeque::from([(NodeId::ROOT, Vec3::Z, 0u32, height_m)]);
    while let Some((fork, dir, order, length)) = branches.pop_front() {
        let mut node = fork;
        let mut dir = dir;
        let mut grown = 0.0;
        while grown < length && tree.len() <= max_internodes {
            let step = STEP_M * rng.random_range(0.6..1.4f32);
            // Wander a little, and bend laterals upward (gravitropism).
            // A random walk: the wander per step grows with the square root
            // of the step, so curvature does not depend on internode length.
            let amplitude = 0.1 * (step / 0.3).sqrt();
            let wander = Vec3::new(
                rng.random_range(-amplitude..amplitude),
                rng.random_range(-amplitude..amplitude),
                rng.random_range(-amplitude..amplitude),
            );
            dir = (dir + wander + Vec3::Z * 0.05 * order as f32).normalize();
            let position = tree.position(node) + dir * step;
            node = tree.add_child(node, position, 0.0);
            grown += step;
            // About 3 laterals per metre, none on the lowest quarter of the trunk.
            let chance = if order == 0 && grown < 0.25 * height_m {
                0.0
            } else {
                3.0 * step
            };
            if order < 5 && rng.random::<f32>() < chance {
                let azimuth = rng.random_range(0.0..std::f32::consts::TAU);
                let tilt = rng.random_range(0.5..1.1f32);
                let axis = Quat::from_rotation_arc(Vec3::Z, dir)
                    * Vec3::new(azimuth.cos(), azimuth.sin(), 0.0);
                let lateral =
                    Quat::from_axis_angle(axis.cross(dir).normalize_or(Vec3::X), tilt) * dir;
                let remaining = (length - grown) * rng.random_range(0.3..0.6);
                branches.push_back((
                    node,
                    lateral.normalize(),
                    order + 1,
                    remaining.max(2.0 * STEP_M),
                ));
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

/// A binary PLY file's header (through `end_header`) and body.
pub fn split_ply(bytes: &[u8]) -> (String, &[u8]) {
    let end = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .expect("PLY header")
        + 11;
    (
        String::from_utf8(bytes[..end].to_vec()).unwrap(),
        &bytes[end..],
    )
}
