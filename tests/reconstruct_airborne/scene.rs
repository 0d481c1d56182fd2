//! A small synthetic airborne scene for the airborne pipeline's tests: one
//! broadleaf tree with a known skeleton, standing on sloped ground, scanned
//! from above at a given pulse density with first and later returns, and no
//! classification (as an AHN clip). A module of `reconstruct_airborne.rs`;
//! it holds no tests of its own.

#![allow(dead_code)]

use glam::{DVec3, Vec2, Vec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use silva::cloud::PointCloud;
use silva::skeleton::{Anchor, NodeId, Skeleton};

/// Terrain under the scene: relative height at (x, y), a 6 % slope along x.
pub fn terrain_z(x: f32, _y: f32) -> f32 {
    0.06 * x
}

/// The absolute trunk base of the scene's tree (EPSG:28992-like values).
pub const BASE: DVec3 = DVec3::new(155_000.5, 463_000.25, 2.0);

/// A broadleaf tree: a 3 m trunk, a leader to about `height_m`, scaffold
/// branches around the leader, and twigs on the scaffolds. Anchored at
/// [`BASE`]; relative root at the origin. `lean` shifts the crown sideways
/// by up to that many metres (asymmetric crowns).
pub fn tree(seed: u64, height_m: f32, lean: f32) -> Skeleton {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut s = Skeleton::new(Anchor::at(BASE), 0.25);
    let crown_base = 3.0;
    let lean_dir = Vec2::from_angle(rng.random_range(0.0..std::f32::consts::TAU));
    let mut node = NodeId::ROOT;
    let mut pos = Vec3::ZERO;
    let steps = (height_m / 0.5).round() as usize;
    let mut k = 0usize;
    for i in 1..=steps {
        let z = i as f32 * 0.5;
        let t = z / height_m;
        let sway = if z > crown_base {
            lean * ((z - crown_base) / (height_m - crown_base))
        } else {
            0.0
        };
        pos = (lean_dir * sway).extend(z);
        let radius = 0.25 * (1.0 - t).max(0.06);
        node = s.add_child(node, pos, radius);
        if z >= crown_base && z <= height_m - 1.5 {
            let azimuth = k as f32 * 2.399_963;
            k += 1;
            scaffold(
                &mut s,
                &mut rng,
                node,
                pos,
                azimuth,
                (z - crown_base) / (height_m - crown_base),
                radius,
            );
        }
    }
    let _ = pos;
    s
}

fn scaffold(
    s: &mut Skeleton,
    rng: &mut ChaCha8Rng,
    from: NodeId,
    start: Vec3,
    azimuth: f32,
    rel_height: f32,
    parent_r: f32,
) {
    let length = 5.5 * (1.0 - rel_height * 0.7) + rng.random_range(-0.4..0.4);
    let elevation = (25.0 + 30.0 * rel_height + rng.random_range(-8.0..8.0f32)).to_radians();
    let horizontal = Vec2::from_angle(azimuth);
    let base_r = (0.11 * (1.0 - rel_height * 0.6)).min(parent_r * 0.8);
    let n = (length / 0.4).ceil() as usize;
    let mut node = from;
    let mut pos = start;
    for i in 1..=n {
        let t = i as f32 / n as f32;
        // Branches bend upward toward their tips.
        let elev = elevation + 0.25 * t;
        let dir = (horizontal * elev.cos()).extend(elev.sin());
        pos += dir * (length / n as f32);
        let radius = base_r * (1.0 - t) + 0.012 * t;
        node = s.add_child(node, pos, radius);
        if i % 2 == 0 && i < n {
            let side = if (i / 2) % 2 == 0 { 1.0 } else { -1.0 };
            let twig_dir = (Vec2::from_angle(azimuth + side * 0.9) * 0.7)
                .extend(0.7)
                .normalize();
            let mut tpos = pos;
            let mut tnode = node;
            for j in 1..=3 {
                tpos += twig_dir * 0.35;
                tnode = s.add_child(tnode, tpos, 0.02 - 0.004 * j as f32);
            }
        }
    }
}

/// A scan of `truth` from above at `density_pts_per_m2` pulses per m² over a
/// square clip `margin_m` wider than the crown on every side, with ground
/// returns, unclassified. Foliage is modelled as leaf discs around the thin
/// branches; a pulse returns from the highest element it meets and, with
/// probability 0.4, once more from the next element below (or the ground).
pub fn scan(truth: &Skeleton, density_pts_per_m2: f32, margin_m: f32, seed: u64) -> PointCloud {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5eed);
    let elements = elements(truth, &mut rng);
    let (lo, hi) = truth.bounds();
    let (lo, hi) = (lo.truncate() - margin_m, hi.truncate() + margin_m);
    let area = (hi - lo).x * (hi - lo).y;
    let pulses = (area * density_pts_per_m2 * 0.75) as usize;
    let grid = Grid::new(&elements, lo, 0.5);
    let mut points = Vec::new();
    for _ in 0..pulses {
        let xy = Vec2::new(rng.random_range(lo.x..hi.x), rng.random_range(lo.y..hi.y));
        let mut hits = grid.hits(&elements, xy);
        hits.sort_by(|a, b| b.total_cmp(a));
        let ground = terrain_z(xy.x, xy.y) + rng.random_range(-0.03..0.03);
        hits.push(ground);
        points.push(xy.extend(hits[0]));
        if hits.len() > 1 && rng.random_bool(0.4) {
            let k = rng.random_range(1..hits.len());
            points.push(xy.extend(hits[k]));
        }
    }
    PointCloud::from_points(truth.anchor().origin, points)
}

