//! Ground separation: which points of a clip are terrain, and how high the
//! terrain is under the tree.
//!
//! Airborne clips (an AHN tile cut around one tree) hold the tree *and* the
//! ground around it. Ground points must stay out of the skeleton and out of
//! any trunk fit (AdTree's DBH is off by metres because they enter its trunk
//! fit), and the terrain height under the trunk is the trunk base, which
//! tree height and trunk insertion (Hu et al. §4.2, the ground plane of
//! Eq. 3/4) are measured from.
//!
//! Two methods, chosen per cloud:
//! - **Classification**: the cloud carries ASPRS classes and has class 2
//!   points; those are the ground.
//! - **Geometry**: a grid of lowest points. Each 1 m cell's lowest point is a
//!   terrain candidate; a plane is fitted to the candidates with iteratively
//!   tightened residual limits, so cells under the crown whose lowest point
//!   is a branch, and isolated below-ground noise, drop out. The fit starts
//!   from the lowest half of the cells, and from the lowest quarter and
//!   eighth when that finds no ground: a plot scan may hold only a patch of
//!   ground around the stem of a broad tree. The fitted plane handles
//!   sloped terrain; the inlier cells' residuals refine it locally. Points
//!   less than [`GROUND_TOLERANCE_M`] above the surface (or far below it,
//!   which is noise) are ground.
//!
//! When no surface covers enough of the clip or holds enough open ground
//! (an already segmented tree, a terrestrial scan), the method is
//! [`GroundMethod::None`] and every point is kept as tree.

use foldhash::{HashMap, HashMapExt};

use glam::{DMat3, DVec3, Vec2};

use crate::cloud::{CLASS_GROUND, PointCloud};

/// Height above the fitted terrain below which a point counts as ground, in
/// metres. AHN3's vertical noise is about 5 cm and grass or kerbs add some
/// decimetres; 0.4 m sits inside the 0.3–0.5 m band that separates ground
/// from the lowest trunk hits.
pub const GROUND_TOLERANCE_M: f32 = 0.4;

/// Points this far below the terrain are noise (multipath, birds' shadows in
/// the return sequence); they are put with the ground so that they never
/// reach the skeleton.
pub(crate) const BELOW_GROUND_NOISE_M: f32 = 1.0;

/// Side of a terrain grid cell in metres: at 10–30 pts/m² a cell holds a
/// dozen points, enough for one to be a ground return where the crown lets
/// light through.
const CELL_M: f32 = 1.0;

/// Successive residual limits (m) of the robust plane fit: wide first so that
/// a tilted start plane does not lose real ground, tight at the end.
const RESIDUAL_LIMITS_M: [f64; 4] = [2.0, 1.0, 0.5, 0.3];

/// Most refits at the last of [`RESIDUAL_LIMITS_M`] until the inliers stop
/// changing ([`fit_robust_plane`]). Each limit's inliers are taken about the
/// plane of the limit before, so a plane that the seed tilted can straighten
/// at the last limit and still keep only the cells its tilted predecessor
/// agreed with: two oaks 6 m apart on one level plot (`silva synth --species
/// oak --seed 1065` and `1066 --scan tls --ground-radius 4`, the second
/// moved 6 m along x) seeded a plane tilted 13° by the underside of one
/// crown; it came level at 0.3 m, but kept 27 cells of the 118 whose lowest
/// return lies on the ground, all under the first oak. One more refit keeps
/// all 118.
///
/// Counted over every plane fit of `silva eval --repeat 1` (2026-12-07,
/// release; several fits per tree) with `--synthetic 100 --scan als`, the
/// same `--ground-slope 15 --seed 901`, `--synthetic 100 --scan tls
/// --ground-radius 4`, the same `--ground-radius 6 --ground-slope 20 --seed
/// 101`, and `--data /work/shared/data`: 146 of 215, 139 of 208, 272 of
/// 508, 269 of 387 and 39 of 80 fits were settled already (the inliers
/// about the last plane are the ones it was fitted to), the others after 1
/// to 7 more refits, except 0, 2, 2, 5 and 0 still swapping cells after 8,
/// which keep the eighth. Every figure of those reports, and of `silva eval`
/// on seeds 101–200 and at 2, 5 and 10 returns per m², leaf-on, and on TLS
/// plots of 5 and 8 m, stayed the same but one oak's (`--ground-radius 4`,
/// seed 85: one node fewer, its height 6 mm nearer the truth).
const SETTLING_ROUNDS: usize = 8;

/// Shares of the grid cells, lowest first, that seed the terrain's plane
/// fit ([`fit_robust_plane`]), tried in turn until one gives ground. The
/// lower half suits a clip with ground all round. A terrestrial plot scan
/// of a broad tree may hold ground under a fraction of its cells: in `silva
/// synth --species oak --seed 1 --scan tls --ground-radius 4` the 4 m disc
/// is the lowest point of 66 of 238 occupied cells, and the plane seeded by
/// the lower half of the cells ran up into the crown (33°, through 7
/// cells); the disc stayed in the tree, and the skeleton's precision at
/// 10 cm was 0.884 (0.943 with the disc found).
const SEED_SHARES: [f64; 3] = [0.5, 0.25, 0.125];

/// Fewest points for a cell to count as bare ground (AHN3 puts 10–30 in a
/// 1 m cell of open ground).
const BARE_CELL_MIN_POINTS: u32 = 5;

