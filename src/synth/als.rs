//! Airborne laser scan simulator: an AHN3-like clip around a known tree.
//!
//! AHN3 (the Dutch national height model) records about 10–30 returns per m²
//! in total. Over a tree most first returns come from the crown, pulses that
//! get through produce later returns on branches, rarely the trunk, and the
//! ground around the tree fills the rest of the clip. Here pulses come from
//! above at a random scan angle of up to ± `max_scan_angle_deg` across a
//! flight line. Each pulse walks its ray through a uniform grid and meets, in
//! order of distance:
//!
//! - foliage: balls around the twig clusters (nodes thinner than
//!   [`Foliage::twig_radius_max_m`]), which intercept the pulse with the
//!   Beer–Lambert probability `1 − exp(−k · chord)`: leaves, or only the
//!   fine twigs of a bare deciduous crown ([`Leaves`],
//!   [`Foliage::for_species`]);
//! - wood: the internode frustums, solid;
//! - the ground: a plane through the trunk base (optionally sloped).
//!
//! Phenology ([`Leaves`]): AHN is flown leaf-off, in winter and early
//! spring. A leaf-off deciduous crown keeps only its fine twigs
//! ([`Foliage::bare_twigs`]); conifers keep their needles. The AHN3 Delft
//! clip (2,488 returns, a 10 m deciduous tree, ground removed) has half its
//! returns in the lower half of the tree, only 13 % in the top fifth, and
//! returns on the stem below the crown; leaf-on simulations put 8–25 % in
//! the lower half and none on the stem, leaf-off ones 19–37 % and a few
//! stem returns (oak, birch, poplar, seeds 101–102). Leaf-on stays
//! available for summer surveys.
//!
//! After a return the pulse goes on with a probability that depends on how
//! much of its footprint the target covered, up to `max_returns`, and only
//! targets at least `min_separation_m` apart are resolved, as with a real
//! full-waveform-less scanner. Pulses are fired over the clip enlarged by the
//! lateral shift of oblique rays, and returns are kept if they fall inside
//! the clip, exactly as cutting a clip out of a national scan; firing stops
//! when the clip holds `density × area` returns, so the measured density is
//! the requested one.

use glam::{Vec2, Vec3};
use rand_chacha::ChaCha8Rng;

use super::Species;
use super::geometry::{Frustum, Grid, Sphere};
use super::random::{Stream, gaussian, seeded, unit};
use super::tls::crown_radius_m;
use crate::cloud::{CLASS_GROUND, PointCloud};
use crate::skeleton::Skeleton;

/// Grid cell for pulse rays, in metres.
const GRID_CELL_M: f32 = 0.5;

/// Most returns a simulated scan produces; higher densities are capped.
pub const MAX_ALS_POINTS: usize = 20_000_000;

/// ASPRS class for unclassified points when ground classification is asked.
const CLASS_UNCLASSIFIED: u8 = 1;

/// The foliage model: leaves and fine twigs that the skeleton does not hold.
#[derive(Debug, Clone, PartialEq)]
pub struct Foliage {
    /// Nodes at most this thick carry a foliage ball, in metres.
    pub twig_radius_max_m: f32,
    /// Radius of the ball around each twig node, in metres.
    pub cluster_radius_m: f32,
    /// Beer–Lambert extinction per metre of path through foliage; 0 for a
    /// leaf-off tree (wood only).
    pub extinction_per_m: f32,
}

impl Default for Foliage {
    fn default() -> Self {
        Foliage {
            twig_radius_max_m: 0.02,
            cluster_radius_m: 0.6,
            extinction_per_m: 0.8,
        }
    }
}

/// The crowns' leaf state at scan time (phenology).
///
/// AHN, the national height model the airborne pipeline targets, is flown
/// leaf-off, in winter and early spring; a summer survey sees leaf-on
/// crowns. Conifers keep their needles in both.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Leaves {
    /// Summer: deciduous crowns in full leaf.
    On,
    /// Winter and early spring, as AHN is flown: deciduous crowns bare.
    #[default]
    Off,
}

