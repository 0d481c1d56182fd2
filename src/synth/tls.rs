//! Terrestrial laser scan simulator: points on the bark of a known skeleton.
//!
//! A co-registered multi-scan TLS cloud of a single tree is, to first order,
//! the woody surface sampled densely with millimetre noise, minus what no
//! scanner could see. Points are drawn uniformly on each internode's frustum
//! (area-weighted), points buried inside another internode (at forks) are
//! dropped, and with occlusion on, a point is kept only if at least one
//! scanner sees its outward side along an unobstructed ray. Rays are cast
//! through a uniform grid, so the cost is about points × scanners × cells per
//! ray.

use std::ops::ControlFlow;

use glam::Vec3;
use rand_chacha::ChaCha8Rng;

use super::geometry::{Frustum, Grid};
use super::random::{Stream, any_perpendicular, gaussian_vec, seeded, unit};
use crate::cloud::PointCloud;
use crate::skeleton::Skeleton;

/// Grid cell for occlusion rays, in metres: a few internodes per cell.
const GRID_CELL_M: f32 = 0.5;

/// Most points a simulated scan produces; higher densities are capped.
pub const MAX_TLS_POINTS: usize = 20_000_000;

/// Where the terrestrial scanner stood.
#[derive(Debug, Clone, PartialEq)]
pub enum ScannerPlacement {
    /// `count` positions evenly spaced on a circle around the trunk.
    Ring {
        /// Number of scan positions.
        count: usize,
        /// Circle radius in metres; `None`: the crown radius plus 5 m.
        distance_m: Option<f32>,
        /// Height of the scanner head above the trunk base, in metres.
        height_m: f32,
    },
    /// Explicit positions, relative to the tree's anchor.
    At(Vec<Vec3>),
}

/// Options of [`simulate_tls`].
#[derive(Debug, Clone, PartialEq)]
pub struct TlsOptions {
    /// Expected points per m² of bark before occlusion.
    pub points_per_m2: f32,
    /// Standard deviation of the isotropic Gaussian range noise, in metres.
    pub noise_sd_m: f32,
    /// Keep only points that some scanner sees.
    pub occlusion: bool,
    /// Scanner positions (used when `occlusion` is on).
    pub scanners: ScannerPlacement,
    /// The ground the scan holds too, as a plot scan does: `None` (the
    /// default) for a tree already cut out of its plot.
    pub ground: Option<TlsGround>,
}

/// The ground around the tree in a terrestrial scan: a disc centred on the
/// trunk base, on the plane through the base with the given gradient,
/// sampled at the bark's density and seen (with occlusion on) by the same
/// scanners, so the stem's shadow stays empty.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TlsGround {
    /// Radius of the scanned disc around the trunk base, in metres.
    pub radius_m: f32,
    /// Rise of the ground per metre along x and y (0, 0 = level).
    pub slope: glam::Vec2,
}

impl Default for TlsOptions {
    /// 150 points/m², 3 mm noise, occlusion from four positions at 1.5 m:
    /// 10⁴–10⁵ points for an oak, like a plot scan after subsampling.
    fn default() -> Self {
        TlsOptions {
            points_per_m2: 150.0,
            noise_sd_m: 0.003,
            occlusion: true,
            scanners: ScannerPlacement::Ring {
                count: 4,
                distance_m: None,
                height_m: 1.5,
            },
            ground: None,
        }
    }
}

impl TlsOptions {
    /// A clean, complete scan: 1,000 points/m² of bark and no occlusion,
    /// the other settings at their defaults. It is the scan of `silva eval
    /// --synthetic N --scan tls --density 1000 --no-occlusion`, on which the
    /// dense pipeline's accuracy target (recall and precision ≥ 0.99 at
    /// 10 cm) is measured.
    ///
    /// ```
    /// use silva::synth::TlsOptions;
    /// let clean = TlsOptions::clean();
    /// assert!(!clean.occlusion);
    /// assert_eq!(clean.points_per_m2, 1000.0);
    /// assert_eq!(clean.noise_sd_m, TlsOptions::default().noise_sd_m);
    /// ```
    pub fn clean() -> Self {
        TlsOptions {
            points_per_m2: 1000.0,
            occlusion: false,
            ..TlsOptions::default()
        }
    }
}