/// Clear air (m) a cell needs above its ground layer to count as open
/// ground ([`count_bare_cells`]): more than the layer of grass, litter and
/// noise the ground tolerance takes in, less than the height of the
/// lowest branches over a plot.
const BARE_CLEARANCE_M: f64 = 1.0;

/// Share of occupied grid cells that must agree with the fitted surface for
/// it to be accepted as terrain. Around a tree most cells see ground; a
/// segmented tree without ground has only its trunk cell near its lowest
/// level.
const MIN_GROUND_CELL_SHARE: f64 = 0.25;

/// Open cells ([`count_bare_cells`], 1 m² each) that make a surface ground
/// whatever share of the clip it covers. A terrestrial plot scan of a broad
/// tree may hold only a patch of ground around the stem: `silva synth
/// --species oak --seed 1 --scan tls --ground-radius 3` has ground as the
/// lowest point of 38 of its 235 occupied cells (16 %), 32 of them open;
/// turned 45° about x, the 4 m disc of `--ground-radius 4` has 50 of 281
/// (45 open). Twenty open square metres is a disc of 2.5 m radius; the
/// underside of a crown has next to no open cells (it always has more of
/// the crown right above its lowest points), and a segmented tree's cut
/// base one or two.
const MIN_OPEN_GROUND_CELLS: usize = 20;

/// Largest share of the points that may lie more than
/// [`BELOW_GROUND_NOISE_M`] below a surface for it to be the ground: a few
/// below-ground returns are noise, but the tree stands on its ground, so a
/// surface with a trunk under it is the underside of a crown (a birch's
/// drooping twig ends 4–5 m up, around a bare stem, look like open ground).
const MAX_BELOW_GROUND_SHARE: f64 = 0.01;

/// Terrain slope (degrees) from which [`GroundSplit::steep_note`] warns of
/// a tilted cloud. Synthetic AHN-like clips on level ground fit 0°; turned
/// by 20–45° about a horizontal axis, their terrain fits at the turn's
/// angle (`tests/reconstruct_airborne.rs`). Real ground can be this steep
/// (a dike's face at 1:3 is 18°), hence a note and not an error.
pub const STEEP_TERRAIN_DEG: f32 = 15.0;

/// How the ground was told apart from the tree.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GroundMethod {
    /// LAS class 2 of the cloud's own classification.
    Classification,
    /// The robust terrain fit described in the module docs.
    Geometry,
    /// No ground found: all points are tree.
    None,
}

/// A terrain surface in the cloud's relative coordinates: a fitted plane,
/// refined per cell by the lowest points that agree with it.
#[derive(Debug, Clone, PartialEq)]
pub struct Terrain {
    /// Plane `z = a·x + b·y + c` (relative metres), as `[a, b, c]`.
    plane: [f64; 3],
    /// Per grid cell with a terrain cell among its 3 × 3: the mean over
    /// those of the ground candidate's height minus the plane
    /// ([`local_means`]).
    residual_m: HashMap<(i32, i32), f32>,
    /// Grid origin (relative x, y of cell (0, 0)'s corner).
    origin: Vec2,
    /// Number of occupied grid cells, and of those that agree with the surface.
    cells: (usize, usize),
    /// Terrain cells that are open ground: enough points in a ground layer
    /// with clear air above it (see [`count_bare_cells`]).
    bare_cells: usize,
    /// Points more than [`BELOW_GROUND_NOISE_M`] below the surface (counted
    /// only when the surface covers open ground), and all the points the
    /// surface was fitted to.
    deep_below: (usize, usize),
    /// As `residual_m`, of each terrain cell's mean height of its ground
    /// returns (those within the ground tolerance of its lowest) minus the
    /// plane (see [`Terrain::surface_at`]).
    surface_m: HashMap<(i32, i32), f32>,
}

impl Terrain {
    /// Terrain height at relative `(x, y)`, in relative metres: the plane,
    /// corrected by the mean residual of the terrain cells around the query.
    pub fn height_at(&self, x: f32, y: f32) -> f32 {
        self.plane_at(x, y) + self.local_mean(&self.residual_m, x, y)
    }

    /// The fitted plane's height at relative `(x, y)`.
    fn plane_at(&self, x: f32, y: f32) -> f32 {
        let [a, b, c] = self.plane;
        (a * f64::from(x) + b * f64::from(y) + c) as f32
    }

    /// The mean of the cell holding `(x, y)` in `means` ([`local_means`]);
    /// 0 when no terrain cell lies around it.
    fn local_mean(&self, means: &HashMap<(i32, i32), f32>, x: f32, y: f32) -> f32 {
        let cell = cell_of(self.origin, x, y);
        means.get(&cell).copied().unwrap_or(0.0)
    }

    /// Height of the ground surface at relative `(x, y)`, in relative
    /// metres: [`Terrain::height_at`] follows each cell's lowest return,
    /// which lies below the surface by up to two standard deviations of the
    /// range noise (the lowest of a dozen returns; 7–9 cm at AHN3's 5 cm),
    /// less where the crown lets fewer returns through; the surface is the
    /// mean of each cell's ground returns instead, unbiased whatever their
    /// number. The trunk base stands on it, so tree height is not measured
    /// from the bottom of the noise.
    pub fn surface_at(&self, x: f32, y: f32) -> f32 {
        self.plane_at(x, y) + self.local_mean(&self.surface_m, x, y)
    }

