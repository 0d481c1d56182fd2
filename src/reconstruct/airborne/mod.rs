//! Airborne pipeline: a skeleton from a sparse airborne LiDAR clip of one
//! tree, after Hu et al., "Efficient tree modeling from airborne LiDAR point
//! clouds" (../shared/papers/airborne-lidar-tree-modeling.txt).
//!
//! Airborne clips (AHN3: 10–30 pts/m²) see the crown from above and hit the
//! trunk a few times at best, so a dense pipeline's shortest-path tree from a
//! trunk base has nothing to start from. Hu et al. instead insert trunk
//! points, build a graph that is connected by construction, and grow the
//! skeleton greedily along a heuristic direction field of natural branch
//! growth. The stages, each a short function citing its section:
//!
//! 1. [`crate::reconstruct::ground::split_ground`] removes the ground and
//!    gives the terrain height (the ground plane of §4.2); a clip whose tree
//!    points fall apart into two trees side by side is refused
//!    (`check_one_tree`: our addition, since Eq. 3/4 would put one trunk
//!    between them), and crowns that touch, which form one part, are
//!    noted when the canopy shows two tops with a deep dip between them
//!    (`two_crowns_note`, module `reconstruct::crown_tops`);
//! 2. `add_trunk` — §4.2, Eq. 3/4 with the λ1/λ2 rule, continued as a
//!    leader to the apex (our addition, see [`Params::leader`]);
//! 3. `thin` — §5.1, voxel downsampling and sequential thinning, then one
//!    contraction step toward the local mean when the crown's returns are
//!    foliage (our addition, see [`Params::contraction_radius_m`] and
//!    [`Params::bare_crown_linearity`]);
//! 4. `graph` — §5.2, Algorithm 1 (FRNN + kNN);
//! 5. `direction_field` — §5.3, Eq. 5 rotated about the centreline;
//! 6. `skeleton_produce` — §5.4, Algorithm 2 (greedy, α/β/φ constraints);
//! 7. provisional pipe-model radii — §5.5, Eq. 6. The shared radius stage
//!    re-assigns radii for both pipelines (for this one the pipe model
//!    alone: crown returns are not branch sections); these only make the
//!    skeleton usable on its own.
//!
//! Coordinates: the paper's y axis is up; silva's z is. The skeleton's anchor
//! is the absolute trunk base, so `anchor.origin + position` is the real
//! (georeferenced) position of every node.
//!
//! What limits recall: on synthetic AHN-like scans (`silva eval --synthetic
//! 20 --scan als`, leaf-off) the branches of at least 5 cm radius that the
//! skeleton misses by more than 0.5 m (oaks' limbs and stem inside the
//! crown, pines' whorl stubs beside the leader) have no return of their
//! own: every return within 0.5 m of them lies nearer other wood, and the
//! skeleton passes within 0.3 m of 89 of those 99 returns (no return at all
//! near the pines' misses). Of the oaks' recalled thick wood 54–58 % has a
//! return within 0.25 m, of the missed 0–1 %. Stages 3–6 work on the
//! returns and cannot place unseen wood; only priors such as the inserted
//! trunk and leader do.

use glam::{DVec3, Vec3};

use super::ReconstructError;
use super::ground::{GroundMethod, GroundSplit, Terrain, split_ground};
use crate::cloud::PointCloud;
use crate::interrupt::Interrupt;
use crate::skeleton::{Anchor, Skeleton};
use crate::spatial::PointIndex;

mod direction;
mod graph;
mod skeleton;
mod thin;
mod trunk;

/// Fewest tree points (after ground removal) the pipeline accepts.
pub const MIN_TREE_POINTS: usize = 10;

/// Share of candidate points that Algorithm 2 must reach for the result to
/// count as a whole tree; Hu et al. §6.2 export a model only above 85 %.
const MIN_VISITED_SHARE: f32 = 0.85;