/// Simulates a co-registered terrestrial scan of `tree`.
///
/// The cloud's offset is the tree's anchor origin, so absolute coordinates
/// are those of the tree. Deterministic for a given `seed`. Non-finite or
/// negative densities and noise are treated as 0; at most
/// [`MAX_TLS_POINTS`] points are produced.
///
/// ```
/// use glam::DVec3;
/// use silva::Anchor;
/// use silva::synth::{Species, TlsOptions, TreeParams, generate, simulate_tls};
///
/// let tree = generate(&TreeParams::preset(Species::Pine), 3, Anchor::at(DVec3::ZERO));
/// let cloud = simulate_tls(&tree, &TlsOptions::default(), 3);
/// assert!(cloud.len() > 5_000);
/// ```
pub fn simulate_tls(tree: &Skeleton, opts: &TlsOptions, seed: u64) -> PointCloud {
    let mut rng = seeded(seed, Stream::Tls);
    let frustums = Frustum::of_skeleton(tree);
    let boxes: Vec<_> = frustums.iter().map(Frustum::bounds).collect();
    let grid = Grid::build(&boxes, GRID_CELL_M);
    let scanners = scanner_positions(tree, &opts.scanners, &mut rng);
    let density = non_negative(opts.points_per_m2);
    let noise_sd = non_negative(opts.noise_sd_m);
    let scene = Scene {
        frustums: &frustums,
        grid: &grid,
    };
    let mut points = Vec::new();
    'all: for (i, f) in frustums.iter().enumerate() {
        let expected = f.lateral_area_m2() * density;
        let count = (expected + unit(&mut rng)).floor() as usize;
        for _ in 0..count {
            if points.len() >= MAX_TLS_POINTS {
                break 'all;
            }
            let (p, normal) = sample_surface(f, &mut rng);
            if scene.buried(p, i) {
                continue;
            }
            if opts.occlusion && !scanners.iter().any(|&s| scene.visible(p, normal, i, s)) {
                continue;
            }
            points.push(p + gaussian_vec(&mut rng, noise_sd));
        }
    }
    if let Some(ground) = opts.ground {
        // A stream of its own, so the bark points are those of the scan
        // without ground.
        let mut rng = seeded(seed, Stream::TlsGround);
        let room = MAX_TLS_POINTS.saturating_sub(points.len());
        let up = (-ground.slope).extend(1.0).normalize_or(Vec3::Z);
        let seen = |p: Vec3| {
            !scene.buried(p, usize::MAX)
                && (!opts.occlusion
                    || scanners
                        .iter()
                        .any(|&s| scene.visible(p, up, usize::MAX, s)))
        };
        let on_ground = sample_ground(&ground, density, &mut rng);
        for p in on_ground.into_iter().filter(|&p| seen(p)).take(room) {
            points.push(p + gaussian_vec(&mut rng, noise_sd));
        }
    }
    PointCloud::from_points(tree.anchor().origin, points)
}

/// Uniform points on the ground disc at `density` points/m².
fn sample_ground(ground: &TlsGround, density: f32, rng: &mut ChaCha8Rng) -> Vec<Vec3> {
    let radius = non_negative(ground.radius_m).min(1_000.0);
    let slope = if ground.slope.is_finite() {
        ground.slope
    } else {
        glam::Vec2::ZERO
    };
    let expected = std::f32::consts::PI * radius * radius * density;
    let count = (expected.min(MAX_TLS_POINTS as f32) + unit(rng)).floor() as usize;
    (0..count)
        .map(|_| {
            let r = radius * unit(rng).sqrt();
            let (s, c) = libm::sincosf(std::f32::consts::TAU * unit(rng));
            let xy = glam::Vec2::new(r * c, r * s);
            xy.extend(slope.dot(xy))
        })
        .collect()
}

fn non_negative(x: f32) -> f32 {
    if x.is_finite() { x.max(0.0) } else { 0.0 }
}

/// A uniform point on the lateral surface of `f` and the outward normal there.
fn sample_surface(f: &Frustum, rng: &mut ChaCha8Rng) -> (Vec3, Vec3) {
    // The area element grows with the radius, so the axial fraction has the
    // linear density ∝ r(t); invert its CDF.
    let (ra, rb) = (f.radius_a_m, f.radius_b_m);
    let u = unit(rng);
    let t = if (ra - rb).abs() < 1e-6 * (ra + rb).max(1e-9) {
        u
    } else {
        let total = 0.5 * (ra + rb);
        // Solve ra·t + (rb − ra)·t²/2 = u·total for t in [0, 1].
        let (a, b, c) = (0.5 * (rb - ra), ra, -u * total);
        ((-b + (b * b - 4.0 * a * c).max(0.0).sqrt()) / (2.0 * a)).clamp(0.0, 1.0)
    };
    let e1 = any_perpendicular(f.axis);
    let e2 = f.axis.cross(e1);
    let angle = std::f32::consts::TAU * unit(rng);
    let (s, c) = libm::sincosf(angle);
    let normal = e1 * c + e2 * s;
    (f.a + (f.b - f.a) * t + normal * f.radius_at(t), normal)
}

struct Scene<'a> {
    frustums: &'a [Frustum],
    grid: &'a Grid,
}