    /// [`Terrain::surface_at`] where the ground was seen: `None` when no
    /// terrain cell lies within one cell of `(x, y)`, where the surface
    /// would be the plane's extrapolation alone.
    pub fn surface_near(&self, x: f32, y: f32) -> Option<f32> {
        let seen = self.surface_m.contains_key(&cell_of(self.origin, x, y));
        seen.then(|| self.surface_at(x, y))
    }

    /// Slope of the fitted plane in degrees (0 = level).
    pub fn slope_deg(&self) -> f32 {
        let [a, b, _] = self.plane;
        (a.hypot(b)).atan().to_degrees() as f32
    }

    /// Unit normal of the terrain's plane, pointing up.
    pub fn up(&self) -> glam::Vec3 {
        let [a, b, _] = self.plane;
        DVec3::new(-a, -b, 1.0).normalize().as_vec3()
    }

    /// Share of the occupied grid cells whose lowest point is terrain.
    pub fn cell_share(&self) -> f32 {
        let (occupied, terrain) = self.cells;
        terrain as f32 / occupied.max(1) as f32
    }

    /// True when the surface is ground rather than the underside of a
    /// crown: it covers [`MIN_GROUND_CELL_SHARE`] of the clip or holds
    /// [`MIN_OPEN_GROUND_CELLS`] open cells, a quarter of its cells are
    /// bare (open ground around the tree; the bottom layer of a crown always
    /// has foliage above its lowest points), and hardly any points lie far
    /// below it ([`MAX_BELOW_GROUND_SHARE`]).
    pub(crate) fn is_ground(&self) -> bool {
        let (below, points) = self.deep_below;
        self.covers_open_ground() && below as f64 <= MAX_BELOW_GROUND_SHARE * points as f64
    }

    /// The first two conditions of [`Terrain::is_ground`].
    fn covers_open_ground(&self) -> bool {
        let (_, terrain) = self.cells;
        (f64::from(self.cell_share()) >= MIN_GROUND_CELL_SHARE
            || self.bare_cells >= MIN_OPEN_GROUND_CELLS)
            && self.bare_cells >= 3
            && self.bare_cells * 4 >= terrain
    }
}

/// A clip split into tree and ground points.
#[derive(Debug, Clone)]
pub struct GroundSplit {
    /// Points that are not ground (the tree, plus anything else standing on
    /// the terrain), same offset as the input.
    pub tree: PointCloud,
    /// Ground points (and below-ground noise), same offset as the input.
    pub ground: PointCloud,
    /// How ground was identified.
    pub method: GroundMethod,
    /// The terrain surface, when one was found.
    pub terrain: Option<Terrain>,
}

impl GroundSplit {
    /// One line for a reconstruction's notes: how many points were ground,
    /// found how, and the terrain's slope.
    pub fn note(&self) -> String {
        let how = match self.method {
            GroundMethod::Classification => "by LAS class 2",
            GroundMethod::Geometry => "by terrain fit",
            GroundMethod::None => return "ground: none found; all points treated as tree".into(),
        };
        let slope = self
            .terrain
            .as_ref()
            .map(|t| format!(", terrain slope {:.0}°", t.slope_deg()))
            .unwrap_or_default();
        format!("ground: {} points {how}{slope}", self.ground.len())
    }

    /// A note when the terrain is steeper than [`STEEP_TERRAIN_DEG`]:
    /// either the ground really is that steep, or the cloud is tilted, and
    /// the pipelines, which take +z as up, measure height and trunk base
    /// askew. A note and not an error: trees grow on hillsides.
    pub fn steep_note(&self) -> Option<String> {
        let terrain = self.terrain.as_ref()?;
        let slope = terrain.slope_deg();
        (slope >= STEEP_TERRAIN_DEG).then(|| {
            format!(
                "the terrain slopes {slope:.0}°: steep ground, or a tilted cloud. silva takes +z \
                 as up, as in a georeferenced clip; if the cloud is tilted, level it first ({}), \
                 or height and trunk base are measured askew",
                levelling_words(terrain.up())
            )
        })
    }

    /// Terrain height (relative metres) at relative `(x, y)`, when there is
    /// a terrain surface. Under the trunk this is the trunk base.
    pub fn ground_height_at(&self, x: f32, y: f32) -> Option<f32> {
        self.terrain.as_ref().map(|t| t.height_at(x, y))
    }
}

/// The turn that brings the direction `up` to +z, as most point cloud tools
/// take a turn: an angle in degrees about a unit axis, right-handed. The
/// axis is `up × z`, or +x when `up` points straight down.
pub(crate) fn levelling_turn(up: glam::Vec3) -> (f32, glam::Vec3) {
    let up = up.normalize_or(glam::Vec3::Z);
    let degrees = up.dot(glam::Vec3::Z).clamp(-1.0, 1.0).acos().to_degrees();
    let axis = up
        .cross(glam::Vec3::Z)
        .try_normalize()
        .unwrap_or(glam::Vec3::X);
    (degrees, axis)
}

/// [`levelling_turn`] in words ([`as_shown`]): "turn the cloud by 60°
/// about the axis (1.00, 0.00, 0.00)".
pub(crate) fn levelling_words(up: glam::Vec3) -> String {
    let (degrees, axis) = levelling_turn(up);
    let axis = as_shown(axis);
    format!(
        "turn the cloud by {degrees:.0}° about the axis ({:.2}, {:.2}, {:.2})",
        axis.x, axis.y, axis.z
    )
}