/// How far below the 1st percentile of height a point may lie before it
/// counts as a low outlier when there is no terrain (metres).
const LOW_OUTLIER_M: f32 = 1.0;

/// A part of the tree points this far from the rest, or farther, is not
/// the same tree ([`check_one_tree`]), in metres…
///
/// Measured on the tree points (more than 0.5 m above the flat ground) of
/// synthetic AHN-like clips (`silva synth --scan als`, each species,
/// seeds 1–25 leaf-off and leaf-on at 20 points/m², seeds 1–10 at 5 and at
/// 2 points/m²; single linkage in a Python prototype): the widest gap that
/// splits off a tenth of one tree's points was 1.5 m at 20 points/m², 2.2 m
/// at 5 and 5.9 m at 2 (a poplar, its spacing 1.5 m), at most 5.4 median
/// point spacings; on tiny.xyz 0.8 m (3.4 spacings), and ahn3_delft does
/// not split at all.
const DETACHED_GAP_M: f32 = 3.0;

/// …or this many median point spacings, if longer: the sparser the scan,
/// the farther apart its hits on one crown lie (see [`DETACHED_GAP_M`]).
const DETACHED_GAP_SPACINGS: f32 = 10.0;

/// …when it holds at least this share of the points, as the dense
/// pipeline's `Params::detached_share`, and stands beside the rest rather
/// than above or below it. Smaller parts stay (a piece of a neighbour's
/// crown at the clip's edge), and so do parts above or below: a crown over
/// ground that was not found, stem returns far under a crown (which the
/// trunk step reads), a sparse crown's top. At 2 points/m², where a
/// synthetic tree holds 20–90 returns and the ground is not always found,
/// the share alone refused 16 of 200 clips (`silva eval --synthetic 100
/// --scan als --density 2`, seeds 1–100 and 101–200), parts 4–11 m above
/// or below the rest; beside the rest, none (nor at 5 points/m²).
const DETACHED_SHARE: f32 = 0.1;

/// The note of a clip without ground that no upright test flagged: such a
/// clip turned by 20–60° reads as upright (see the [`super::upright`]
/// module docs), so the assumption is stated rather than checked.
const UPRIGHT_UNCHECKED: &str = "upright not checked: with no ground in the clip, silva takes \
     +z as up, as in a georeferenced clip; a clip tilted by less than about 60° cannot be told \
     from an upright one without ground, and its height and trunk base would be measured askew";

/// Smallest spread (standard deviation, metres) along the second and third
/// principal axes for a cloud to be a volume rather than a line or a plane.
const MIN_SPREAD_M: f32 = 0.05;

