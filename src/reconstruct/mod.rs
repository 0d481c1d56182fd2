//! Skeleton reconstruction from point clouds (issue 3).
//!
//! [`reconstruct`] turns the point cloud of one tree into a [`Skeleton`] with
//! radii and [`metrics::TreeMetrics`]:
//!
//! 1. drop the points classified as noise (LAS classes 7 and 18), a
//!    handful of stray returns far from the rest (birds, noise; see
//!    [`STRAY_GAP_M`]) and small groups with no other return near them
//!    ([`ISOLATED_GROUPS`]), and validate the input (enough points, no wider than
//!    [`MAX_TREE_WIDTH_M`], not on one line or plane);
//! 2. choose a pipeline ([`Mode::Auto`] looks at point density and trunk
//!    coverage, see [`survey`]);
//! 3. build the skeleton: the dense pipeline after AdTree
//!    (lsystem-from-adtree-skeletons §2.1.1; multi-temporal-tree-growth
//!    §3.2.1), see [`dense`];
//! 4. assign radii with the shared stage in [`radii`]: a robust trunk circle
//!    fit (or an allometric estimate, flagged) and the pipe model of
//!    airborne-lidar-tree-modeling §5.5, Eq. 6;
//! 5. compute per-tree metrics in [`metrics`].
//!
//! Plain synchronous code without IO. The z axis is assumed to point up and
//! the cloud to hold one tree; inputs that break this assumption get a
//! [`ReconstructError`] or a flagged best effort in [`Reconstruction::notes`].
//! Both pipelines reject a cloud that is wide at the bottom and narrow at the
//! top, and one whose thickest stem is near its top (module `upright`: a
//! conifer or a columnar tree turned over is narrow at both ends), and note
//! a cloud whose ground, found as a plane in 3D, tilts 45° or more (module
//! `ground_plane`: a plot scan turned too far for the terrain grid).

use std::borrow::Cow;

use glam::{DVec3, Vec3};
use serde::{Deserialize, Serialize};

use crate::cloud::PointCloud;
use crate::cloud::clean::{self, IsolatedGroups, Strays};
use crate::interrupt::Interrupt;
use crate::skeleton::Skeleton;

pub mod airborne;
mod crown_tops;
pub mod dense;
mod error;
pub mod ground;
mod ground_plane;
pub mod metrics;
mod parts;
pub mod radii;
mod upright;

pub use error::ReconstructError;

/// Fewest points any pipeline accepts: below this there is no tree shape.
pub const MIN_POINTS: usize = 10;

/// Most height, in metres, that the points of one tree may span. The
/// tallest measured trees (coast redwoods, mountain ash) stand 116–132 m;
/// the rest is room for sloping ground in the clip.
pub const MAX_TREE_HEIGHT_M: f32 = 200.0;

/// Most horizontal extent, in metres, that the points of one tree may span
/// (the larger side of their bounding box). The widest single crowns
/// spread 60–80 m; the rest is room for the clip's margins.
pub const MAX_TREE_WIDTH_M: f32 = 200.0;

/// Returns with no neighbour within this many metres of the rest of the
/// cloud are strays ([`crate::cloud::clean::remove_stray_returns`]) when
/// there are only a handful of them: more than any gap inside one tree,
/// from its ground to its crown base, yet birds and atmospheric noise
/// usually lie farther off.
pub const STRAY_GAP_M: f32 = 30.0;

/// Small groups of returns with no other return near them, wholly above or
/// below the rest, are strays too
/// ([`crate::cloud::clean::remove_isolated_groups`]): birds above a crown,
/// multipath returns under the ground. A group holds at most 8 returns;
/// more together are a piece of something. The gap is 3 m, or 20 median
/// point spacings if longer: in synthetic airborne clips at 2 points/m²
/// (spacing 0.35–0.47 m) the top few hits of a poplar lie up to 4 m above
/// the rest of its crown (exact single linkage, a Python prototype over
/// `silva synth --scan als`, seeds 1–24, all four species), and 3 m dropped
/// them on 3 of 40 clips; at 5 and 20 points/m², at most 2.5 m.
///
/// A lone return nearer than the gap above the crown (a bird 2.5 m over
/// it) stays and sets the height. Its heights cannot tell it from a twig
/// tip reached by one pulse: the gap under the highest return over the
/// spread of the next 19, whose tail under [`metrics::apex_gap`]'s dome
/// model is 1.80 at 10⁻⁵, reached 1.17 on 600 synthetic leaf-off clips at
/// 20 points/m² and 1.84 on 200 at 60 (a birch), so no threshold both
/// keeps every real apex and catches a return less than about 1.9 m over
/// an oak's or a birch's highest (median; 3.6 m over a poplar's, 0.7 m
/// over a pine's). Measured with `tools/top_return_gaps.py --model`
/// (seeds 1–150; 1–50 with `--density 60`, leaf-off; 1–50 with
/// `--leaves on`, at most 1.06);
/// ahn3_delft, tiny, tree1 and tree13 reach 0.02–0.15.
pub const ISOLATED_GROUPS: IsolatedGroups = IsolatedGroups {
    min_gap_m: 3.0,
    gap_spacings: 20.0,
    max_group: 8,
    max_share: MAX_STRAY_SHARE,
};

/// Largest share of the points that may be dropped as strays (at least
/// one point): a bigger detached part is a second object, not noise.
pub const MAX_STRAY_SHARE: f32 = 0.01;

/// Which reconstruction pipeline to run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Mode {
    /// Choose from point density and trunk coverage (see [`survey`]).
    #[default]
    Auto,
    /// Terrestrial or mobile scans: the AdTree-style pipeline in [`dense`].
    Dense,
    /// Sparse airborne scans with a thin or missing trunk (Hu et al.).
    Airborne,
}

impl Mode {
    /// The lowercase name used on the command line and in JSON.
    pub fn name(self) -> &'static str {
        match self {
            Mode::Auto => "auto",
            Mode::Dense => "dense",
            Mode::Airborne => "airborne",
        }
    }
}

/// Settings of a reconstruction. `Options::default()` suits both scan kinds.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Options {
    /// Pipeline to run; [`Mode::Auto`] decides per cloud.
    pub mode: Mode,
    /// Settings of the dense pipeline.
    pub dense: dense::Params,
    /// Settings of the airborne pipeline.
    pub airborne: airborne::Params,
    /// Settings of the shared radius stage.
    pub radii: radii::Params,
    /// Thresholds of the automatic mode choice.
    pub auto: AutoThresholds,
    /// When to give up, checked between the steps of the pipelines (never,
    /// by default).
    pub interrupt: Interrupt,
}