/// A direction rounded to the hundredths a note shows, without a sign on a
/// zero (a note should not read "-0.00").
pub(crate) fn as_shown(v: glam::Vec3) -> glam::Vec3 {
    (v * 100.0).round() / 100.0 + glam::Vec3::ZERO
}

/// Splits a cloud into tree and ground points, by LAS class 2 when the cloud
/// has it and by the terrain fit otherwise (see the module docs).
///
/// ```
/// use glam::{DVec3, Vec3};
/// use silva::cloud::PointCloud;
/// use silva::reconstruct::ground::{split_ground, GroundMethod};
///
/// // A 10 m × 10 m patch of flat ground and a 5 m pole in its middle.
/// let mut pts: Vec<Vec3> = (0..1600)
///     .map(|i| Vec3::new((i % 40) as f32 * 0.25, (i / 40) as f32 * 0.25, 0.0))
///     .collect();
/// pts.extend((1..=20).map(|k| Vec3::new(5.1, 5.1, k as f32 * 0.25)));
/// let split = split_ground(&PointCloud::from_points(DVec3::ZERO, pts));
/// assert_eq!(split.method, GroundMethod::Geometry);
/// assert_eq!(split.tree.len(), 19); // the pole above 0.4 m
/// assert!(split.ground_height_at(5.0, 5.0).unwrap().abs() < 0.05);
/// ```
pub fn split_ground(cloud: &PointCloud) -> GroundSplit {
    if let Some(classes) = &cloud.classification {
        if classes.len() == cloud.len() && classes.contains(&CLASS_GROUND) {
            let is_ground: Vec<bool> = classes.iter().map(|&c| c == CLASS_GROUND).collect();
            let ground = cloud.retain_indices(|i| is_ground[i]);
            let terrain = fit_terrain(&ground.points);
            return GroundSplit {
                tree: cloud.retain_indices(|i| !is_ground[i]),
                ground,
                method: GroundMethod::Classification,
                terrain,
            };
        }
    }
    match ground_terrain(&cloud.points) {
        Some(terrain) => {
            let is_ground: Vec<bool> = cloud
                .points
                .iter()
                .map(|p| {
                    let above = p.z - terrain.height_at(p.x, p.y);
                    above < GROUND_TOLERANCE_M || above < -BELOW_GROUND_NOISE_M
                })
                .collect();
            GroundSplit {
                tree: cloud.retain_indices(|i| !is_ground[i]),
                ground: cloud.retain_indices(|i| is_ground[i]),
                method: GroundMethod::Geometry,
                terrain: Some(terrain),
            }
        }
        None => GroundSplit {
            tree: cloud.clone(),
            ground: PointCloud::new(cloud.offset),
            method: GroundMethod::None,
            terrain: None,
        },
    }
}

/// Fits the terrain to the lowest point of each grid cell (module docs).
/// `None` when there are fewer than three cells to fit a plane to.
pub(crate) fn fit_terrain(points: &[glam::Vec3]) -> Option<Terrain> {
    let grid = LowestPoints::of(points)?;
    Some(completed(points, grid.terrain_cells(SEED_SHARES[0])?))
}

/// The first terrain that [`Terrain::is_ground`] accepts, its plane fit
/// seeded by each of [`SEED_SHARES`] in turn. The grid is built once, and
/// a seed whose surface has too few cells to be accepted
/// ([`TerrainCells::may_be_ground`]) costs no pass over the points: a
/// segmented tree, which has no ground, tries all three.
fn ground_terrain(points: &[glam::Vec3]) -> Option<Terrain> {
    let grid = LowestPoints::of(points)?;
    SEED_SHARES.iter().find_map(|&share| {
        let cells = grid.terrain_cells(share)?;
        cells
            .may_be_ground()
            .then(|| completed(points, cells))
            .filter(Terrain::is_ground)
    })
}

/// The terrain on `cells`: its open cells, ground surface and the points
/// far below it, measured over `points`.
fn completed(points: &[glam::Vec3], cells: TerrainCells) -> Terrain {
    let TerrainCells {
        origin,
        occupied,
        plane,
        residual_m,
    } = cells;
    let bare_cells = count_bare_cells(points, origin, plane, &residual_m);
    let surface_m = mean_ground(points, origin, plane, &residual_m);
    let mut terrain = Terrain {
        plane,
        bare_cells,
        deep_below: (0, points.len()),
        surface_m: local_means(&surface_m),
        cells: (occupied, residual_m.len()),
        residual_m: local_means(&residual_m),
        origin,
    };
    // Counted only where it can decide (a pass over every point).
    if terrain.covers_open_ground() {
        terrain.deep_below.0 = points
            .iter()
            .filter(|p| p.z - terrain.height_at(p.x, p.y) < -BELOW_GROUND_NOISE_M)
            .count();
    }
    terrain
}