/// Parameters of the airborne pipeline. `Default` gives Hu et al.'s defaults
/// (§6.2: "d_l = 0.2 m, r_p = 1.2 m, θ_u = 80°, θ_l = −40°, k1 = 1.4,
/// k2 = 1.0, α_max = 70°, β_max = 70° and φ_max = 30°") and the §4.2 rule,
/// with one documented change: λ2's limit (see [`Params::lambda2_max`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Params {
    /// d_l, voxel pitch of thinning (§5.1, Table 1: 0.15–0.25 m). 0.2 m.
    pub voxel_m: f32,
    /// r_p, fixed-radius neighbour search radius of the graph (§5.2,
    /// Algorithm 1; Table 1: 0.8–1.4 m). 1.2 m.
    pub neighbour_radius_m: f32,
    /// k, nearest neighbours connected when a point has fewer than k within
    /// r_p (§5.2, Algorithm 1; Table 1: 10–30). The paper gives no single
    /// default; 10, the low end of its range, suits r_p = 1.2 m.
    pub knn: usize,
    /// θ_u, direction angle at the upper outer corner of the bounding box
    /// (§5.3, Eq. 5). 80°.
    pub theta_upper_deg: f32,
    /// θ_l, direction angle at the lower outer corner (§5.3, Eq. 5). −40°.
    pub theta_lower_deg: f32,
    /// k1, exponent of the height term μ1 (§5.3, Eq. 5). 1.4.
    pub k1: f32,
    /// k2, exponent of the distance-from-centreline term μ2 (§5.3, Eq. 5). 1.0.
    pub k2: f32,
    /// α_max, largest bending angle between parent and child segment
    /// (§5.4, Algorithm 2). 70°.
    pub alpha_max_deg: f32,
    /// β_max, largest angle between a child segment and the direction field
    /// at its end (§5.4, Algorithm 2). 70°.
    pub beta_max_deg: f32,
    /// φ_max, pruning angle: of two child segments closer than this, the one
    /// with the larger bending angle is dropped (§5.4). 30°.
    pub phi_max_deg: f32,
    /// Upper limit of λ1, the angle between the lowest points' mean
    /// direction and the centreline, for Eq. 3 (§4.2). 30°.
    pub lambda1_max_deg: f32,
    /// Upper limit of λ2, the lowest point's horizontal distance from the
    /// centreline relative to the crown's half diagonal, for Eq. 3 (§4.2).
    /// The paper uses 0.5 on its 40 pts/m² UAV clips; at AHN densities the
    /// lowest point is often a low limb, and 0.5 of a 10 m half diagonal
    /// accepted limbs metres from the trunk on synthetic AHN-like scans, so
    /// the default here is 0.25.
    pub lambda2_max: f32,
    /// r, radius of the sphere around the lowest tree point whose points give
    /// the trunk direction n_avg (§4.2). The paper leaves it open; r_p's
    /// default, 1.2 m, reaches the next trunk hits at AHN densities.
    pub trunk_sphere_m: f32,
    /// Radius of the neighbourhood whose mean replaces each candidate point
    /// after thinning (one contraction step). Not in the paper: on sparse
    /// clouds §5.1's thinning leaves candidates where the returns are, on
    /// the foliage up to half a metre from the wood; the neighbourhood mean
    /// moves them toward the twigs the foliage surrounds. 0.6 m, the size of
    /// a leaf cluster; 0 turns it off. Skipped on a bare crown (see
    /// [`Params::bare_crown_linearity`]).
    pub contraction_radius_m: f32,
    /// A crown whose candidates' median linearity within the contraction
    /// radius reaches this reads as bare twigs, and is not contracted. Not
    /// in the paper. A leaf-off (AHN) crown returns from the twigs
    /// themselves, in lines; the mean of 0.6 m around a candidate there lies
    /// off the twig, between the branches, and Algorithm 2 then misses the
    /// limbs' bases by half a metre. Foliage (needles, leaf-on crowns)
    /// returns from clumps (`thin::crown_linearity`). See the field's
    /// default for the figures; above 1 every crown is contracted.
    pub bare_crown_linearity: f32,
    /// R_const, radius of a branch tip in the pipe model (§5.5, Eq. 6),
    /// user-defined in the paper. 1 cm.
    pub tip_radius_m: f32,
    /// Continue the inserted trunk as a straight leader from the crown
    /// centroid to just under the highest return, when that line leans less
    /// than 30° from the vertical. Not in the paper, whose §4.2 trunk ends at
    /// the centroid: a needle shell or a leaf-on crown returns nothing near
    /// the axis, so Algorithm 2 carried the main stem up from limb to limb,
    /// metres off the true leader. Synthetic AHN-like scans (`silva eval
    /// --synthetic 20 --scan als`, release build): the pines' recall of
    /// branches of at least 5 cm radius 0.797–0.945 → 0.885–0.996, median
    /// recall over all 20 trees 0.944 → 0.997 (18 of 20 trees at 0.90 or
    /// more, from 16), precision within ±0.01 on every tree; leaf-on
    /// (`--leaves on`) median recall 0.876 → 0.995, but birch 10's precision
    /// 0.854 → 0.849.
    pub leader: bool,
}