/// Thresholds of [`Mode::Auto`]: a cloud is dense when its trunk is seen all
/// around and its crown is sampled densely (by points per m² of crown
/// projection or by point spacing).
#[derive(Debug, Clone, PartialEq)]
pub struct AutoThresholds {
    /// Points per m² of crown projection; terrestrial scans have thousands,
    /// airborne scans (AHN: 10–50) far fewer.
    pub min_density_pts_per_m2: f32,
    /// Share (0–1) of the angular sectors around the lowest metres of the
    /// tree that hold points: a scanned trunk is seen from (nearly) all sides.
    pub min_trunk_coverage: f32,
    /// A median point spacing at or below this, in metres, is dense too: a
    /// slender tree (birch, pine) scanned from the ground has a small crown
    /// projection per point, yet a few centimetres between points, where
    /// airborne scans have 15 cm or more.
    pub max_dense_spacing_m: f32,
}

impl Default for AutoThresholds {
    fn default() -> Self {
        Self {
            min_density_pts_per_m2: 100.0,
            min_trunk_coverage: 0.5,
            max_dense_spacing_m: 0.08,
        }
    }
}

/// Why an airborne tree's wood volume is only indicative: a sparse scan
/// resolves no branch sections, so every branch takes the pipe model's
/// radius (Eq. 6) scaled from the DBH (mostly estimated), over a
/// skeleton whose tip count is not the tree's. Measured with `silva eval
/// --synthetic 20 --scan als --seed S` for S = 1, 101, 201, 301, 401, 501
/// (120 trees, release build): 0.12–4.4 × the true volume, median 1.50;
/// by species oak 0.79–1.28, birch 1.72–2.81, pine 2.14–4.38 (their
/// laterals carry more tips than the tree's) and poplar 0.12–0.34 (the
/// allometric DBH of a columnar crown is a third of the truth).
const AIRBORNE_VOLUME_NOTE: &str = "wood volume is indicative only: an airborne scan shows no \
     branch sections, so branch radii follow the pipe model from the DBH (on synthetic \
     AHN-like scans it came out 0.1 to 4.4 times the true volume, median 1.5)";

/// The mode reason of a pipeline the caller chose.
const REQUESTED: &str = "requested by the caller (--mode on the command line, mode= at upload)";

/// A reconstructed tree.
#[derive(Debug, Clone)]
pub struct Reconstruction {
    /// The skeleton with final radii; its anchor is the absolute trunk base.
    pub skeleton: Skeleton,
    /// Per-tree metrics.
    pub metrics: metrics::TreeMetrics,
    /// The pipeline actually used (never [`Mode::Auto`]).
    pub mode: Mode,
    /// Why that pipeline was used, in words.
    pub mode_reason: String,
    /// Best efforts the caller should know about, e.g. an estimated DBH.
    pub notes: Vec<String>,
}

/// Reconstructs the skeleton, radii and metrics of the one tree in `cloud`.
///
/// ```
/// use glam::{DVec3, Vec3};
/// use silva::cloud::PointCloud;
/// use silva::reconstruct::{reconstruct, Mode, Options};
///
/// // A vertical stem of radius 10 cm, 3 m tall, sampled on its bark.
/// let mut points = Vec::new();
/// for i in 0..3000 {
///     let a = i as f32 * 2.399_963; // golden angle: even cover
///     points.push(Vec3::new(0.1 * a.cos(), 0.1 * a.sin(), 3.0 * i as f32 / 3000.0));
/// }
/// let cloud = PointCloud::from_points(DVec3::new(155_000.0, 463_000.0, 0.0), points);
/// let options = Options { mode: Mode::Dense, ..Options::default() };
/// let tree = reconstruct(&cloud, &options).unwrap();
/// assert!((tree.metrics.dbh_m - 0.2).abs() < 0.02);
/// assert!((tree.skeleton.anchor().origin.x - 155_000.0).abs() < 0.02);
/// ```
pub fn reconstruct(cloud: &PointCloud, opts: &Options) -> Result<Reconstruction, ReconstructError> {
    let interrupt = &opts.interrupt;
    check_points(cloud)?;
    interrupt.check("stray-return removal")?;
    let Denoised {
        cloud: cleaned,
        notes: noise_notes,
        spacing_m,
    } = without_noise(cloud)?;
    let cloud = cleaned.as_ref();
    validate(cloud)?;
    interrupt.check("the choice of pipeline")?;
    let (mode, mode_reason, survey_note) = match opts.mode {
        Mode::Auto => {
            let survey = survey_spaced(cloud, spacing_m, &opts.auto);
            let (mode, reason) = survey.choose(&opts.auto);
            (mode, reason, survey.dense_without_trunk(mode, &opts.auto))
        }
        Mode::Dense | Mode::Airborne => (opts.mode, REQUESTED.to_string(), None),
    };
    let (mut skeleton, tree_cloud, pipeline_notes) = run_pipeline(cloud, mode, opts)?;
    let mut notes: Vec<String> = noise_notes.into_iter().chain(survey_note).collect();
    notes.extend(pipeline_notes);
    interrupt.check("crown measurement")?;
    let crown = measure_crown(&skeleton, &tree_cloud, &mut notes);
    interrupt.check("radius assignment")?;
    let trunk = radii::assign_radii(
        &mut skeleton,
        &tree_cloud,
        &crown,
        &radius_params(&opts.radii, mode),
    );
    notes.extend(trunk.note());
    if mode == Mode::Airborne {
        notes.push(AIRBORNE_VOLUME_NOTE.to_string());
    }
    let metrics = metrics::TreeMetrics::measure(&skeleton, &crown, &trunk);
    Ok(Reconstruction {
        skeleton,
        metrics,
        mode,
        mode_reason,
        notes,
    })
}

/// A cloud as [`without_noise`] leaves it.
struct Denoised<'a> {
    /// Borrowed when nothing was dropped.
    cloud: Cow<'a, PointCloud>,
    /// A note on each kind of return dropped.
    notes: Vec<String>,
    /// The median spacing of `cloud`'s points, when the search for
    /// isolated groups measured it.
    spacing_m: Option<f32>,
}