impl Scene<'_> {
    /// True when `p` (on internode `own`) lies inside another internode.
    fn buried(&self, p: Vec3, own: usize) -> bool {
        self.grid
            .items_at(p)
            .iter()
            .any(|&j| j as usize != own && self.frustums[j as usize].contains(p))
    }

    /// True when the scanner at `s` sees `p`, whose outward normal is
    /// `normal`: it faces the scanner and no other internode is in between.
    fn visible(&self, p: Vec3, normal: Vec3, own: usize, s: Vec3) -> bool {
        let to_scanner = s - p;
        if normal.dot(to_scanner) <= 0.0 {
            return false;
        }
        let dist = to_scanner.length();
        let dir = -to_scanner / dist;
        // Stop 1 cm short of the point: its own surface is not an obstacle.
        let t_max = dist - 0.01;
        let mut blocked = false;
        self.grid.traverse(s, dir, t_max, |ids| {
            blocked = ids.iter().any(|&j| {
                j as usize != own
                    && self.frustums[j as usize]
                        .ray_hit(s, dir, 0.0, t_max)
                        .is_some()
            });
            if blocked {
                ControlFlow::Break(())
            } else {
                ControlFlow::Continue(())
            }
        });
        !blocked
    }
}

/// Absolute scanner positions (relative to the anchor) for a placement.
fn scanner_positions(
    tree: &Skeleton,
    placement: &ScannerPlacement,
    rng: &mut ChaCha8Rng,
) -> Vec<Vec3> {
    match placement {
        ScannerPlacement::At(positions) => positions
            .iter()
            .copied()
            .filter(|p| p.is_finite())
            .collect(),
        ScannerPlacement::Ring {
            count,
            distance_m,
            height_m,
        } => {
            let crown = crown_radius_m(tree);
            let distance = distance_m
                .filter(|d| d.is_finite() && *d > 0.0)
                .unwrap_or(crown + 5.0);
            let height = if height_m.is_finite() { *height_m } else { 1.5 };
            let count = (*count).min(64);
            let start = std::f32::consts::TAU * unit(rng);
            (0..count)
                .map(|k| {
                    let (s, c) =
                        libm::sincosf(start + std::f32::consts::TAU * k as f32 / count as f32);
                    Vec3::new(distance * c, distance * s, height)
                })
                .collect()
        }
    }
}

/// Largest horizontal distance of a node from the trunk base, in metres.
pub(crate) fn crown_radius_m(tree: &Skeleton) -> f32 {
    tree.nodes()
        .iter()
        .map(|n| n.position.truncate().length())
        .fold(0.0, f32::max)
}

#[cfg(test)]
mod tests {
    use glam::{DVec3, Vec2};

    use super::*;
    use crate::synth::{Species, TreeParams, generate};

    /// The ground comes after the bark, from a stream of its own: the bark
    /// points are those of the scan without ground, and the ground points
    /// lie on the sloped plane through the base, in the disc, and not
    /// inside the stem.
    #[test]
    fn ground_is_added_on_its_plane_and_leaves_the_bark_alone() {
        let tree = generate(
            &TreeParams::preset(Species::Birch),
            2,
            crate::Anchor::at(DVec3::ZERO),
        );
        let alone = simulate_tls(&tree, &TlsOptions::default(), 2);
        let rise = 0.3;
        let opts = TlsOptions {
            ground: Some(TlsGround {
                radius_m: 5.0,
                slope: Vec2::new(rise, 0.0),
            }),
            noise_sd_m: 0.0,
            ..TlsOptions::default()
        };
        let plot = simulate_tls(&tree, &opts, 2);
        let bare = simulate_tls(
            &tree,
            &TlsOptions {
                noise_sd_m: 0.0,
                ..TlsOptions::default()
            },
            2,
        );
        assert_eq!(&plot.points[..bare.len()], &bare.points[..]);
        assert_eq!(alone.len(), bare.len());
        let ground = &plot.points[bare.len()..];
        // π·5²·150 ≈ 11,800 points, less the stem's shadow.
        assert!(ground.len() > 9_000, "{} ground points", ground.len());
        for p in ground {
            assert!((p.z - rise * p.x).abs() < 1e-4, "{p} off the plane");
            assert!(p.truncate().length() <= 5.0 + 1e-4, "{p} outside the disc");
        }
        // Downhill of the base the ground lies below the synthetic stem,
        // which starts at the base's height; uphill the stem buries it.
        let stem = tree.radius(crate::NodeId::ROOT);
        let inside = ground
            .iter()
            .filter(|p| p.z > 0.0 && p.truncate().length() < 0.9 * stem);
        assert_eq!(inside.count(), 0, "ground inside the stem");
    }
}