impl Default for Params {
    fn default() -> Self {
        Self {
            voxel_m: 0.2,
            neighbour_radius_m: 1.2,
            knn: 10,
            theta_upper_deg: 80.0,
            theta_lower_deg: -40.0,
            k1: 1.4,
            k2: 1.0,
            alpha_max_deg: 70.0,
            beta_max_deg: 70.0,
            phi_max_deg: 30.0,
            lambda1_max_deg: 30.0,
            lambda2_max: 0.25,
            trunk_sphere_m: 1.2,
            contraction_radius_m: 0.6,
            bare_crown_linearity: BARE_CROWN_LINEARITY,
            tip_radius_m: 0.01,
            leader: true,
        }
    }
}

/// What the airborne pipeline produced.
#[derive(Debug, Clone)]
pub struct AirborneResult {
    /// The skeleton; its anchor origin is the absolute trunk base.
    pub skeleton: Skeleton,
    /// Points identified as ground and left out of the reconstruction.
    pub ground_points: usize,
    /// The tree's points (finite, without ground), relative to the
    /// skeleton's anchor: `tree.offset == skeleton.anchor().origin`.
    pub tree: PointCloud,
    /// Trunk points inserted by §4.2 (the root included).
    pub trunk_points_added: usize,
    /// Human-readable remarks: ground method, trunk rule, and any flag that
    /// makes the result a best effort rather than a whole tree.
    pub notes: Vec<String>,
}

/// Reconstructs the skeleton of the one tree in an airborne clip (module
/// docs). The clip may contain ground; z must point up.
///
/// ```
/// use glam::{DVec3, Vec3};
/// use silva::cloud::PointCloud;
/// use silva::reconstruct::airborne::{reconstruct, Params};
///
/// // Ground, and a crown sphere 6 m up around a point above (5, 5).
/// let mut pts = Vec::new();
/// for i in 0..40 {
///     for j in 0..40 {
///         pts.push(Vec3::new(i as f32 * 0.25, j as f32 * 0.25, 0.0));
///     }
/// }
/// for k in 0..600 {
///     let (u, v) = (k as f32 * 0.618_034 % 1.0, k as f32 / 600.0);
///     let (phi, z) = (u * std::f32::consts::TAU, 2.0 * v - 1.0);
///     let r = (1.0 - z * z).sqrt();
///     pts.push(Vec3::new(5.0, 5.0, 6.0) + 2.5 * Vec3::new(r * phi.cos(), r * phi.sin(), z));
/// }
/// let cloud = PointCloud::from_points(DVec3::new(85_000.0, 446_000.0, 1.0), pts);
/// let result = reconstruct(&cloud, &Params::default()).unwrap();
/// let base = result.skeleton.anchor().origin;
/// assert!((base.x - 85_005.0).abs() < 0.5 && (base.y - 446_005.0).abs() < 0.5);
/// assert!((base.z - 1.0).abs() < 0.1);
/// assert_eq!(result.ground_points, 1600);
/// ```
pub fn reconstruct(
    cloud: &PointCloud,
    params: &Params,
) -> Result<AirborneResult, ReconstructError> {
    reconstruct_within(cloud, params, &Interrupt::never())
}