/// `cloud` without the returns classified as noise, the strays far from
/// the rest ([`STRAY_GAP_M`]) and the small isolated groups
/// ([`ISOLATED_GROUPS`]).
fn without_noise(cloud: &PointCloud) -> Result<Denoised<'_>, ReconstructError> {
    let mut notes = Vec::new();
    let mut cloud = Cow::Borrowed(cloud);
    if let Some((kept, noise)) = clean::remove_classified_noise(&cloud) {
        notes.push(noise_note(noise));
        cloud = Cow::Owned(kept);
        check_points(&cloud)?;
    }
    let mut strays = None;
    if let Some((kept, far)) = clean::remove_stray_returns(&cloud, STRAY_GAP_M, MAX_STRAY_SHARE) {
        cloud = Cow::Owned(kept);
        strays = Some(far);
    }
    let (isolated, mut spacing_m) =
        clean::remove_isolated_groups_measured(&cloud, &ISOLATED_GROUPS);
    if let Some((kept, isolated)) = isolated {
        cloud = Cow::Owned(kept);
        strays = Some(strays.map_or(isolated, |far: Strays| far.merged(isolated)));
        // Measured on the points before the groups went.
        spacing_m = None;
    }
    notes.extend(strays.map(strays_note));
    Ok(Denoised {
        cloud,
        notes,
        spacing_m,
    })
}

/// The skeleton of `mode`'s pipeline (radii not yet final), the tree's
/// points without ground relative to the skeleton's anchor, and the
/// pipeline's notes.
fn run_pipeline(
    cloud: &PointCloud,
    mode: Mode,
    opts: &Options,
) -> Result<(Skeleton, PointCloud, Vec<String>), ReconstructError> {
    Ok(match mode {
        Mode::Dense | Mode::Auto => {
            let out = dense::reconstruct(cloud, &opts.dense, &opts.interrupt)?;
            (out.skeleton, out.cloud, out.notes)
        }
        Mode::Airborne => {
            let out = airborne::reconstruct_within(cloud, &opts.airborne, &opts.interrupt)?;
            (out.skeleton, out.tree, out.notes)
        }
    })
}

/// The radius stage's settings for `mode`'s skeleton. An airborne clip's
/// returns around a branch come from the twigs and leaves about it, not
/// from its bark: measured as sections they read the crown's clumping as
/// girth (single-tip twigs of 6–7 cm and 6.3 times the true wood volume on a
/// synthetic pine), so its radii are the pipe model's alone.
fn radius_params(radii: &radii::Params, mode: Mode) -> radii::Params {
    radii::Params {
        measured_radii: radii.measured_radii && mode != Mode::Airborne,
        ..radii.clone()
    }
}

/// The crown's measures; the tree's height is raised by the expected gap
/// between its highest return and its apex ([`metrics::apex_gap`]), with a
/// note when it shows in centimetres ([`apex_note`]).
///
/// A sparse scan from above rarely hits the apex itself, and a scan from
/// the ground hardly sees the twigs at the top of the crown, which the
/// crown below hides: on 60 occluded synthetic TLS scans (`silva eval
/// --synthetic 60 --scan tls`) the highest point lay a median 0.156 m below
/// the true top (all four species 0.13–0.20 m), and with the gap added the
/// height is a median 0.042 m low, |error| a median 0.081 m (within 0.3 m:
/// 52 → 57 of 60). On clean scans (`--density 1000 --no-occlusion`, 20
/// trees) the error goes from −0.025 to +0.030 m in the median. The
/// estimate is model-based and its scatter is stated in the note.
fn measure_crown(
    skeleton: &Skeleton,
    tree: &PointCloud,
    notes: &mut Vec<String>,
) -> metrics::Crown {
    let mut crown = metrics::Crown::measure(skeleton, tree);
    let apex = metrics::apex_gap(&tree.points);
    notes.extend(apex_note(crown.height_m, &apex));
    crown.height_m += apex.gap_m;
    crown
}

/// Gaps under this (metres) go without a note: the note gives centimetres,
/// and a dense scan's gap of a few millimetres would read "plus 0.00 m
/// (± 0.00 m)" (tree1's did).
const NOTED_APEX_GAP_M: f32 = 0.005;

/// What [`measure_crown`] says about the gap it added to the height of the
/// highest return, `highest_m`.
fn apex_note(highest_m: f32, apex: &metrics::ApexGap) -> Option<String> {
    (apex.gap_m >= NOTED_APEX_GAP_M).then(|| {
        format!(
            "height: highest return {highest_m:.2} m plus {:.2} m expected gap to the apex of a \
             {} top (± {:.2} m, one standard deviation: the gap of one tree scatters about its \
             expectation)",
            apex.gap_m,
            apex.top.name(),
            apex.scatter_m()
        )
    })
}

/// What [`reconstruct`] says about the points it dropped by their class.
fn noise_note(noise: usize) -> String {
    let points = if noise == 1 { "point" } else { "points" };
    format!("{noise} {points} classified as noise ignored (LAS classes 7 and 18)")
}

/// What [`reconstruct`] says about the strays it dropped.
fn strays_note(strays: Strays) -> String {
    let places: Vec<String> = [
        (strays.above, "above"),
        (strays.below, "below"),
        (strays.beside, "beside"),
    ]
    .iter()
    .filter(|(n, _)| *n > 0)
    .map(|(n, place)| format!("{n} {place}"))
    .collect();
    let total = strays.total();
    let returns = if total == 1 { "return" } else { "returns" };
    format!(
        "{total} stray {returns} ignored ({} the tree): no other point within \
         {STRAY_GAP_M:.0} m, or in groups of at most {} above or below the rest with no other \
         point within {:.0} m or {:.0} point spacings (birds, multipath, atmospheric noise or \
         corrupt records)",
        places.join(", "),
        ISOLATED_GROUPS.max_group,
        ISOLATED_GROUPS.min_gap_m,
        ISOLATED_GROUPS.gap_spacings,
    )
}

/// Rejects clouds no pipeline can turn into a tree: too few or non-finite
/// points, points spanning more than [`MAX_TREE_WIDTH_M`] horizontally, or
/// points on one line or one plane.
pub fn validate(cloud: &PointCloud) -> Result<(), ReconstructError> {
    check_points(cloud)?;
    check_width(&cloud.points)?;
    let spread = principal_spreads(&cloud.points);
    // Spreads are standard deviations along the principal axes, largest
    // first. A real tree is never thinner than a millimetre per 10 m.
    if spread[0] < 1e-3 {
        return Err(ReconstructError::Degenerate("all points coincide".into()));
    }
    if spread[1] < 1e-4 * spread[0] {
        return Err(ReconstructError::Degenerate(
            "all points lie on one line".into(),
        ));
    }
    if spread[2] < 1e-4 * spread[0] {
        return Err(ReconstructError::Degenerate(
            "all points lie on one plane".into(),
        ));
    }
    Ok(())
}

