//! Skeleton generators for the chain code tests and benchmark.
//!
//! `random_skeleton` is deliberately hostile to the encoder: arbitrary
//! directions and lengths (zero included), multi-way forks, unordered
//! children. `botanical_tree` is a smooth, tapering tree of the kind the
//! paper encodes (slowly bending axes, laterals at 30–70°, pipe-model radii)
//! until `silva::synth` provides trees.

use glam::{DVec3, Vec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use silva::{Anchor, NodeId, Skeleton};

/// The anchor of every generated skeleton: the Dutch national grid.
pub fn anchor() -> Anchor {
    Anchor {
        origin: DVec3::new(155_000.0, 463_000.0, 0.0),
        crs: Some("EPSG:28992".into()),
    }
}

fn unit(rng: &mut ChaCha8Rng) -> Vec3 {
    loop {
        let v = Vec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        let l = v.length();
        if l > 0.05 && l <= 1.0 {
            return v / l;
        }
    }
}

/// `nodes` nodes; each attaches to a recent node (so chains form) or, now
/// and then, to any node (so forks get 3+ children). Radii are whole
/// millimetres so that LOD thresholds at half millimetres are unambiguous.
pub fn random_skeleton(seed: u64, nodes: usize) -> Skeleton {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut s = Skeleton::new(anchor(), rng.random_range(0..500) as f32 * 0.001);
    let root_offset = Vec3::new(
        rng.random_range(-50.0..50.0),
        rng.random_range(-50.0..50.0),
        rng.random_range(-5.0..5.0),
    );
    s.set_position(NodeId::ROOT, root_offset);
    for i in 1..nodes {
        let parent = if rng.random_bool(0.8) {
            i - 1 - rng.random_range(0..i.min(3))
        } else {
            rng.random_range(0..i)
        };
        let parent = NodeId::from_index(parent);
        let length = if rng.random_bool(0.05) {
            0.0
        } else {
            rng.random_range(0.0..2.0)
        };
        let pos = s.position(parent) + unit(&mut rng) * length;
        s.add_child(parent, pos, rng.random_range(0..400) as f32 * 0.001);
    }
    s
}

/// A smooth tree of roughly `target` internodes: a trunk and recursive
/// laterals up to order 4, internodes of 0.2 m ± 5 % (the paper's trees have
/// fixed-length internodes), axes bending by about 7° per internode, radii
/// by the pipe model (`r = 4 mm · √tips`), main extension first.
pub fn botanical_tree(seed: u64, target: usize) -> Skeleton {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut s = Skeleton::new(anchor(), 0.0);
    s.set_position(NodeId::ROOT, Vec3::new(12.5, -3.25, 0.5));
    // (start node, direction, internodes, order)
    let mut pending = vec![(NodeId::ROOT, Vec3::Z, 60usize, 0u32)];
    while let Some((start, mut dir, count, order)) = pending.pop() {
        let mut node = start;
        for k in 0..count {
            if s.len() > target {
                break;
            }
            let bend = unit(&mut rng) * 0.12 + Vec3::Z * 0.03;
            dir = (dir + bend).normalize();
            let length = 0.2 * rng.random_range(0.95..1.05);
            let next = s.add_child(node, s.position(node) + dir * length, 0.0);
            let remaining = count - k;
            if order < 4 && remaining > 3 && rng.random_bool(0.35) {
                let side = (unit(&mut rng) - dir * unit(&mut rng).dot(dir)).normalize_or(Vec3::X);
                let angle = rng.random_range(0.5..1.2f32);
                let lateral = (dir * angle.cos() + side * angle.sin()).normalize();
                let len = (remaining as f32 * rng.random_range(0.3..0.7)) as usize + 2;
                pending.push((next, lateral, len, order + 1));
            }
            node = next;
        }
    }
    let mut tips = vec![0u32; s.len()];
    for id in s.ids().rev() {
        if s.is_tip(id) {
            tips[id.index()] = 1;
        }
        if let Some(p) = s.parent(id) {
            tips[p.index()] += tips[id.index()];
        }
    }
    for id in s.ids() {
        let r = 0.004 * (tips[id.index()] as f32).sqrt();
        s.set_radius(id, (r * 1000.0).round() / 1000.0);
    }
    s.order_main_extension_first();
    s
}