/// [`reconstruct`], checking `interrupt` before each step.
pub fn reconstruct_within(
    cloud: &PointCloud,
    params: &Params,
    interrupt: &Interrupt,
) -> Result<AirborneResult, ReconstructError> {
    validate(params)?;
    interrupt.check("ground separation")?;
    let mut notes = Vec::new();
    let (finite, split) = separated(cloud, &mut notes)?;
    interrupt.check("trunk completion")?;
    let tree = &without_low_outliers(&split, &mut notes);
    super::check_height(tree)?;
    check_one_tree(tree)?;
    notes.extend(two_crowns_note(tree, split.terrain.as_ref()));
    let trunk = trunk::add_trunk(tree, split.terrain.as_ref(), params);
    notes.push(trunk.note());
    let trunk_points_added = trunk.points.len();
    interrupt.check("thinning and contraction")?;
    let mut points = trunk.points;
    let candidates = thin::thin(tree, params.voxel_m);
    let contraction = contraction_radius(&candidates, params, &mut notes);
    points.extend(thin::contract(&candidates, tree, contraction));
    let produced = produce(&points, params, interrupt, &mut notes)?;
    interrupt.check("skeleton assembly")?;
    let root = points[0];
    let anchor = Anchor {
        origin: finite.offset + root.as_dvec3(),
        crs: None,
    };
    let mut skeleton = skeleton::to_skeleton(anchor, &points, &produced, root);
    skeleton::pipe_radii(&mut skeleton, params.tip_radius_m);
    skeleton.order_main_extension_first();
    Ok(AirborneResult {
        tree: split.tree.rebased(skeleton.anchor().origin),
        skeleton,
        ground_points: split.ground.len(),
        trunk_points_added,
        notes,
    })
}

/// The cloud's finite points, and those split into ground and tree; errors
/// when too few are left for a tree, or the tree is not upright or too big.
fn separated(
    cloud: &PointCloud,
    notes: &mut Vec<String>,
) -> Result<(PointCloud, GroundSplit), ReconstructError> {
    let finite = usable_points(cloud);
    if finite.len() < MIN_TREE_POINTS {
        return Err(ReconstructError::TooFewPoints {
            found: finite.len(),
            needed: MIN_TREE_POINTS,
        });
    }
    if finite.len() < cloud.len() {
        notes.push(format!(
            "{} non-finite points ignored",
            cloud.len() - finite.len()
        ));
    }
    let split = split_ground(&finite);
    super::upright::check_ground_below(&finite.points, &split)?;
    super::upright::check_stands_on_its_trunk(
        &split.tree.points,
        STEM_LINK_M,
        super::upright::SPARSE_SLICES,
    )?;
    notes.push(split.note());
    notes.extend(split.steep_note());
    if split.tree.len() < MIN_TREE_POINTS {
        return Err(ReconstructError::NoTreeAboveGround {
            tree: split.tree.len(),
            ground: split.ground.len(),
            needed: MIN_TREE_POINTS,
        });
    }
    check_volume(&split.tree.points)?;
    if split.method == GroundMethod::None {
        let tree = &split.tree.points;
        notes.push(
            super::ground_plane::tilted_ground(tree)
                .map(|g| g.note())
                .or_else(|| super::upright::seen_from_below(tree))
                .or_else(|| super::upright::trunk_on_top(tree))
                .or_else(|| super::upright::seen_from_beside(tree))
                .unwrap_or_else(|| UPRIGHT_UNCHECKED.to_owned()),
        );
    }
    Ok((finite, split))
}

/// The graph (Algorithm 1), the direction field (Eq. 5) and the greedy
/// skeleton (Algorithm 2) over the candidate points, with a note on how
/// many of them the skeleton reached.
fn produce(
    points: &[Vec3],
    params: &Params,
    interrupt: &Interrupt,
    notes: &mut Vec<String>,
) -> Result<skeleton::Produced, ReconstructError> {
    interrupt.check("the neighbour graph")?;
    let adjacency = graph::graph(points, params.neighbour_radius_m, params.knn);
    interrupt.check("the direction field")?;
    let field = direction::direction_field(points, params);
    interrupt.check("skeleton production (Algorithm 2)")?;
    let produced = skeleton::skeleton_produce(points, &adjacency, &field, 0, 1, params);
    let share = |n: usize| n as f32 / points.len() as f32;
    notes.push(format!(
        "Algorithm 2 reached {:.0} % of {} candidate points, {:.0} % after re-attachment",
        share(produced.reached_by_algorithm2) * 100.0,
        points.len(),
        share(produced.visited) * 100.0
    ));
    if share(produced.visited) < MIN_VISITED_SHARE {
        notes.push(format!(
            "best effort: under {:.0} % of the points are connected to the trunk; the clip may \
             hold several trees or detached parts",
            MIN_VISITED_SHARE * 100.0
        ));
    }
    Ok(produced)
}