/// Rejects too few or non-finite points.
fn check_points(cloud: &PointCloud) -> Result<(), ReconstructError> {
    if cloud.len() < MIN_POINTS {
        return Err(ReconstructError::TooFewPoints {
            found: cloud.len(),
            needed: MIN_POINTS,
        });
    }
    if !cloud.points.iter().all(|p| p.is_finite()) || !cloud.offset.is_finite() {
        return Err(ReconstructError::Degenerate(
            "the cloud has non-finite coordinates".into(),
        ));
    }
    Ok(())
}

/// Rejects points spanning more than [`MAX_TREE_WIDTH_M`] horizontally: two
/// trees 99 km apart were "all points on one line" (their principal axes
/// are), which misled (found by `tools/hostile_uploads.py`).
fn check_width(points: &[Vec3]) -> Result<(), ReconstructError> {
    let (lo, hi) = points.iter().fold(
        (glam::Vec2::INFINITY, glam::Vec2::NEG_INFINITY),
        |(lo, hi), p| (lo.min(p.truncate()), hi.max(p.truncate())),
    );
    let width_m = (hi - lo).max_element();
    if width_m > MAX_TREE_WIDTH_M {
        return Err(ReconstructError::TooWide {
            width_m,
            max_m: MAX_TREE_WIDTH_M,
        });
    }
    Ok(())
}

/// Rejects tree points that span more height than [`MAX_TREE_HEIGHT_M`].
/// Called by the pipelines on the points they grow the skeleton over (after
/// their own noise removal), before the work that scales with height: one
/// return 99 km above a 2000-point crown made the airborne pipeline grow its
/// leader up to it, a trunk point every 0.6 m, and a job ran 90 s to store a
/// 99 km tree (found by `tools/hostile_uploads.py`).
pub(crate) fn check_height<'a>(
    points: impl IntoIterator<Item = &'a Vec3>,
) -> Result<(), ReconstructError> {
    let (low, high) = z_range(points);
    let height_m = high - low;
    if height_m > MAX_TREE_HEIGHT_M {
        return Err(ReconstructError::TooTall {
            height_m,
            max_m: MAX_TREE_HEIGHT_M,
        });
    }
    Ok(())
}

/// The lowest and highest `z` of `points` (infinities when there are none).
pub(crate) fn z_range<'a>(points: impl IntoIterator<Item = &'a Vec3>) -> (f32, f32) {
    points
        .into_iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(p.z), hi.max(p.z))
        })
}

/// A trunk leaning more than this from vertical (degrees) is flagged in a
/// note. The lean is the least-squares drift of the lowest [`LEAN_SHARE`]
/// of the points ([`upright::lean`]). A prototype of it on the raw clouds
/// of `silva synth --scan tls` (seeds 1–60, all four species) measured
/// 0–29° upright, 5° and 24° on tree1 and tree13, and above 30° on 4, 61
/// and 57 of these 62 clouds rotated by 20°, 40° and 60°. The drift of the
/// centroid from the lowest tenth to the next, used before, read low
/// branches as lean (31° and 36° on two upright oaks) and flagged 2, 62 and
/// 56. In `silva reconstruct`, none of 100 upright synthetic TLS scans is
/// flagged (the airborne pipeline does not run this test).
///
/// The trunk's axis over the lowest [`AXIS_LEAN_SHARE`]
/// ([`upright::axis_lean`]) measures the lean too, and the larger counts:
/// the points' slope misses a stout trunk's lean when its slanted lowest end
/// fills the band (tree1 turned 45° about +x: unflagged before, 42° now).
/// On 24 clouds of `silva synth --scan tls` (seeds 1–24) and tree1, tree13
/// and tiny, each
/// turned both ways about x and y, `silva reconstruct` flagged 72 of 108
/// turned by 30° (32 before), 105 of 108 by 45° (104; tiny, which goes to
/// the airborne pipeline, is the rest) and 104 by 60° (104), and none
/// upright; `silva eval --synthetic 100 --scan tls` (seeds 1 and 101, the
/// second with ground) reports the same as before, one lean note each.
const FLAGGED_LEAN_DEG: f32 = 30.0;

/// The share of the height, from the bottom, whose points measure the lean.
const LEAN_SHARE: f32 = 0.15;

/// The share of the height, from the bottom, whose axis also measures the
/// lean ([`upright::axis_lean`]); the larger of the two leans counts.
const AXIS_LEAN_SHARE: f32 = 0.3;

/// A trunk leaning more than this from vertical (degrees) is an error.
const MAX_LEAN_DEG: f32 = 60.0;

/// Checks that the tree stands upright: the lowest part (the trunk) must be
/// narrow and not lean over. Called by the dense pipeline on its cleaned points.
/// Returns a note when the trunk leans enough to suggest a tilted cloud.
///
/// `ground_up`: the up direction of ground that step 0 found tilted (the
/// terrain's normal when its slope is noted, or the 3D ground plane's), when
/// there is such ground. A trunk that stands square to tilted ground (see
/// [`stands_square_to`]) gets no note of its own: the ground's note already
/// says that the cloud looks tilted and by how much, and gives the turn that
/// levels it. Measured against +z, such a trunk's lean read 30° on a plot
/// scan turned 60°, whose ground's note read 60°.
pub(crate) fn check_upright(
    points: &[Vec3],
    base_z: f32,
    top_z: f32,
    ground_up: Option<Vec3>,
) -> Result<Option<String>, ReconstructError> {
    let height = top_z - base_z;
    let band =
        |lo: f32, hi: f32| upright::slice(points, base_z + lo * height, base_z + hi * height);
    let low = band(0.0, 0.1);
    let high = band(0.9, 1.0);
    let (_, low_r) = horizontal_spread(&low);
    let (_, high_r) = horizontal_spread(&high);
    // A lying tree fills its lowest tenth of "height" along its whole length.
    if low_r > 0.5 * height {
        return Err(ReconstructError::Degenerate(format!(
            "the lowest tenth of the cloud spreads {low_r:.1} m sideways for a height of \
             {height:.1} m: the tree looks tilted or lying"
        )));
    }
    // Upside down: a narrow "trunk" on top of a wide "crown".
    if low_r > 4.0 * high_r.max(0.02) && low_r > 0.15 * height {
        return Err(ReconstructError::Degenerate(format!(
            "the cloud is wide at the bottom ({low_r:.1} m) and narrow at the top \
             ({high_r:.2} m): the tree looks upside down"
        )));
    }
    let lean_deg = trunk_lean_deg(points, base_z, top_z);
    let square = ground_up.is_some_and(|up| stands_square_to(points, up, lean_deg));
    if low.is_empty() || lean_deg <= FLAGGED_LEAN_DEG || square {
        return Ok(None);
    }
    if lean_deg > MAX_LEAN_DEG {
        return Err(ReconstructError::Degenerate(format!(
            "the trunk leans {lean_deg:.0}° from vertical: the cloud looks tilted"
        )));
    }
    Ok(Some(format!(
        "the trunk leans {lean_deg:.0}° from vertical: if the tree stands upright, the cloud is \
         tilted and the skeleton follows the tilt (silva assumes the z axis points up)"
    )))
}