/// Per cell with a cell of `per_cell` among its 3 × 3, the mean of
/// `per_cell` over those (summed in row order, as one would around each
/// query). Taken once per terrain, so that a height costs one lookup
/// instead of nine: the heights of every point were a tenth of an airborne
/// clip's reconstruction.
fn local_means(per_cell: &HashMap<(i32, i32), f32>) -> HashMap<(i32, i32), f32> {
    let around = |(i, j): (i32, i32)| {
        (-1..=1).flat_map(move |di: i32| {
            (-1..=1).map(move |dj: i32| (i.saturating_add(di), j.saturating_add(dj)))
        })
    };
    let mut means = HashMap::with_capacity(4 * per_cell.len());
    for &cell in per_cell.keys() {
        for query in around(cell) {
            means.entry(query).or_insert_with(|| {
                let (sum, n) = around(query)
                    .filter_map(|c| per_cell.get(&c))
                    .fold((0.0f32, 0u32), |(sum, n), r| (sum + r, n + 1));
                sum / n as f32
            });
        }
    }
    means
}

/// The first steps of [`fit_terrain`]: the plane through the grid cells'
/// lowest points and the largest patch of cells on it.
struct TerrainCells {
    origin: Vec2,
    /// Grid cells that hold a point.
    occupied: usize,
    plane: [f64; 3],
    /// Per terrain cell, its lowest point's height above the plane.
    residual_m: HashMap<(i32, i32), f32>,
}

impl TerrainCells {
    /// False when [`Terrain::covers_open_ground`] must fail whatever the
    /// points above the cells: its open cells are terrain cells.
    fn may_be_ground(&self) -> bool {
        let terrain = self.residual_m.len();
        // As `Terrain::cell_share` computes it, so that the bound is exact.
        let share = terrain as f32 / self.occupied.max(1) as f32;
        terrain >= 3
            && (f64::from(share) >= MIN_GROUND_CELL_SHARE || terrain >= MIN_OPEN_GROUND_CELLS)
    }
}

/// The grid of [`fit_terrain`]: each occupied cell's lowest point, the
/// terrain candidates.
struct LowestPoints {
    origin: Vec2,
    /// Per occupied cell, its lowest point, sorted by cell so that the
    /// plane's sums do not depend on the hash map's order.
    candidates: Vec<((i32, i32), DVec3)>,
}

impl LowestPoints {
    /// `None` when fewer than three cells hold a point.
    fn of(points: &[glam::Vec3]) -> Option<LowestPoints> {
        let origin = points
            .iter()
            .fold(Vec2::splat(f32::INFINITY), |o, p| o.min(p.truncate()));
        let cells = cell_stats(points, origin);
        if cells.len() < 3 {
            return None;
        }
        let mut candidates: Vec<((i32, i32), DVec3)> = cells
            .into_iter()
            .map(|(k, c)| (k, c.low.as_dvec3()))
            .collect();
        candidates.sort_by_key(|(k, _)| *k);
        Some(LowestPoints { origin, candidates })
    }

    /// The plane through the candidates, seeded by their lowest
    /// `seed_share` ([`fit_robust_plane`]), and the largest patch of cells
    /// on it.
    fn terrain_cells(&self, seed_share: f64) -> Option<TerrainCells> {
        let candidates = &self.candidates;
        let (plane, inlier) = fit_robust_plane(candidates, seed_share)?;
        let residual_m: HashMap<(i32, i32), f32> = candidates
            .iter()
            .zip(&inlier)
            .filter(|(_, keep)| **keep)
            .map(|((k, p), _)| (*k, (p.z - eval_plane(plane, *p)) as f32))
            .collect();
        Some(TerrainCells {
            origin: self.origin,
            occupied: candidates.len(),
            plane,
            residual_m: largest_patch(residual_m),
        })
    }
}

/// [`Terrain::cell_share`] of the terrain that [`fit_terrain`] would fit,
/// at a third of its cost (one pass over the points instead of four): an
/// upper bound on the share of a terrain that [`Terrain::is_ground`]
/// accepts, for tests that need ground over most of the cells.
pub(crate) fn terrain_cell_share(points: &[glam::Vec3]) -> f32 {
    let cells = LowestPoints::of(points).and_then(|grid| grid.terrain_cells(SEED_SHARES[0]));
    cells.map_or(0.0, |c| {
        c.residual_m.len() as f32 / c.occupied.max(1) as f32
    })
}

/// The largest 8-connected patch of `cells`: the ground is one surface. An
/// isolated cell whose lowest point happens to lie on the plane's
/// extrapolation is a limb, not ground (a synthetic oak's limb tip 10 m out
/// over a 20° slope, beyond the plot's scanned ground, became the trunk
/// base).
fn largest_patch<V>(mut cells: HashMap<(i32, i32), V>) -> HashMap<(i32, i32), V> {
    // Starts in cell order, so that a tie keeps the same patch every run.
    let mut starts: Vec<(i32, i32)> = cells.keys().copied().collect();
    starts.sort_unstable();
    let mut unseen: foldhash::HashSet<(i32, i32)> = starts.iter().copied().collect();
    let mut largest: Vec<(i32, i32)> = Vec::new();
    for start in starts {
        if !unseen.remove(&start) {
            continue;
        }
        let mut patch = vec![start];
        let mut next = 0;
        while let Some(&(i, j)) = patch.get(next) {
            next += 1;
            for di in -1..=1 {
                for dj in -1..=1 {
                    let cell = (i.saturating_add(di), j.saturating_add(dj));
                    if unseen.remove(&cell) {
                        patch.push(cell);
                    }
                }
            }
        }
        if patch.len() > largest.len() {
            largest = patch;
        }
    }
    let keep: foldhash::HashSet<(i32, i32)> = largest.into_iter().collect();
    cells.retain(|cell, _| keep.contains(cell));
    cells
}