/// Rejects a clip whose tree points fall apart into parts too far apart to
/// be one tree (see [`DETACHED_GAP_M`]): two trees in one clip, which the
/// trunk step (Eq. 3/4) and Algorithm 2 would read as one, with a trunk
/// between them. The dense pipeline rejects them with the same error when
/// it connects its graph.
fn check_one_tree(points: &[Vec3]) -> Result<(), ReconstructError> {
    let Some(part) = super::parts::detached_part(points, DETACHED_GAP_M) else {
        return Ok(());
    };
    let share = part.points as f32 / points.len() as f32;
    if share < DETACHED_SHARE || !part.beside() {
        return Ok(());
    }
    let spacing_m = PointIndex::new(points)
        .median_spacing(points)
        .unwrap_or(0.0);
    let gap_m = part.gap_m(points);
    if gap_m < DETACHED_GAP_SPACINGS * spacing_m {
        return Ok(());
    }
    Err(ReconstructError::Disconnected {
        share_pct: 100.0 * share,
        gap_m,
    })
}

/// A best-effort note when the canopy shows two crowns that touch
/// ([`super::crown_tops`]): one part, so [`check_one_tree`] lets it pass,
/// but two tops with the canopy low between them. Heights are taken above
/// the terrain, or above the lowest tree point when there is none.
fn two_crowns_note(tree: &[Vec3], terrain: Option<&Terrain>) -> Option<String> {
    let lowest = tree.iter().map(|p| p.z).fold(f32::INFINITY, f32::min);
    let heights: Vec<Vec3> = tree
        .iter()
        .map(|p| {
            let ground = terrain.map_or(lowest, |t| t.height_at(p.x, p.y));
            p.with_z(p.z - ground)
        })
        .collect();
    super::crown_tops::two_crowns(&heights)
        .filter(|tops| tops.dip() >= super::crown_tops::TWO_CROWNS_DIP)
        .map(|tops| tops.note())
}

/// The finite points of `cloud` with their classification (the only
/// attribute the pipeline reads); attributes whose length does not match the
/// points are dropped rather than trusted.
fn usable_points(cloud: &PointCloud) -> PointCloud {
    let keep: Vec<usize> = (0..cloud.len())
        .filter(|&i| cloud.points[i].is_finite())
        .collect();
    let classification = cloud
        .classification
        .as_ref()
        .filter(|c| c.len() == cloud.len())
        .map(|c| keep.iter().map(|&i| c[i]).collect());
    PointCloud {
        classification,
        ..PointCloud::from_points(
            cloud.offset,
            keep.iter().map(|&i| cloud.points[i]).collect(),
        )
    }
}

/// The tree points, without isolated returns far below the rest when there
/// is no terrain to judge them by: the lowest point becomes the trunk base,
/// so one multipath return a few metres under the ground would otherwise
/// set the tree's height. Points more than [`LOW_OUTLIER_M`] below the 1st
/// percentile of height are dropped.
fn without_low_outliers(split: &GroundSplit, notes: &mut Vec<String>) -> Vec<Vec3> {
    let points = &split.tree.points;
    if split.terrain.is_some() {
        return points.clone();
    }
    let mut heights: Vec<f32> = points.iter().map(|p| p.z).collect();
    heights.sort_by(f32::total_cmp);
    let floor = heights[heights.len() / 100] - LOW_OUTLIER_M;
    let kept: Vec<Vec3> = points.iter().copied().filter(|p| p.z >= floor).collect();
    if kept.len() < points.len() {
        notes.push(format!(
            "{} isolated low points ignored (more than {LOW_OUTLIER_M} m below the 1st percentile)",
            points.len() - kept.len()
        ));
    }
    kept
}