/// The trunk's lean from vertical in degrees, for a cloud between heights
/// `base_z` and `top_z`: the larger of the slope of the points in the lowest
/// [`LEAN_SHARE`] ([`upright::lean`]) and of the axis in the lowest
/// [`AXIS_LEAN_SHARE`] ([`upright::axis_lean`]).
fn trunk_lean_deg(points: &[Vec3], base_z: f32, top_z: f32) -> f32 {
    let height = top_z - base_z;
    let low = upright::slice(points, base_z, base_z + LEAN_SHARE * height);
    let axis_top = base_z + AXIS_LEAN_SHARE * height;
    upright::lean(&low)
        .length()
        .max(upright::axis_lean(points, base_z, axis_top).length())
        .atan()
        .to_degrees()
}

/// A trunk within this angle (degrees) of tilted ground's normal stands
/// square to it ([`stands_square_to`]). With `silva reconstruct` on plot
/// scans (`silva synth --scan tls --ground-radius 4`, the four species,
/// seeds 1–8) turned 30°, 45° and 60° about x and about y, the trunk's
/// angle to its ground's normal measured 1.5° in the median, 6.6° at the
/// 95th percentile and over 12° on 2 of 151 (an oak, 18° and 33°); on
/// the same plots with a 20° slope, their trees turned 40° about their
/// base downhill, 19.5–25° (oaks 30–36°), and turned sideways 34–69°.
const SQUARE_TO_GROUND_DEG: f32 = 15.0;

/// True when the trunk stands square to tilted ground whose normal is `up`:
/// within [`SQUARE_TO_GROUND_DEG`] of it, and nearer to it than to +z,
/// from which it leans `lean_deg`. The angle to `up` is [`trunk_lean_deg`]
/// in the cloud turned so that `up` is +z, as that measure reads small
/// leans best: measured against +z, the same trunks read 28–66° on the
/// plot scans turned 30° and 26–68° (median 29°) on those turned 60°.
/// Tilted ground and a trunk square to it are a tilted cloud, or a tree on
/// a hillside leaning downhill by about the slope; from the cloud alone the
/// two look the same, and the ground's note names both.
fn stands_square_to(points: &[Vec3], up: Vec3, lean_deg: f32) -> bool {
    let Some(up) = up.try_normalize() else {
        return false;
    };
    let level = glam::Quat::from_rotation_arc(up, Vec3::Z);
    let levelled: Vec<Vec3> = points.iter().map(|&p| level * p).collect();
    let (base_z, top_z) = z_range(&levelled);
    let square_deg = trunk_lean_deg(&levelled, base_z, top_z);
    square_deg <= SQUARE_TO_GROUND_DEG && square_deg < lean_deg
}

/// Horizontal centroid of `points` and their RMS horizontal distance to it,
/// in metres; the origin and 0 for none.
fn horizontal_spread(points: &[Vec3]) -> (glam::Vec2, f32) {
    if points.is_empty() {
        return (glam::Vec2::ZERO, 0.0);
    }
    let n = points.len() as f32;
    let c = points.iter().map(|p| p.truncate()).sum::<glam::Vec2>() / n;
    let ms = points
        .iter()
        .map(|p| p.truncate().distance_squared(c))
        .sum::<f32>()
        / n;
    (c, ms.sqrt())
}

/// Standard deviations of the points along their principal axes, largest
/// first (eigenvalues of the covariance matrix by Jacobi rotations).
pub(crate) fn principal_spreads(points: &[Vec3]) -> [f64; 3] {
    let mut ev = symmetric_eigenvalues(covariance(points));
    ev.sort_by(|a, b| b.total_cmp(a));
    ev.map(|v| v.max(0.0).sqrt())
}

/// Unit direction along which the points spread least (the eigenvector of
/// the smallest covariance eigenvalue): the axis of a thin band of points
/// around a stem. `None` for fewer than three points or a degenerate spread.
pub(crate) fn least_spread_axis(points: &[Vec3]) -> Option<Vec3> {
    if points.len() < 3 {
        return None;
    }
    let c = covariance(points);
    let smallest = symmetric_eigenvalues(c)
        .into_iter()
        .fold(f64::INFINITY, f64::min);
    // The rows of C − λI span the plane across the eigenvector; their
    // largest cross product is the eigenvector itself.
    let rows = c.map(DVec3::from);
    let rows = [0, 1, 2].map(|i| rows[i] - DVec3::AXES[i] * smallest);
    [(0, 1), (0, 2), (1, 2)]
        .map(|(a, b)| rows[a].cross(rows[b]))
        .into_iter()
        .max_by(|a, b| a.length_squared().total_cmp(&b.length_squared()))
        .and_then(|v| v.try_normalize())
        .map(|v| v.as_vec3())
}

/// Covariance matrix of the points about their mean.
fn covariance(points: &[Vec3]) -> [[f64; 3]; 3] {
    let n = points.len().max(1) as f64;
    let mean = points.iter().map(|p| p.as_dvec3()).sum::<DVec3>() / n;
    let mut c = [[0.0f64; 3]; 3];
    for p in points {
        let d = p.as_dvec3() - mean;
        let d = [d.x, d.y, d.z];
        for i in 0..3 {
            for j in 0..3 {
                c[i][j] += d[i] * d[j] / n;
            }
        }
    }
    c
}

/// Eigenvalues of a symmetric 3×3 matrix by cyclic Jacobi rotations.
fn symmetric_eigenvalues(mut a: [[f64; 3]; 3]) -> [f64; 3] {
    for _ in 0..50 {
        let off = a[0][1].abs() + a[0][2].abs() + a[1][2].abs();
        if off < 1e-15 * (a[0][0].abs() + a[1][1].abs() + a[2][2].abs()) || off == 0.0 {
            break;
        }
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            if a[p][q] == 0.0 {
                continue;
            }
            let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
            // Numerical Recipes' stable choice of the rotation angle.
            let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
            let cs = 1.0 / (t * t + 1.0).sqrt();
            let sn = t * cs;
            // Apply the rotation J^T A J on rows/columns p and q.
            for row in a.iter_mut() {
                let (akp, akq) = (row[p], row[q]);
                row[p] = cs * akp - sn * akq;
                row[q] = sn * akp + cs * akq;
            }
            let (row_p, row_q) = (a[p], a[q]);
            for k in 0..3 {
                a[p][k] = cs * row_p[k] - sn * row_q[k];
                a[q][k] = sn * row_p[k] + cs * row_q[k];
            }
        }
    }
    [a[0][0], a[1][1], a[2][2]]
}

