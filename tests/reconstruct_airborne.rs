//! The airborne pipeline (Hu et al.) against the issue 3 targets on
//! synthetic airborne scans, ground handling, and degenerate input.

#[path = "reconstruct_airborne/scene.rs"]
mod scene;

use glam::{DVec3, Vec3};
use silva::cloud::{CLASS_GROUND, PointCloud};
use silva::eval::compare::compare;
use silva::reconstruct::ReconstructError;
use silva::reconstruct::airborne::{Params, reconstruct};
use silva::reconstruct::ground::{GroundMethod, split_ground};
use silva::skeleton::{NodeId, Skeleton};

/// Height of a skeleton: its highest node above its root, in metres.
fn height(s: &Skeleton) -> f64 {
    s.ids()
        .map(|id| s.absolute_position(id).z)
        .fold(f64::NEG_INFINITY, f64::max)
        - s.absolute_position(NodeId::ROOT).z
}

struct Figures {
    recall: f32,
    precision: f32,
    height_error_m: f64,
    base_offset_m: f64,
}

fn run(seed: u64, height_m: f32, lean: f32) -> Figures {
    let truth = scene::tree(seed, height_m, lean);
    let cloud = scene::scan(&truth, 20.0, 3.0, seed);
    let result = reconstruct(&cloud, &Params::default()).expect("a tree");
    let c = compare(&truth, &result.skeleton, 0.5, 0.05);
    let base = result.skeleton.anchor().origin - truth.anchor().origin;
    let f = Figures {
        recall: c.recall,
        precision: c.precision,
        height_error_m: height(&result.skeleton) - height(&truth),
        base_offset_m: base.truncate().length(),
    };
    println!(
        "seed {seed}: {} pts, {} nodes, recall {:.3} precision {:.3} mean {:.2} m p95 {:.2} m, \
         height error {:+.2} m, base offset {:.2} m (z {:+.2}); {:?}",
        cloud.len(),
        result.skeleton.len(),
        f.recall,
        f.precision,
        c.mean_distance_m,
        c.p95_distance_m,
        f.height_error_m,
        f.base_offset_m,
        base.z,
        result.notes
    );
    f
}

#[test]
fn synthetic_als_scans_meet_the_targets() {
    for (seed, h, lean) in [
        (1, 11.0, 0.0),
        (2, 9.0, 0.8),
        (3, 13.0, 0.4),
        (4, 10.0, 1.2),
    ] {
        let f = run(seed, h, lean);
        assert!(f.recall >= 0.90, "seed {seed}: recall {}", f.recall);
        assert!(
            f.precision >= 0.85,
            "seed {seed}: precision {}",
            f.precision
        );
        assert!(
            f.height_error_m.abs() <= 0.3,
            "seed {seed}: height error {}",
            f.height_error_m
        );
        assert!(
            f.base_offset_m <= 0.5,
            "seed {seed}: base offset {}",
            f.base_offset_m
        );
    }
}