/// What [`fit_terrain`] keeps of the points in one grid cell.
struct CellStats {
    /// The lowest point.
    low: glam::Vec3,
}

/// The points' grid cells with their lowest point.
fn cell_stats(points: &[glam::Vec3], origin: Vec2) -> HashMap<(i32, i32), CellStats> {
    let mut cells: HashMap<(i32, i32), CellStats> = HashMap::new();
    for &p in points {
        cells
            .entry(cell_of(origin, p.x, p.y))
            .and_modify(|c| {
                if p.z < c.low.z {
                    c.low = p;
                }
            })
            .or_insert(CellStats { low: p });
    }
    cells
}

/// The plane through the cells' lowest points `candidates`, refitted to
/// those within each of [`RESIDUAL_LIMITS_M`] in turn and then at the last
/// of them until its inliers settle ([`SETTLING_ROUNDS`]), with the final
/// inliers. It starts from the lowest `seed_share` of the candidates: under
/// a crown the lowest point of a cell is often a branch, never lower than
/// the ground.
fn fit_robust_plane(
    candidates: &[((i32, i32), DVec3)],
    seed_share: f64,
) -> Option<([f64; 3], Vec<bool>)> {
    let mut heights: Vec<f64> = candidates.iter().map(|(_, p)| p.z).collect();
    heights.sort_by(f64::total_cmp);
    let at = (heights.len() as f64 * seed_share) as usize;
    let seed_top = heights[at.min(heights.len() - 1)];
    let mut inlier: Vec<bool> = candidates.iter().map(|(_, p)| p.z <= seed_top).collect();
    let mut plane = fit_plane(candidates, &inlier)?;
    let last = RESIDUAL_LIMITS_M[RESIDUAL_LIMITS_M.len() - 1];
    let settling = std::iter::repeat_n(last, SETTLING_ROUNDS);
    for (round, limit) in RESIDUAL_LIMITS_M.into_iter().chain(settling).enumerate() {
        let next: Vec<bool> = candidates
            .iter()
            .map(|(_, p)| (p.z - eval_plane(plane, *p)).abs() <= limit)
            .collect();
        let settled = round >= RESIDUAL_LIMITS_M.len() && next == inlier;
        if settled || next.iter().filter(|&&b| b).count() < 3 {
            break;
        }
        inlier = next;
        plane = fit_plane(candidates, &inlier)?;
    }
    Some((plane, inlier))
}

/// Per terrain cell (those in `residual_m`, the lowest returns' heights
/// above the plane): the mean height above the plane of the cell's returns
/// within [`GROUND_TOLERANCE_M`] of its lowest, its ground returns.
fn mean_ground(
    points: &[glam::Vec3],
    origin: Vec2,
    plane: [f64; 3],
    residual_m: &HashMap<(i32, i32), f32>,
) -> HashMap<(i32, i32), f32> {
    let mut sums: HashMap<(i32, i32), (f64, u32)> = HashMap::new();
    for p in points {
        let cell = cell_of(origin, p.x, p.y);
        let Some(&lowest) = residual_m.get(&cell) else {
            continue;
        };
        let above_plane = f64::from(p.z) - eval_plane(plane, p.as_dvec3());
        if above_plane - f64::from(lowest) <= f64::from(GROUND_TOLERANCE_M) {
            let sum = sums.entry(cell).or_insert((0.0, 0));
            sum.0 += above_plane;
            sum.1 += 1;
        }
    }
    sums.into_iter()
        .map(|(cell, (sum, n))| (cell, (sum / f64::from(n)) as f32))
        .collect()
}

/// The terrain cells (those in `residual_m`) that are open ground: at
/// least [`BARE_CELL_MIN_POINTS`] points within [`GROUND_TOLERANCE_M`] of
/// the cell's lowest, and clear air for [`BARE_CLEARANCE_M`] above them.
///
/// Heights are measured above the plane rather than in z, so that a cell
/// of open ground on a slope is as bare as on the level: a 1 m cell on a
/// 30° slope spans 0.58 m in z (0.82 m across its diagonal), which the
/// tolerance would otherwise read as something standing on it, and no
/// ground steeper than about 20° would be found. Points higher than the
/// clearance do not count against the cell: under a crown, a terrestrial
/// plot scan sees the ground with the canopy metres above it, and when
/// every ground cell of a plot lies under the crown, nothing else shows
/// that the ground is ground. The bottom layer of a crown, which this test
/// keeps out, always has more of the crown right above its lowest points.
fn count_bare_cells(
    points: &[glam::Vec3],
    origin: Vec2,
    plane: [f64; 3],
    residual_m: &HashMap<(i32, i32), f32>,
) -> usize {
    let above = |p: &glam::Vec3| f64::from(p.z) - eval_plane(plane, p.as_dvec3());
    let mut lowest: HashMap<(i32, i32), f64> = HashMap::new();
    for p in points {
        let cell = cell_of(origin, p.x, p.y);
        if residual_m.contains_key(&cell) {
            let low = lowest.entry(cell).or_insert(f64::INFINITY);
            *low = low.min(above(p));
        }
    }
    // Per cell: the points of its ground layer, and whether anything
    // stands in the clearance above it.
    let tolerance = f64::from(GROUND_TOLERANCE_M);
    let mut layers: HashMap<(i32, i32), (u32, bool)> = HashMap::new();
    for p in points {
        let cell = cell_of(origin, p.x, p.y);
        let Some(&low) = lowest.get(&cell) else {
            continue;
        };
        let height = above(p) - low;
        let layer = layers.entry(cell).or_insert((0, false));
        if height <= tolerance {
            layer.0 += 1;
        } else if height <= tolerance + BARE_CLEARANCE_M {
            layer.1 = true;
        }
    }
    layers
        .values()
        .filter(|&&(n, blocked)| n >= BARE_CELL_MIN_POINTS && !blocked)
        .count()
}