/// What [`Mode::Auto`] looks at: how densely the crown is sampled and how
/// well the trunk is seen from all sides.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Survey {
    /// Points per m² of the crown's projected footprint (0.5 m cells).
    pub density_pts_per_m2: f32,
    /// Share (0–1) of the 8 angular sectors around the stem that hold points,
    /// averaged over the 0.25 m slices of the lowest 2 m. When that is below
    /// the thresholds' minimum in a dense cloud that stands on several stems
    /// metres apart, it is measured about the largest of them instead.
    pub trunk_coverage: f32,
    /// Median distance between a point and its nearest neighbour, in metres,
    /// over a sample of points (`NaN` when not measured).
    pub spacing_m: f32,
}

/// Measures the cloud for the automatic mode choice under the thresholds
/// `t` (which decide whether the trunk coverage is worth measuring about
/// each stem, see [`Survey::trunk_coverage`]). Ground points (LAS class 2)
/// are ignored when the cloud is classified.
pub fn survey(cloud: &PointCloud, t: &AutoThresholds) -> Survey {
    survey_spaced(cloud, None, t)
}

/// [`survey`], with the median spacing of all of `cloud`'s points when it
/// is known already (see [`clean::remove_isolated_groups_measured`]); it
/// stands for the sample's when no ground point is left out.
fn survey_spaced(cloud: &PointCloud, spacing_m: Option<f32>, t: &AutoThresholds) -> Survey {
    let pts: Vec<Vec3> = match &cloud.classification {
        Some(class) => cloud
            .points
            .iter()
            .zip(class)
            .filter(|&(_, &c)| c != crate::cloud::CLASS_GROUND)
            .map(|(p, _)| *p)
            .collect(),
        None => cloud.points.clone(),
    };
    let mut survey = Survey {
        density_pts_per_m2: footprint_density(&pts),
        trunk_coverage: trunk_coverage(&pts),
        spacing_m: sampled_spacing(&pts, spacing_m.filter(|_| pts.len() == cloud.len())),
    };
    if survey.crown_dense(t) && survey.trunk_coverage < t.min_trunk_coverage {
        if let Some(coverage) = largest_stem_coverage(&pts) {
            survey.trunk_coverage = coverage;
        }
    }
    survey
}

impl Survey {
    /// The pipeline these figures call for, and why.
    pub fn choose(&self, t: &AutoThresholds) -> (Mode, String) {
        let dense = self.crown_dense(t) && self.trunk_coverage >= t.min_trunk_coverage;
        let (mode, verdict) = if dense {
            (Mode::Dense, "dense scan")
        } else {
            (Mode::Airborne, "sparse scan or trunk not seen all around")
        };
        // Huge clouds skip the spacing sample (NaN): say so, not "NaN m".
        let spacing = if self.spacing_m.is_finite() {
            format!("{:.3} m", self.spacing_m)
        } else {
            "not sampled".to_string()
        };
        let reason = format!(
            "{verdict}: {:.0} points/m² of crown projection (dense from {:.0}), trunk coverage \
             {:.2} (dense from {:.2}), median point spacing {spacing} (dense up to {:.3} m)",
            self.density_pts_per_m2,
            t.min_density_pts_per_m2,
            self.trunk_coverage,
            t.min_trunk_coverage,
            t.max_dense_spacing_m
        );
        (mode, reason)
    }

    /// True when the crown's points lie as densely as a terrestrial scan's.
    fn crown_dense(&self, t: &AutoThresholds) -> bool {
        self.density_pts_per_m2 >= t.min_density_pts_per_m2
            || self.spacing_m <= t.max_dense_spacing_m
    }

    /// A note when `mode` is the airborne pipeline although the points lie
    /// as close as a terrestrial scan's: no trunk was seen all around at
    /// the bottom of a dense cloud. A scan from one side or a hidden trunk
    /// base does that, and so does a cloud tilted or lying on its side (an
    /// oak's TLS scan turned 90° about x: trunk coverage 0.38, median
    /// spacing 0.043 m), which no other test flags. Two trees whose crowns
    /// touch did too, until the coverage was measured about the larger of
    /// their stems ([`Survey::trunk_coverage`]); stems that go unseen still
    /// do.
    pub fn dense_without_trunk(&self, mode: Mode, t: &AutoThresholds) -> Option<String> {
        let flagged = mode == Mode::Airborne
            && self.spacing_m <= t.max_dense_spacing_m
            && self.trunk_coverage < t.min_trunk_coverage;
        flagged.then(|| {
            format!(
                "the points lie as close as a terrestrial scan's (median spacing {:.3} m) but no \
                 trunk is seen all around at the bottom (coverage {:.2}), so the airborne pipeline \
                 ran: if this is a terrestrial scan, check that the tree stands on the z axis \
                 (silva assumes the z axis points up), that its trunk base was scanned, and that \
                 the cloud holds one tree (`--mode dense` refuses two whose crowns touch, for \
                 their two stems)",
                self.spacing_m, self.trunk_coverage
            )
        })
    }
}

/// Points per m² of occupied 0.5 m × 0.5 m ground cells.
fn footprint_density(points: &[Vec3]) -> f32 {
    const CELL_M: f32 = 0.5;
    let mut cells: Vec<(i64, i64)> = points
        .iter()
        .map(|p| ((p.x / CELL_M).floor() as i64, (p.y / CELL_M).floor() as i64))
        .collect();
    cells.sort_unstable();
    cells.dedup();
    points.len() as f32 / (cells.len().max(1) as f32 * CELL_M * CELL_M)
}

/// Mean share of occupied angular sectors around the stem in the lowest 2 m.
fn trunk_coverage(points: &[Vec3]) -> f32 {
    const SLICE_M: f32 = 0.25;
    const SLICES: usize = 8;
    const SECTORS: usize = 8;
    let Some(base_z) = points.iter().map(|p| p.z).min_by(f32::total_cmp) else {
        return 0.0;
    };
    let mut slices: Vec<Vec<Vec3>> = vec![Vec::new(); SLICES];
    for p in points {
        let k = ((p.z - base_z) / SLICE_M) as usize;
        if k < SLICES {
            slices[k].push(*p);
        }
    }
    let mut total = 0.0;
    for slice in &slices {
        if slice.len() < SECTORS {
            continue;
        }
        let (c, _) = horizontal_spread(slice);
        let flat: Vec<glam::Vec2> = slice.iter().map(|p| p.truncate()).collect();
        total += radii::sectors_seen(&flat, c, SECTORS) as f32 / SECTORS as f32;
    }
    total / SLICES as f32
}

