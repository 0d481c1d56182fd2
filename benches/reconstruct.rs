//! Dense reconstruction speed on a synthetic Y-shaped tree (about 12,000
//! bark points, the size of tree1.xyz in issue 3's AdTree comparison).

use criterion::{Criterion, criterion_group, criterion_main};
use glam::{DVec3, Vec3};
use rand::{Rng, SeedableRng};
use silva::cloud::PointCloud;
use silva::reconstruct::{Mode, Options, reconstruct};
use silva::spatial::PointIndex;

fn y_tree_scan(spacing_m: f32) -> PointCloud {
    let fork = Vec3::new(0.0, 0.0, 3.0);
    let cylinders = [
        (Vec3::ZERO, fork, 0.15),
        (fork, Vec3::new(1.2, 0.0, 5.0), 0.07),
        (fork, Vec3::new(-0.8, 0.6, 5.2), 0.07),
    ];
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let mut pts = Vec::new();
    for (a, b, r) in cylinders {
        let axis = b - a;
        let u = axis.normalize();
        let (e1, e2) = (
            u.any_orthonormal_vector(),
            u.cross(u.any_orthonormal_vector()),
        );
        let n = (std::f32::consts::TAU * r * axis.length() / (spacing_m * spacing_m)) as usize;
        for _ in 0..n {
            let t: f32 = rng.random();
            let phi = rng.random::<f32>() * std::f32::consts::TAU;
            pts.push(a + axis * t + (e1 * phi.cos() + e2 * phi.sin()) * r);
        }
    }
    PointCloud::from_points(DVec3::new(155_000.0, 463_000.0, 0.0), pts)
}

fn bench(c: &mut Criterion) {
    let cloud = y_tree_scan(0.02);
    let dense = Options {
        mode: Mode::Dense,
        ..Options::default()
    };
    c.bench_function(&format!("dense_{}_points", cloud.len()), |b| {
        b.iter(|| reconstruct(&cloud, &dense).expect("a clean synthetic tree"))
    });
    c.bench_function("auto_survey", |b| {
        b.iter(|| silva::reconstruct::survey(&cloud, &Default::default()))
    });
    bench_neighbour_lists(c, &cloud.points);
}

/// The dense graph's neighbour lists (k = 10 within 10 spacings), one
/// kd-tree query per point against all points cell by cell.
fn bench_neighbour_lists(c: &mut Criterion, points: &[Vec3]) {
    let index = PointIndex::new(points);
    let radius = 10.0 * index.median_spacing(points).unwrap_or(0.02);
    c.bench_function("neighbours_per_point", |b| {
        b.iter(|| {
            points
                .iter()
                .map(|&p| index.nearest_k_within(p, 11, radius).len())
                .sum::<usize>()
        })
    });
    c.bench_function("neighbours_by_cell", |b| {
        b.iter(|| {
            let mut found = 0;
            index.each_nearest_k_within(points, 10, radius, |_, near| found += near.len());
            found
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