impl Foliage {
    /// A bare deciduous crown: no leaves, only the fine twigs that the
    /// skeleton does not hold. They stay within 0.3 m of the twig nodes
    /// and intercept a quarter of what the leafy crown does (extinction
    /// 0.2 instead of 0.8 per metre): the woody area of a bare broadleaf
    /// crown is about a fifth to a third of its leaf-on plant area. The
    /// same pulses therefore reach the limbs and the stem, as the AHN3
    /// leaf-off clips show (returns all through the crown depth and on the
    /// stem, not only on the top of the crown).
    pub fn bare_twigs() -> Self {
        Foliage {
            twig_radius_max_m: 0.02,
            cluster_radius_m: 0.3,
            extinction_per_m: 0.2,
        }
    }

    /// The foliage of `species` in `leaves` state: conifers keep their
    /// needles ([`Foliage::default`]) all year, deciduous trees have
    /// [`Foliage::bare_twigs`] when leaf-off.
    ///
    /// ```
    /// use silva::synth::{Foliage, Leaves, Species};
    ///
    /// assert_eq!(Foliage::for_species(Species::Pine, Leaves::Off), Foliage::default());
    /// assert_eq!(Foliage::for_species(Species::Oak, Leaves::Off), Foliage::bare_twigs());
    /// assert_eq!(Foliage::for_species(Species::Oak, Leaves::On), Foliage::default());
    /// ```
    pub fn for_species(species: Species, leaves: Leaves) -> Self {
        match (species.is_deciduous(), leaves) {
            (true, Leaves::Off) => Foliage::bare_twigs(),
            _ => Foliage::default(),
        }
    }

    /// Height of the tree's top above its root with this foliage on: the
    /// top of the highest foliage ball, or the highest node when that is
    /// higher or the tree is leaf-off. An airborne scan of a leafy crown
    /// samples the leaves, so this, not the highest twig, is the height a
    /// reconstruction should find.
    ///
    /// ```
    /// use glam::{DVec3, Vec3};
    /// use silva::synth::Foliage;
    /// use silva::{Anchor, NodeId, Skeleton};
    ///
    /// let mut tree = Skeleton::new(Anchor::at(DVec3::ZERO), 0.2);
    /// tree.add_child(NodeId::ROOT, Vec3::new(0.0, 0.0, 10.0), 0.01);
    /// assert_eq!(Foliage::default().top_height_m(&tree), 10.6);
    /// let leaf_off = Foliage { extinction_per_m: 0.0, ..Foliage::default() };
    /// assert_eq!(leaf_off.top_height_m(&tree), 10.0);
    /// ```
    pub fn top_height_m(&self, tree: &Skeleton) -> f32 {
        let base = tree.position(crate::NodeId::ROOT).z;
        let leafy = self.extinction_per_m > 0.0 && self.cluster_radius_m > 0.0;
        tree.ids()
            .map(|id| {
                let z = tree.position(id).z - base;
                let carries_leaves = id.index() > 0 && tree.radius(id) <= self.twig_radius_max_m;
                if leafy && carries_leaves {
                    z + self.cluster_radius_m.min(10.0)
                } else {
                    z
                }
            })
            .fold(0.0, f32::max)
    }
}

/// Options of [`simulate_als`].
#[derive(Debug, Clone, PartialEq)]
pub struct AlsOptions {
    /// Returns per m² of clip area, all returns counted (AHN3: 10–30).
    pub density_pts_per_m2: f32,
    /// Half-width of the square clip around the trunk, in metres; `None`:
    /// the crown radius plus 3 m.
    pub clip_radius_m: Option<f32>,
    /// Keep the ground returns. Without them the cloud is the same scan with
    /// the ground points removed (the density then counts them too).
    pub ground: bool,
    /// Set ASPRS classes: 2 on ground returns, 1 elsewhere. Off: no
    /// classification, as an unclassified clip.
    pub classify_ground: bool,
    /// Standard deviation of the Gaussian range noise, in metres.
    pub noise_sd_m: f32,
    /// Largest off-nadir scan angle, in degrees.
    pub max_scan_angle_deg: f32,
    /// Most returns per pulse (1: first returns only).
    pub max_returns: u8,
    /// Smallest range difference at which two targets give two returns, m.
    pub min_separation_m: f32,
    /// Laser footprint diameter on the target, in metres.
    pub footprint_m: f32,
    /// Ground slope `(dz/dx, dz/dy)` of the plane through the trunk base.
    pub ground_slope: Vec2,
    /// Foliage model.
    pub foliage: Foliage,
}