fn validate(p: &Params) -> Result<(), ReconstructError> {
    let positive = [
        p.voxel_m,
        p.neighbour_radius_m,
        p.trunk_sphere_m,
        p.k1,
        p.k2,
    ];
    let angles = [
        p.alpha_max_deg,
        p.beta_max_deg,
        p.phi_max_deg,
        p.lambda1_max_deg,
    ];
    let ok = positive.iter().all(|v| v.is_finite() && *v > 0.0)
        && angles
            .iter()
            .all(|a| a.is_finite() && *a > 0.0 && *a <= 180.0)
        && p.theta_lower_deg.is_finite()
        && p.theta_upper_deg.is_finite()
        && p.lambda2_max.is_finite()
        && p.tip_radius_m.is_finite()
        && p.tip_radius_m >= 0.0
        && p.contraction_radius_m.is_finite()
        && p.contraction_radius_m >= 0.0
        && p.bare_crown_linearity.is_finite()
        && p.knn >= 1;
    if ok {
        Ok(())
    } else {
        Err(ReconstructError::InvalidParameter(format!("{p:?}")))
    }
}

/// Default of [`Params::bare_crown_linearity`]. On synthetic AHN-like
/// scans (`silva eval --synthetic 20 --scan als --seed S`, S = 1, 21, …,
/// 581) the median linearity of the leaf-off birch and oak crowns was
/// 0.52–0.68 and 0.55–0.72 (10th percentiles 0.57 and 0.60), of the pines'
/// needle shells 0.49–0.55, of leaf-on crowns (`--leaves on`) 0.46–0.61, the
/// highest on poplars; the real AHN3 clip `ahn3_delft` reads 0.52. Not
/// contracting the bare crowns raised the trees with recall ≥ 0.90 from 526
/// to 560 of 600 (oaks 101 → 135; S = 601, …, 1181 held out: 515 → 554),
/// every tree keeping precision ≥ 0.85; at 0.58 it was 567, but six leaf-on
/// poplars of 150 fell below precision 0.85 (one at 0.60). Leaf-on scans,
/// S = 1, 21, …, 81: unchanged. (Recall as `eval::compare` measured it
/// then, a lateral's first internode counted at the mean of its radius and
/// its stem's; see [`crate::Skeleton::internode_radii`].)
const BARE_CROWN_LINEARITY: f32 = 0.6;

/// The contraction radius for these candidates: the parameter's, or 0 on a
/// bare crown ([`Params::bare_crown_linearity`]), with a note.
fn contraction_radius(candidates: &[Vec3], params: &Params, notes: &mut Vec<String>) -> f32 {
    let radius = params.contraction_radius_m;
    if radius <= 0.0 {
        return 0.0;
    }
    let Some(linearity) = thin::crown_linearity(candidates, radius) else {
        return radius;
    };
    if linearity < params.bare_crown_linearity {
        notes.push(format!(
            "crown read as foliage (median linearity {linearity:.2} within {radius} m, \
             below {:.2}): candidates contracted toward their neighbourhood means",
            params.bare_crown_linearity
        ));
        radius
    } else {
        notes.push(format!(
            "crown read as bare twigs (median linearity {linearity:.2} within {radius} m, \
             at least {:.2}): candidates left on the returns",
            params.bare_crown_linearity
        ));
        0.0
    }
}