/// [`trunk_coverage`] of the points nearest the largest of the stems the
/// cloud stands on, when it stands on several metres apart
/// ([`parts::stems_apart`]); `None` otherwise. About the centre of two
/// trunks each fills a sector or two: two terrestrial scans of trees whose
/// crowns touch went to the airborne pipeline for that, where nothing told
/// them from one tree, whereas the dense pipeline refuses them for their
/// stems. `tools/tls_pairs.py` (200 pairs of `silva synth --scan tls`
/// clouds, trunks 2–8 m apart, in `--mode auto`): 5 pairs (trunks 4–8 m
/// apart) went airborne before, none since; all 200 are refused.
fn largest_stem_coverage(points: &[Vec3]) -> Option<f32> {
    let heights: Vec<f32> = points.iter().map(|p| p.z).collect();
    let lowest = heights.iter().copied().fold(f32::INFINITY, f32::min);
    let stems = parts::stems_apart(points, &heights, lowest);
    let [largest, others @ ..] = &stems[..] else {
        return None;
    };
    if others.is_empty() {
        return None;
    }
    let nearest_largest: Vec<Vec3> = points
        .iter()
        .filter(|p| {
            let d = p.truncate().distance(largest.centre);
            others.iter().all(|s| p.truncate().distance(s.centre) >= d)
        })
        .copied()
        .collect();
    Some(trunk_coverage(&nearest_largest))
}