impl Default for AlsOptions {
    /// AHN3-like: 20 returns/m², ±12° scan angle, up to 4 returns, 5 cm noise,
    /// flat ground, unclassified.
    fn default() -> Self {
        AlsOptions {
            density_pts_per_m2: 20.0,
            clip_radius_m: None,
            ground: true,
            classify_ground: false,
            noise_sd_m: 0.05,
            max_scan_angle_deg: 12.0,
            max_returns: 4,
            min_separation_m: 1.0,
            footprint_m: 0.25,
            ground_slope: Vec2::ZERO,
            foliage: Foliage::default(),
        }
    }
}

impl AlsOptions {
    /// Half-width of the square clip around `tree`'s trunk base, in metres:
    /// `clip_radius_m`, or the crown radius plus 3 m, at most 1 km. The clip
    /// area is the square of twice this.
    pub fn clip_half_width_m(&self, tree: &Skeleton) -> f32 {
        self.clip_radius_m
            .filter(|r| r.is_finite() && *r > 0.0)
            .unwrap_or_else(|| crown_radius_m(tree) + 3.0)
            .min(1_000.0)
    }
}

/// What a return came from.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Target {
    Foliage,
    Wood { radius_m: f32 },
    Ground,
}

/// One possible return along a pulse.
#[derive(Debug, Clone, Copy)]
struct Event {
    t: f32,
    target: Target,
}

/// Simulates an airborne scan of `tree` over a square clip around it.
///
/// The cloud's offset is the tree's anchor origin. Every point carries its
/// return number and an intensity; classification only with
/// `classify_ground`. Deterministic for a given `seed`. A non-finite or
/// non-positive density gives an empty cloud; at most [`MAX_ALS_POINTS`]
/// returns are produced.
///
/// ```
/// use glam::DVec3;
/// use silva::Anchor;
/// use silva::synth::{AlsOptions, Species, TreeParams, generate, simulate_als};
///
/// let tree = generate(&TreeParams::preset(Species::Oak), 7, Anchor::at(DVec3::ZERO));
/// let opts = AlsOptions { clip_radius_m: Some(10.0), ..AlsOptions::default() };
/// let cloud = simulate_als(&tree, &opts, 7);
/// let density = cloud.len() as f32 / (20.0 * 20.0);
/// assert!((density - 20.0).abs() < 1.0);
/// ```
pub fn simulate_als(tree: &Skeleton, opts: &AlsOptions, seed: u64) -> PointCloud {
    let mut rng = seeded(seed, Stream::Als);
    let mut scene = AlsScene::new(tree, opts);
    let half = opts.clip_half_width_m(tree);
    let density = if opts.density_pts_per_m2.is_finite() {
        opts.density_pts_per_m2.max(0.0)
    } else {
        0.0
    };
    let target = ((density * 4.0 * half * half).round() as usize).min(MAX_ALS_POINTS);
    let max_angle = finite_or(opts.max_scan_angle_deg, 0.0)
        .clamp(0.0, 30.0)
        .to_radians();
    let heading = std::f32::consts::TAU * unit(&mut rng);
    let across = Vec3::new(libm::cosf(heading), libm::sinf(heading), 0.0);
    // Oblique rays hit the crown up to this far from their ground point.
    let reach = half + libm::tanf(max_angle) * (scene.top_z + 1.0);
    let mut out = Returns::default();
    let mut kept = 0usize;
    // Every pulse whose ground point is in the clip gives at least a ground
    // return there, so this bound is never reached with sane options; it
    // only guarantees termination.
    let max_pulses = target.saturating_mul(50).saturating_add(1_000);
    let mut pulses = 0usize;
    while kept < target && pulses < max_pulses {
        pulses += 1;
        let ground_xy = Vec2::new(
            reach * (2.0 * unit(&mut rng) - 1.0),
            reach * (2.0 * unit(&mut rng) - 1.0),
        );
        let angle = max_angle * (2.0 * unit(&mut rng) - 1.0);
        let (s, c) = libm::sincosf(angle);
        let dir = across * s - Vec3::Z * c;
        let ground = ground_xy.extend(opts.ground_slope.dot(ground_xy));
        let range = (scene.top_z + 5.0 - ground.z).max(1.0) / c;
        let origin = ground - dir * range;
        for (k, (t, target_kind)) in scene
            .pulse(origin, dir, range + 1.0, opts, &mut rng)
            .into_iter()
            .enumerate()
        {
            let noise = gaussian(&mut rng) * finite_or(opts.noise_sd_m, 0.0).max(0.0);
            let p = origin + dir * (t + noise);
            if p.x.abs() > half || p.y.abs() > half {
                continue;
            }
            kept += 1;
            out.push(p, k as u8 + 1, target_kind, &mut rng);
            if kept >= target {
                break;
            }
        }
    }
    out.into_cloud(tree, opts)
}