/// Reflecting elements: (centre, radius). Leaves around thin branches,
/// bark discs along every internode.
fn elements(truth: &Skeleton, rng: &mut ChaCha8Rng) -> Vec<(Vec3, f32)> {
    let mut out = Vec::new();
    for (p, c) in truth.internodes() {
        let (a, b) = (truth.position(p), truth.position(c));
        let r = truth.radius(c);
        let n = (a.distance(b) / 0.05).ceil() as usize;
        for k in 0..n {
            out.push((a.lerp(b, k as f32 / n as f32), r.max(0.01)));
        }
        if r < 0.05 {
            for _ in 0..25 {
                let along = a.lerp(b, rng.random_range(0.0..1.0));
                let offset = Vec3::new(
                    rng.random_range(-0.35..0.35),
                    rng.random_range(-0.35..0.35),
                    rng.random_range(-0.2..0.3),
                );
                out.push((along + offset, 0.12));
            }
        }
    }
    out
}

/// A 2D bucket grid over the elements for the pulse queries.
struct Grid {
    lo: Vec2,
    cell: f32,
    cols: usize,
    rows: usize,
    buckets: Vec<Vec<u32>>,
}

impl Grid {
    fn new(elements: &[(Vec3, f32)], lo: Vec2, cell: f32) -> Self {
        let hi = elements.iter().fold(lo, |h, (p, _)| h.max(p.truncate()));
        let cols = ((hi.x - lo.x) / cell) as usize + 2;
        let rows = ((hi.y - lo.y) / cell) as usize + 2;
        let mut buckets = vec![Vec::new(); cols * rows];
        for (i, (p, _)) in elements.iter().enumerate() {
            let c = ((p.x - lo.x) / cell).max(0.0) as usize;
            let r = ((p.y - lo.y) / cell).max(0.0) as usize;
            buckets[r.min(rows - 1) * cols + c.min(cols - 1)].push(i as u32);
        }
        Self {
            lo,
            cell,
            cols,
            rows,
            buckets,
        }
    }

    /// Heights of the elements whose disc covers `xy`.
    fn hits(&self, elements: &[(Vec3, f32)], xy: Vec2) -> Vec<f32> {
        let c = ((xy.x - self.lo.x) / self.cell) as isize;
        let r = ((xy.y - self.lo.y) / self.cell) as isize;
        let mut out = Vec::new();
        for dr in -1..=1 {
            for dc in -1..=1 {
                let (rr, cc) = (r + dr, c + dc);
                if rr < 0 || cc < 0 || rr as usize >= self.rows || cc as usize >= self.cols {
                    continue;
                }
                for &i in &self.buckets[rr as usize * self.cols + cc as usize] {
                    let (p, radius) = elements[i as usize];
                    if p.truncate().distance(xy) <= radius {
                        out.push(p.z);
                    }
                }
            }
        }
        out
    }
}