fn cell_of(origin: Vec2, x: f32, y: f32) -> (i32, i32) {
    // `as` saturates, so absurd extents merge into edge cells instead of
    // overflowing.
    (
        ((x - origin.x) / CELL_M).floor() as i32,
        ((y - origin.y) / CELL_M).floor() as i32,
    )
}

fn eval_plane([a, b, c]: [f64; 3], p: DVec3) -> f64 {
    a * p.x + b * p.y + c
}

/// Least-squares plane `z = a·x + b·y + c` through the selected candidates,
/// centred for conditioning. A level plane at their mean height when they
/// are collinear in plan (a one-cell-wide strip).
fn fit_plane(candidates: &[((i32, i32), DVec3)], use_it: &[bool]) -> Option<[f64; 3]> {
    let chosen: Vec<DVec3> = candidates
        .iter()
        .zip(use_it)
        .filter(|(_, u)| **u)
        .map(|((_, p), _)| *p)
        .collect();
    if chosen.is_empty() {
        return None;
    }
    let mean = chosen.iter().copied().sum::<DVec3>() / chosen.len() as f64;
    let (mut sxx, mut sxy, mut syy, mut sxz, mut syz) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for p in &chosen {
        let d = *p - mean;
        sxx += d.x * d.x;
        sxy += d.x * d.y;
        syy += d.y * d.y;
        sxz += d.x * d.z;
        syz += d.y * d.z;
    }
    let det = sxx * syy - sxy * sxy;
    let scale = (sxx + syy).max(f64::MIN_POSITIVE);
    let (a, b) = if det.abs() <= 1e-9 * scale * scale {
        (0.0, 0.0)
    } else {
        let m = DMat3::from_cols(
            DVec3::new(sxx, sxy, 0.0),
            DVec3::new(sxy, syy, 0.0),
            DVec3::Z,
        );
        let ab = m.inverse() * DVec3::new(sxz, syz, 0.0);
        (ab.x, ab.y)
    };
    Some([a, b, mean.z - a * mean.x - b * mean.y])
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    /// Two oaks' plot scans (4 m discs of ground) 6 m apart on one level
    /// plot, as `silva synth --species oak --seed 1065` and `1066 --scan tls
    /// --ground-radius 4`: the underside of one crown tilts the seed plane,
    /// and the terrain must still hold the ground under both stems (before
    /// [`SETTLING_ROUNDS`] it held 27 cells, all under the first oak).
    #[test]
    fn the_terrain_of_two_plots_reaches_under_both_stems() {
        use crate::skeleton::Anchor;
        use crate::synth::{Species, TlsGround, TlsOptions, TreeParams, generate, simulate_tls};
        let options = TlsOptions {
            ground: Some(TlsGround {
                radius_m: 4.0,
                slope: Vec2::ZERO,
            }),
            ..TlsOptions::default()
        };
        let scan = |seed| {
            let oak = generate(
                &TreeParams::preset(Species::Oak),
                seed,
                Anchor::at(DVec3::ZERO),
            );
            simulate_tls(&oak, &options, seed).points
        };
        let apart = Vec3::new(6.0, 0.0, 0.0);
        let mut points = scan(1065);
        points.extend(scan(1066).into_iter().map(|p| p + apart));
        let terrain = fit_terrain(&points).unwrap();
        assert!(terrain.slope_deg() < 1.0, "{}", terrain.slope_deg());
        for stem in [Vec3::ZERO, apart] {
            let ground = terrain.surface_near(stem.x, stem.y);
            assert!(ground.is_some_and(|z| z.abs() < 0.05), "{stem}: {ground:?}");
        }
        // The lowest return of 118 cells lies on one of the two discs.
        let (occupied, cells) = terrain.cells;
        assert!(cells >= 80, "{cells} of {occupied} cells");
    }

    /// A plot's scanned ground, 10 m across, and one limb tip 5 m beyond
    /// its edge that lies on the ground plane's extrapolation: the tip's
    /// cell is no ground, as it is not part of the ground's one surface.
    #[test]
    fn a_cell_apart_from_the_ground_is_no_ground() {
        let mut points: Vec<Vec3> = (0..50)
            .flat_map(|i| (0..50).map(move |j| Vec3::new(i as f32 * 0.2, j as f32 * 0.2, 0.0)))
            .collect();
        points.extend((0..5).map(|k| Vec3::new(15.0 + 0.1 * k as f32, 5.0, 0.05)));
        let terrain = fit_terrain(&points).unwrap();
        assert!(terrain.surface_near(5.0, 5.0).is_some());
        assert_eq!(terrain.surface_near(15.2, 5.0), None);
    }

    /// 20 returns/m² of open ground on a 0.3 slope, 5 cm Gaussian range
    /// noise: the cells' lowest returns lie about 8 cm below the
    /// surface, and `surface_at` puts it back.
    #[test]
    fn the_surface_lies_above_the_lowest_returns_by_their_noise() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let noise = rand_distr::Normal::new(0.0f32, 0.05).expect("a valid deviation");
        let points: Vec<Vec3> = (0..8_000)
            .map(|_| {
                let (x, y) = (20.0 * rng.random::<f32>(), 20.0 * rng.random::<f32>());
                Vec3::new(x, y, 1.0 + 0.3 * x + rng.sample(noise))
            })
            .collect();
        let terrain = fit_terrain(&points).expect("a terrain");
        let truth = 1.0 + 0.3 * 10.0;
        let lowest = terrain.height_at(10.0, 10.0) - truth;
        let surface = terrain.surface_at(10.0, 10.0) - truth;
        assert!(lowest < -0.05, "lowest returns {lowest:+.3} m");
        assert!(surface.abs() < 0.02, "surface {surface:+.3} m");
    }

    /// A terrestrial plot scan of a broad tree: a 4 m disc of ground
    /// around the stem under a crown 20 m across, so that the ground's cells
    /// are about an eighth of the occupied ones. The disc is found as ground
    /// (before, the plane fit, seeded by the lower half of the cells, ran up
    /// into the crown, and a surface covering under a quarter of the cells
    /// was not ground however open) and the stem and crown stay tree.
    #[test]
    fn a_ground_patch_under_a_broad_crown_is_ground() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let mut ground: Vec<Vec3> = Vec::new();
        while ground.len() < 2_500 {
            let (x, y) = (
                8.0 * rng.random::<f32>() - 4.0,
                8.0 * rng.random::<f32>() - 4.0,
            );
            if x.hypot(y) <= 4.0 {
                ground.push(Vec3::new(x, y, 0.01 * rng.random::<f32>()));
            }
        }
        let mut standing: Vec<Vec3> = (0..200)
            .map(|k| {
                Vec3::new(
                    0.3 * (k as f32).cos(),
                    0.3 * (k as f32).sin(),
                    k as f32 * 0.02,
                )
            })
            .collect();
        standing.extend((0..8_000).map(|_| {
            let (x, y) = (
                20.0 * rng.random::<f32>() - 10.0,
                20.0 * rng.random::<f32>() - 10.0,
            );
            Vec3::new(x, y, 4.0 + 5.0 * rng.random::<f32>())
        }));
        let points: Vec<Vec3> = ground.iter().chain(&standing).copied().collect();
        let split = split_ground(&PointCloud::from_points(DVec3::ZERO, points));
        assert_eq!(split.method, GroundMethod::Geometry);
        let terrain = split.terrain.as_ref().expect("a terrain");
        assert!(
            terrain.cell_share() < 0.25,
            "share {}",
            terrain.cell_share()
        );
        assert!(
            terrain.slope_deg() < 1.0,
            "slope {:.1}°",
            terrain.slope_deg()
        );
        let stem_foot = standing.iter().filter(|p| p.z < GROUND_TOLERANCE_M).count();
        assert_eq!(split.ground.len(), ground.len() + stem_foot);
        assert_eq!(split.tree.len(), standing.len() - stem_foot);
    }

    /// Open ground on a 35° slope with a pole standing on it: a 1 m cell
    /// spans 0.7 m in z, yet the cells are bare in height above the plane,
    /// so the slope is found as ground (before the spans were measured
    /// above the plane, nothing steeper than about 20° was) and the pole
    /// stays tree.
    #[test]
    fn steep_open_ground_is_ground() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let noise = rand_distr::Normal::new(0.0f32, 0.05).expect("a valid deviation");
        let rise = 35f32.to_radians().tan();
        let mut points: Vec<Vec3> = (0..8_000)
            .map(|_| {
                let (x, y) = (20.0 * rng.random::<f32>(), 20.0 * rng.random::<f32>());
                Vec3::new(x, y, rise * x + rng.sample(noise))
            })
            .collect();
        points.extend((4..=40).map(|k| Vec3::new(10.0, 10.0, rise * 10.0 + k as f32 * 0.25)));
        let split = split_ground(&PointCloud::from_points(DVec3::ZERO, points));
        assert_eq!(split.method, GroundMethod::Geometry);
        let slope = split.terrain.as_ref().expect("a terrain").slope_deg();
        assert!((slope - 35.0).abs() < 1.0, "slope {slope:.1}°");
        assert_eq!(split.tree.len(), 37, "the pole, and no ground");
        // Rising along +x, the ground is levelled by turning it about +y.
        let note = split.steep_note().expect("a steep note");
        assert!(
            note.contains("slopes 35°")
                && note.contains("by 35° about the axis (0.00, 1.00, 0.00)"),
            "{note}"
        );
    }

    #[test]
    fn the_levelling_turn_brings_up_to_z() {
        for up in [
            Vec3::new(0.0, -0.87, 0.5),
            Vec3::new(0.3, 0.2, 0.9),
            Vec3::new(0.0, 0.0, -1.0),
            Vec3::Z,
        ] {
            let (degrees, axis) = levelling_turn(up);
            let turned = glam::Quat::from_axis_angle(axis, degrees.to_radians()) * up.normalize();
            assert!(turned.dot(Vec3::Z) > 0.9999, "{up} -> {turned}");
        }
        assert_eq!(
            levelling_words(Vec3::Z),
            "turn the cloud by 0° about the axis (1.00, 0.00, 0.00)"
        );
    }
}