fn finite_or(x: f32, fallback: f32) -> f32 {
    if x.is_finite() { x } else { fallback }
}

/// The solids and foliage of one tree, in a grid.
struct AlsScene {
    frustums: Vec<Frustum>,
    spheres: Vec<Sphere>,
    grid: Grid,
    extinction: f32,
    top_z: f32,
    /// Per-primitive number of the last pulse that tested it, so that a
    /// primitive spanning several cells is tested once per pulse.
    stamp: Vec<u32>,
    pulse_no: u32,
}

impl AlsScene {
    fn new(tree: &Skeleton, opts: &AlsOptions) -> Self {
        let frustums = Frustum::of_skeleton(tree);
        let f = &opts.foliage;
        let extinction = finite_or(f.extinction_per_m, 0.0).max(0.0);
        let radius = finite_or(f.cluster_radius_m, 0.0).clamp(0.0, 10.0);
        let spheres: Vec<Sphere> = if extinction > 0.0 && radius > 0.0 {
            tree.ids()
                .filter(|&id| id.index() > 0 && tree.radius(id) <= f.twig_radius_max_m)
                .map(|id| Sphere {
                    centre: tree.position(id),
                    radius_m: radius,
                })
                .collect()
        } else {
            Vec::new()
        };
        let boxes: Vec<_> = frustums
            .iter()
            .map(Frustum::bounds)
            .chain(spheres.iter().map(Sphere::bounds))
            .collect();
        let top_z = boxes.iter().map(|b| b.1.z).fold(0.0, f32::max);
        let grid = Grid::build(&boxes, GRID_CELL_M);
        AlsScene {
            stamp: vec![0; boxes.len()],
            pulse_no: 0,
            frustums,
            spheres,
            grid,
            extinction,
            top_z,
        }
    }

    /// The returns of one pulse: `(range, target)` in order of range.
    fn pulse(
        &mut self,
        origin: Vec3,
        dir: Vec3,
        t_max: f32,
        opts: &AlsOptions,
        rng: &mut ChaCha8Rng,
    ) -> Vec<(f32, Target)> {
        let mut events = self.events(origin, dir, t_max, rng);
        if dir.z < 0.0 {
            // The ground plane z = slope · xy along the ray.
            let slope = opts.ground_slope;
            let rate = dir.z - slope.dot(dir.truncate());
            let t = (slope.dot(origin.truncate()) - origin.z) / rate;
            if t > 0.0 && rate < 0.0 {
                events.push(Event {
                    t,
                    target: Target::Ground,
                });
            }
        }
        events.sort_by(|a, b| a.t.total_cmp(&b.t));
        let footprint = finite_or(opts.footprint_m, 0.25).max(0.01);
        let min_sep = finite_or(opts.min_separation_m, 1.0).max(0.0);
        let mut returns: Vec<(f32, Target)> = Vec::new();
        for e in events {
            if returns.len() >= usize::from(opts.max_returns.max(1)) {
                break;
            }
            if returns.last().is_some_and(|&(t, _)| e.t - t < min_sep) {
                continue;
            }
            returns.push((e.t, e.target));
            let go_on = match e.target {
                Target::Ground => 0.0,
                // Leaves fill part of the footprint; the rest goes on.
                Target::Foliage => 0.5,
                Target::Wood { radius_m } => (1.0 - 2.0 * radius_m / footprint).clamp(0.0, 0.8),
            };
            if unit(rng) >= go_on {
                break;
            }
        }
        returns
    }