/// Median nearest-neighbour distance over up to 2,000 evenly picked points,
/// or the one `measured` on the same points already.
fn sampled_spacing(points: &[Vec3], measured: Option<f32>) -> f32 {
    if points.len() < 2 || points.len() > 2_000_000 {
        return f32::NAN;
    }
    measured.unwrap_or_else(|| {
        crate::spatial::PointIndex::new(points)
            .median_spacing(points)
            .unwrap_or(f32::NAN)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A vertical stem of radius 10 cm, `height` m tall, sampled on its bark.
    fn stem(height: f32) -> Vec<Vec3> {
        (0..3000)
            .map(|i| {
                let a = i as f32 * 2.399_963;
                Vec3::new(0.1 * a.cos(), 0.1 * a.sin(), height * i as f32 / 3000.0)
            })
            .collect()
    }

    #[test]
    fn only_a_gap_that_shows_in_centimetres_gets_a_note() {
        let gap = |gap_m| metrics::ApexGap {
            gap_m,
            top: metrics::CrownTop::Dome,
        };
        assert_eq!(apex_note(5.53, &gap(0.002)), None);
        let note = apex_note(10.0, &gap(0.25)).expect("a noted gap");
        assert!(
            note.contains("highest return 10.00 m plus 0.25 m"),
            "{note}"
        );
    }

    fn dense(points: Vec<Vec3>) -> Result<Reconstruction, ReconstructError> {
        let cloud = PointCloud::from_points(DVec3::new(155_000.0, 463_000.0, 0.0), points);
        let options = Options {
            mode: Mode::Dense,
            ..Options::default()
        };
        reconstruct(&cloud, &options)
    }

    /// A trunk 0.8 m thick and 2 m tall under a crown of 40 twigs, 7 m tall.
    fn stout_tree() -> Vec<Vec3> {
        let bark = |i: usize, n: usize, radius: f32, z0: f32, z1: f32| {
            let a = i as f32 * 2.399_963;
            let z = z0 + (z1 - z0) * i as f32 / n as f32;
            Vec3::new(radius * a.cos(), radius * a.sin(), z)
        };
        let mut tree: Vec<Vec3> = (0..4000).map(|i| bark(i, 4000, 0.4, 0.0, 2.0)).collect();
        for k in 0..40 {
            let a = k as f32 * 2.399_963;
            let tip = Vec3::new(2.0 * a.cos(), 2.0 * a.sin(), 3.0 + (k % 5) as f32);
            let from = Vec3::new(0.0, 0.0, 2.0);
            tree.extend((0..100).map(|i| from.lerp(tip, i as f32 / 100.0)));
        }
        tree
    }

    /// The lean check's verdict on `points` with `ground_up`: its note or
    /// its error, `None` for neither.
    fn lean_flag(points: &[Vec3], ground_up: Option<Vec3>) -> Option<String> {
        let (low, high) = z_range(points);
        match check_upright(points, low, high, ground_up) {
            Ok(note) => note,
            Err(e) => Some(e.to_string()),
        }
    }

    /// A stout trunk turned 45°: the slope of its lowest points reads the
    /// slanted bark across its lowest end, far under 45°; its axis does not.
    #[test]
    fn a_stout_trunk_turned_45_degrees_is_flagged_by_its_axis() {
        let tree = stout_tree();
        let turn = glam::Quat::from_rotation_x(45f32.to_radians());
        let tilted: Vec<Vec3> = tree.iter().map(|&p| turn * p).collect();
        let (low, high) = z_range(&tilted);
        let band = upright::slice(&tilted, low, low + LEAN_SHARE * (high - low));
        let slope_deg = upright::lean(&band).length().atan().to_degrees();
        assert!(slope_deg < FLAGGED_LEAN_DEG, "{slope_deg}");
        let flag = lean_flag(&tilted, None).expect("a 45° tilt is flagged");
        assert!(flag.contains("leans") && flag.contains("tilted"), "{flag}");
        assert_eq!(check_upright(&tree, 0.0, 7.0, None), Ok(None));
    }

    /// Turned 45° with its ground, a trunk stands square to that ground,
    /// whose note gives the tilt: the lean check adds no note of its own
    /// (it would read another angle). Over level ground, or ground tilted
    /// the other way, the trunk's lean is still flagged.
    #[test]
    fn a_trunk_square_to_tilted_ground_leaves_the_tilt_to_the_grounds_note() {
        let turn = glam::Quat::from_rotation_x(45f32.to_radians());
        let tilted: Vec<Vec3> = stout_tree().iter().map(|&p| turn * p).collect();
        assert_eq!(lean_flag(&tilted, Some(turn * Vec3::Z)), None);
        let other_way = glam::Quat::from_rotation_x(-45f32.to_radians()) * Vec3::Z;
        for ground_up in [Some(Vec3::Z), Some(other_way)] {
            let flag = lean_flag(&tilted, ground_up).expect("the lean is flagged");
            assert!(flag.contains("leans"), "{flag}");
        }
    }

    /// A passed deadline stops each pipeline at its first step; the default
    /// interrupt never does.
    #[test]
    fn a_passed_deadline_stops_the_pipelines_at_their_first_step() {
        use crate::interrupt::Interrupted;

        let passed = Interrupt::at(Some(std::time::Instant::now()));
        let cloud = PointCloud::from_points(DVec3::ZERO, stem(3.0));
        let options = Options {
            interrupt: passed,
            ..Options::default()
        };
        let err = reconstruct(&cloud, &options).unwrap_err();
        let first = Interrupted {
            step: "stray-return removal",
        };
        assert_eq!(err, ReconstructError::Interrupted(first));
        assert_eq!(
            err.to_string(),
            "reconstruction interrupted at its deadline before stray-return removal"
        );
        let err = dense::reconstruct(&cloud, &options.dense, &passed).unwrap_err();
        let step = Interrupted { step: "clean-up" };
        assert_eq!(err, ReconstructError::Interrupted(step));
        let err = airborne::reconstruct_within(&cloud, &options.airborne, &passed).unwrap_err();
        let step = Interrupted {
            step: "ground separation",
        };
        assert_eq!(err, ReconstructError::Interrupted(step));
        assert!(dense(stem(3.0)).is_ok());
    }

    #[test]
    fn stray_returns_kilometres_away_are_dropped_with_a_note() {
        let clean = dense(stem(3.0)).unwrap();
        let mut points = stem(3.0);
        points.push(Vec3::new(0.0, 0.0, 99_000.0));
        points.push(Vec3::new(-5_000.0, 0.0, 1.0));
        let tree = dense(points).unwrap();
        assert_eq!(tree.metrics, clean.metrics);
        let note = &tree.notes[0];
        assert!(
            note.starts_with("2 stray returns ignored (1 above, 1 beside the tree)"),
            "{note}"
        );
        assert_eq!(tree.notes[1..], clean.notes[..]);
    }

    /// A bird 15 m above the top and two multipath returns 5–6 m under the
    /// base: nearer than the 30 m strays, but alone within 3 m. Kept, they
    /// made an AHN tree 52.7 m tall and a terrestrial scan "upside down".
    #[test]
    fn returns_alone_a_few_metres_off_are_dropped_with_a_note() {
        let clean = dense(stem(3.0)).unwrap();
        let mut points = stem(3.0);
        points.push(Vec3::new(0.5, 0.0, 18.0));
        points.extend([Vec3::new(0.0, 0.3, -5.0), Vec3::new(0.2, 0.0, -6.0)]);
        let tree = dense(points).unwrap();
        assert_eq!(tree.metrics, clean.metrics);
        let note = &tree.notes[0];
        assert!(
            note.starts_with("3 stray returns ignored (1 above, 2 below the tree)"),
            "{note}"
        );
        assert!(note.contains("groups of at most 8"), "{note}");
        assert_eq!(tree.notes[1..], clean.notes[..]);
    }

    #[test]
    fn a_tree_too_tall_or_too_wide_is_refused_not_trimmed() {
        let err = dense(stem(250.0)).unwrap_err();
        assert!(matches!(err, ReconstructError::TooTall { .. }), "{err}");
        let mut two = stem(3.0);
        two.extend(
            stem(3.0)
                .iter()
                .map(|p| *p + Vec3::new(99_000.0, 99_000.0, 0.0)),
        );
        let err = dense(two).unwrap_err();
        assert!(
            matches!(err, ReconstructError::TooWide { width_m, max_m: MAX_TREE_WIDTH_M } if width_m > 98_000.0),
            "{err}"
        );
        assert!(err.to_string().contains("horizontally"), "{err}");
    }

    #[test]
    fn a_huge_clouds_unsampled_spacing_is_named_not_printed_as_nan() {
        let survey = Survey {
            density_pts_per_m2: 5000.0,
            trunk_coverage: 1.0,
            spacing_m: f32::NAN,
        };
        let (mode, reason) = survey.choose(&AutoThresholds::default());
        assert_eq!(mode, Mode::Dense);
        assert!(reason.contains("spacing not sampled"), "{reason}");
        assert!(!reason.contains("NaN"), "{reason}");
    }

    #[test]
    fn eigenvalues_of_a_diagonal_and_a_rotated_matrix() {
        let ev = symmetric_eigenvalues([[3.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 2.0]]);
        let mut ev = ev.to_vec();
        ev.sort_by(f64::total_cmp);
        assert_eq!(ev, vec![1.0, 2.0, 3.0]);
        // [[2,1,0],[1,2,0],[0,0,5]] has eigenvalues 1, 3, 5.
        let mut ev =
            symmetric_eigenvalues([[2.0, 1.0, 0.0], [1.0, 2.0, 0.0], [0.0, 0.0, 5.0]]).to_vec();
        ev.sort_by(f64::total_cmp);
        for (a, b) in ev.iter().zip([1.0, 3.0, 5.0]) {
            assert!((a - b).abs() < 1e-9, "{ev:?}");
        }
    }

    #[test]
    fn a_tilted_band_of_points_has_its_axis_as_least_spread_axis() {
        let axis = Vec3::new(0.3, -0.2, 1.0).normalize();
        let e1 = axis.any_orthonormal_vector();
        let e2 = axis.cross(e1);
        let band: Vec<Vec3> = (0..200)
            .map(|i| {
                let a = i as f32 * 0.1;
                let h = 0.01 * ((i % 7) as f32 - 3.0);
                (e1 * a.cos() + e2 * a.sin()) * 0.3 + axis * h
            })
            .collect();
        let found = least_spread_axis(&band).expect("axis of a band");
        assert!(found.dot(axis).abs() > 0.999, "{found} vs {axis}");
        assert_eq!(least_spread_axis(&band[..2]), None);
    }

    #[test]
    fn a_dense_cloud_sent_to_the_airborne_pipeline_is_flagged() {
        let t = AutoThresholds::default();
        let survey = |spacing_m, trunk_coverage| Survey {
            density_pts_per_m2: 50.0,
            trunk_coverage,
            spacing_m,
        };
        let note = survey(0.043, 0.38)
            .dense_without_trunk(Mode::Airborne, &t)
            .expect("a note");
        assert!(
            note.contains("0.043 m") && note.contains("z axis points up"),
            "{note}"
        );
        // An airborne clip's returns lie farther apart; a dense pipeline run
        // saw its trunk; a NaN spacing (not sampled) is not dense.
        assert_eq!(
            survey(0.13, 0.25).dense_without_trunk(Mode::Airborne, &t),
            None
        );
        assert_eq!(
            survey(0.043, 0.38).dense_without_trunk(Mode::Dense, &t),
            None
        );
        assert_eq!(
            survey(f32::NAN, 0.0).dense_without_trunk(Mode::Airborne, &t),
            None
        );
    }
}