/// Points closer than this (metres) belong to one piece of bark in the
/// upside-down test of a terrestrial cloud sent to this pipeline
/// ([`super::upright`]). Sparse terrestrial scans (`silva synth --scan tls
/// --density 40`, seeds 1–20), which `Mode::Auto` sends here when turned
/// over, have median point spacings of 0.09–0.13 m: at 0.1 m their trunk's
/// bark fell apart into pieces too small to fit a ring, and 8 of the 20
/// turned over were rejected; at 0.15 m, 12 (the misses are birches and
/// pines, whose trunk slice holds under 30 points), none upright; with
/// the taller slices of [`super::upright::SPARSE_SLICES`], 18. Airborne
/// points do not ring a stem at this link either (ahn3_delft's lie 0.22 m
/// apart, the synthetic AHN-like clips' about 0.14 m): the report of
/// `silva eval --synthetic 100 --scan als` is the same at 0.1 and 0.15 m,
/// and ahn3_delft and tiny are rejected or flagged at the same turns.
const STEM_LINK_M: f32 = 0.15;

/// Rejects tree points that lie on one line or one plane (principal
/// component spreads below [`MIN_SPREAD_M`]).
fn check_volume(points: &[Vec3]) -> Result<(), ReconstructError> {
    let n = points.len() as f64;
    let mean = points.iter().map(|p| p.as_dvec3()).sum::<DVec3>() / n;
    let mut cov = glam::DMat3::ZERO;
    for p in points {
        let d = p.as_dvec3() - mean;
        cov += glam::DMat3::from_cols(d * d.x, d * d.y, d * d.z);
    }
    let spreads = eigen_spreads(cov * (1.0 / n));
    let min = f64::from(MIN_SPREAD_M);
    if spreads[1] < min {
        return Err(ReconstructError::Degenerate(format!(
            "the tree points lie on one line (spread across it {:.3} m)",
            spreads[1]
        )));
    }
    if spreads[2] < min {
        return Err(ReconstructError::Degenerate(format!(
            "the tree points lie on one plane (spread across it {:.3} m)",
            spreads[2]
        )));
    }
    Ok(())
}

/// Standard deviations along the principal axes, largest first, from the
/// eigenvalues of a symmetric 3×3 covariance (closed form, trigonometric).
fn eigen_spreads(c: glam::DMat3) -> [f64; 3] {
    let (a, b, d) = (c.x_axis, c.y_axis, c.z_axis);
    let p1 = a.y * a.y + a.z * a.z + b.z * b.z;
    let q = (a.x + b.y + d.z) / 3.0;
    let mut eig = if p1 <= 1e-18 * (q * q).max(1e-30) {
        [a.x, b.y, d.z]
    } else {
        let p2 = (a.x - q).powi(2) + (b.y - q).powi(2) + (d.z - q).powi(2) + 2.0 * p1;
        let p = (p2 / 6.0).sqrt();
        let bm = (c - glam::DMat3::from_diagonal(DVec3::splat(q))) * (1.0 / p);
        let r = (bm.determinant() / 2.0).clamp(-1.0, 1.0);
        let phi = r.acos() / 3.0;
        let e1 = q + 2.0 * p * phi.cos();
        let e3 = q + 2.0 * p * (phi + 2.0 * std::f64::consts::FRAC_PI_3).cos();
        [e1, 3.0 * q - e1 - e3, e3]
    };
    eig.sort_by(|x, y| y.total_cmp(x));
    eig.map(|e| e.max(0.0).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    /// A clip without ground says so in words, not as "0 points none found".
    #[test]
    fn the_ground_note_reads_as_a_sentence_with_and_without_ground() {
        let cloud = |points| PointCloud::from_points(DVec3::ZERO, points);
        let none = GroundSplit {
            tree: cloud(vec![Vec3::Z]),
            ground: cloud(Vec::new()),
            method: GroundMethod::None,
            terrain: None,
        };
        assert_eq!(
            none.note(),
            "ground: none found; all points treated as tree"
        );
        let classified = GroundSplit {
            ground: cloud(vec![Vec3::ZERO, Vec3::X]),
            method: GroundMethod::Classification,
            ..none
        };
        assert_eq!(classified.note(), "ground: 2 points by LAS class 2");
    }
}