    /// Candidate targets along the ray (ground excluded), unsorted.
    fn events(&mut self, origin: Vec3, dir: Vec3, t_max: f32, rng: &mut ChaCha8Rng) -> Vec<Event> {
        self.pulse_no = self.pulse_no.wrapping_add(1);
        if self.pulse_no == 0 {
            // Wrapped after 2^32 pulses: old stamps could collide.
            self.stamp.fill(0);
            self.pulse_no = 1;
        }
        let pulse_stamp = self.pulse_no;
        let n_frustums = self.frustums.len();
        let mut events = Vec::new();
        let (frustums, spheres, stamp, extinction) = (
            &self.frustums,
            &self.spheres,
            &mut self.stamp,
            self.extinction,
        );
        self.grid.traverse(origin, dir, t_max, |ids| {
            for &id in ids {
                let id = id as usize;
                if stamp[id] == pulse_stamp {
                    continue;
                }
                stamp[id] = pulse_stamp;
                if id < n_frustums {
                    let f = &frustums[id];
                    if let Some(t) = f.ray_hit(origin, dir, 0.0, t_max) {
                        events.push(Event {
                            t,
                            target: Target::Wood {
                                radius_m: 0.5 * (f.radius_a_m + f.radius_b_m),
                            },
                        });
                    }
                } else if let Some((t0, t1)) = spheres[id - n_frustums].chord(origin, dir) {
                    // Free path through the ball: exponential with rate k.
                    let free = -libm::logf(1.0 - unit(rng)) / extinction;
                    if t0 + free < t1 {
                        events.push(Event {
                            t: t0 + free,
                            target: Target::Foliage,
                        });
                    }
                }
            }
            std::ops::ControlFlow::Continue(())
        });
        events
    }
}

/// Returns gathered so far, with their attributes.
#[derive(Default)]
struct Returns {
    points: Vec<Vec3>,
    return_number: Vec<u8>,
    intensity: Vec<u16>,
    ground: Vec<bool>,
}

impl Returns {
    fn push(&mut self, p: Vec3, return_number: u8, target: Target, rng: &mut ChaCha8Rng) {
        // A rough radiometric model: bright ground, darker bark, dark leaves,
        // and later returns weaker because the pulse energy is shared.
        let base = match target {
            Target::Ground => 1400.0,
            Target::Wood { .. } => 900.0,
            Target::Foliage => 500.0,
        };
        let value = base / f32::from(return_number) * (0.8 + 0.4 * unit(rng));
        self.points.push(p);
        self.return_number.push(return_number);
        self.intensity.push(value as u16);
        self.ground.push(target == Target::Ground);
    }

    fn into_cloud(self, tree: &Skeleton, opts: &AlsOptions) -> PointCloud {
        let keep: Vec<usize> = (0..self.points.len())
            .filter(|&i| opts.ground || !self.ground[i])
            .collect();
        let classification = opts.classify_ground.then(|| {
            keep.iter()
                .map(|&i| {
                    if self.ground[i] {
                        CLASS_GROUND
                    } else {
                        CLASS_UNCLASSIFIED
                    }
                })
                .collect()
        });
        PointCloud {
            offset: tree.anchor().origin,
            points: keep.iter().map(|&i| self.points[i]).collect(),
            intensity: Some(keep.iter().map(|&i| self.intensity[i]).collect()),
            return_number: Some(keep.iter().map(|&i| self.return_number[i]).collect()),
            classification,
        }
    }
}
