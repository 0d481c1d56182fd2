//! One evaluation row per tree: reconstruct (timed, median of repeats), then
//! measure against the truth (synthetic trees) or the points (real clouds).
//!
//! Plain computation: the CLI (`silva eval`) reads files and writes the
//! report; this module only turns a cloud (and maybe its truth) into a row.

use std::time::Duration;

use serde::Serialize;

use super::compare::{SkeletonComparison, compare_scanned};
use super::fit::{SurfaceFit, surface_fit};
use super::mesh_fit::mesh_fit;
use super::report::{Source, timed_median};
use crate::cityjson::lod_figures;
use crate::cloud::PointCloud;
use crate::encode::lsystem::{self, LsJson, LsOptions};
use crate::encode::{chaincode, gzip_len};
use crate::mesh::{Lod, build_mesh};
use crate::reconstruct::ground::split_ground;
use crate::reconstruct::metrics::{OrderStats, TreeMetrics, order_stats, wood_volume_m3};
use crate::reconstruct::{Mode, Options, Reconstruction, reconstruct};
use crate::skeleton::{Anchor, NodeId, Skeleton};
use crate::synth::{Species, TreeParams, generate};
use glam::DVec3;

/// Breast height for DBH, in metres above the trunk base.
const BREAST_HEIGHT_M: f32 = 1.3;

/// How to evaluate.
#[derive(Debug, Clone)]
pub struct EvalOptions {
    /// Reconstruction settings (mode auto by default).
    pub reconstruct: Options,
    /// Reconstructions per tree; the median wall time is reported.
    pub repeat: usize,
    /// Tolerance of recall and precision against a truth, in metres.
    pub tolerance_m: f32,
    /// Truth internodes thinner than this do not count towards recall.
    pub min_truth_radius_m: f32,
    /// The leaves the scan saw (airborne simulations): the true height is
    /// then the top of the foliage, not of the wood. `None`: wood only.
    pub foliage: Option<crate::synth::Foliage>,
}

/// Tree `i` of `silva eval --synthetic N --seed FIRST`: the species in
/// turn ([`Species::ALL`]), seed `FIRST + i`, standing 30 m east of the one
/// before it in EPSG:28992, so that large coordinates are exercised too.
/// Diagnostics that reproduce the eval's trees build them here.
///
/// ```
/// use silva::eval::run::SyntheticTree;
/// use silva::synth::Species;
/// let tree = SyntheticTree::nth(5, 1);
/// assert_eq!((tree.species, tree.seed), (Species::ALL[1], 6));
/// assert_eq!(tree.truth.anchor().origin.x, 155_150.0);
/// ```
#[derive(Debug, Clone)]
pub struct SyntheticTree {
    /// Its species' preset.
    pub species: Species,
    /// The seed of the generator and of the scan simulations.
    pub seed: u64,
    /// The generated skeleton, the truth the reconstruction is measured
    /// against.
    pub truth: Skeleton,
}

impl SyntheticTree {
    /// Tree `i` of the run whose first seed is `first_seed`.
    pub fn nth(i: usize, first_seed: u64) -> Self {
        let species = Species::ALL[i % Species::ALL.len()];
        let seed = first_seed + i as u64;
        let anchor = Anchor {
            origin: DVec3::new(155_000.0 + 30.0 * i as f64, 463_000.0, 1.5),
            crs: Some("EPSG:28992".into()),
        };
        let truth = generate(&TreeParams::preset(species), seed, anchor);
        Self {
            species,
            seed,
            truth,
        }
    }
}

/// Figures against a known skeleton.
#[derive(Debug, Clone, Serialize)]
pub struct TruthFigures {
    /// Tolerance used for recall and precision, in metres.
    pub tolerance_m: f32,
    /// Minimum truth radius counted in recall, in metres.
    pub min_truth_radius_m: f32,
    /// Share of the (radius-filtered) truth length found.
    pub recall: f32,
    /// Share of the reconstructed length near the truth.
    pub precision: f32,
    /// Recall over the truth a scan can see: truth inside thicker truth
    /// wood left out (`compare::SkeletonComparison::visible_recall`). A
    /// diagnostic; `recall` is the figure of record.
    pub visible_recall: f32,
    /// Share of the radius-filtered truth length inside thicker truth wood.
    pub hidden_share: f32,
    /// Recall over the truth that has a point of the scan on its bark
    /// (`compare::SkeletonComparison::scanned_recall`): what the pipeline
    /// made of what the scanners hit. A diagnostic; `None` when no truth
    /// has a scan point on its bark (an airborne clip often has none).
    pub scanned_recall: Option<f32>,
    /// Share of the radius-filtered truth length with a scan point on its
    /// bark.
    pub scanned_share: f32,
    /// Mean symmetric skeleton distance, in metres.
    pub mean_distance_m: f32,
    /// 95th percentile of the symmetric skeleton distance, in metres.
    pub p95_distance_m: f32,
    /// Reconstructed minus true height, in metres (the true top is that of
    /// the foliage when [`EvalOptions::foliage`] is set, else of the wood).
    pub height_error_m: f32,
    /// Reconstructed minus true DBH, in metres.
    pub dbh_error_m: f32,
    /// Horizontal distance between the true and reconstructed trunk base, in metres.
    pub trunk_base_offset_m: f32,
    /// Wood volume of the true skeleton ([`wood_volume_m3`]), m³.
    pub true_volume_m3: f32,
    /// Reconstructed wood volume divided by the true one (1 is exact).
    pub volume_ratio: f32,
    /// Reconstructed total branch length (the metric
    /// `total_branch_length_m`) divided by the true one.
    pub length_ratio: f32,
    /// Reconstructed branch count (all orders, the metric `branch_orders`)
    /// divided by the true one.
    pub branch_count_ratio: f32,
}

/// One tree's row of the report.
#[derive(Debug, Clone, Serialize)]
pub struct TreeRow {
    /// File name or synthetic tree name.
    pub name: String,
    /// Real data or synthetic.
    pub source: Source,
    /// Points in the input cloud.
    pub points: usize,
    /// Pipeline used.
    pub mode: Option<Mode>,
    /// Why that pipeline.
    pub mode_reason: Option<String>,
    /// Median wall time of one reconstruction, in milliseconds.
    pub wall_time_ms: f64,
    /// Number of timed reconstructions.
    pub runs: usize,
    /// Input points per second of reconstruction.
    pub points_per_s: f64,
    /// Skeleton nodes.
    pub nodes: usize,
    /// Tree metrics of the reconstruction.
    pub metrics: Option<TreeMetrics>,
    /// Against the truth, for synthetic trees.
    pub truth: Option<TruthFigures>,
    /// Point-to-surface fit of the cylinders, for dense reconstructions.
    pub fit: Option<SurfaceFit>,
    /// Point-to-surface fit of the LOD 3 triangle mesh, for dense
    /// reconstructions.
    pub mesh_fit: Option<SurfaceFit>,
    /// Best efforts flagged by the reconstruction.
    pub notes: Vec<String>,
    /// Encoding figures (issue 4).
    pub encoding: Option<EncodingFigures>,
    /// Mesh figures per LOD (issue 5).
    pub lods: Vec<LodRow>,
    /// The reconstruction's error, when it failed.
    pub error: Option<String>,
}

/// LsJSON and chain-code figures of one skeleton.
#[derive(Debug, Clone, Serialize)]
pub struct EncodingFigures {
    /// Internodes of the skeleton.
    pub internodes: usize,
    /// LsJSON size, raw, in bytes.
    pub lsjson_bytes: usize,
    /// LsJSON size, gzip, in bytes.
    pub lsjson_gzip_bytes: usize,
    /// Largest decoded node error of the LsJSON, in metres.
    pub lsjson_max_error_m: f64,
    /// Mean decoded node error of the LsJSON, in metres.
    pub lsjson_mean_error_m: f64,
    /// LsJSON encode time, in milliseconds.
    pub lsjson_encode_ms: f64,
    /// LsJSON parse + decode time, in milliseconds.
    pub lsjson_decode_ms: f64,
    /// Chain code figures at r = 3, 5 and 10.
    pub chain: Vec<ChainRow>,
}

/// Chain code figures at one resolution: the sizes, node error and LOD
/// levels of [`chaincode::stats`], and the decoding time.
#[derive(Debug, Clone, Serialize)]
pub struct ChainRow {
    /// Sizes, error and levels of detail.
    #[serde(flatten)]
    pub code: chaincode::ChainStats,
    /// Encode + compress time (`chaincode::encode` with the default
    /// options, which try every step prediction, then `compress`: skeleton
    /// to bytes, as storage does it), median of 3 runs, in milliseconds.
    pub encode_ms: f64,
    /// Decompress + decode time (`chaincode::decode_compressed`, bytes to
    /// skeleton), median of 15 runs, in milliseconds.
    pub decode_ms: f64,
}

/// Mesh figures at one LOD.
#[derive(Debug, Clone, Serialize)]
pub struct LodRow {
    /// LOD level 0–3.
    pub lod: u8,
    /// Triangles of the branch mesh.
    pub triangles: usize,
    /// GLB bytes.
    pub glb_bytes: usize,
    /// OBJ bytes.
    pub obj_bytes: usize,
    /// CityJSON bytes.
    pub cityjson_bytes: usize,
    /// GLB build time from the skeleton, in milliseconds.
    pub glb_build_ms: f64,
}

/// Reconstructs `cloud` and measures the result. A failed reconstruction is
/// a row with `error` set, not an error of the evaluation.
pub fn evaluate(
    name: &str,
    source: Source,
    cloud: &PointCloud,
    truth: Option<&Skeleton>,
    opts: &EvalOptions,
) -> (TreeRow, Option<Reconstruction>) {
    let (result, time) = timed_median(opts.repeat, || reconstruct(cloud, &opts.reconstruct));
    let mut row = empty_row(name, source, cloud.len(), time, opts.repeat);
    match result {
        Err(e) => row.error = Some(e.to_string()),
        Ok(rec) => {
            fill(&mut row, &rec, cloud, truth, opts);
            return (row, Some(rec));
        }
    }
    (row, None)
}

fn empty_row(name: &str, source: Source, points: usize, time: Duration, runs: usize) -> TreeRow {
    let secs = time.as_secs_f64();
    TreeRow {
        name: name.to_string(),
        source,
        points,
        mode: None,
        mode_reason: None,
        wall_time_ms: secs * 1e3,
        runs: runs.max(1),
        points_per_s: if secs > 0.0 {
            points as f64 / secs
        } else {
            0.0
        },
        nodes: 0,
        metrics: None,
        truth: None,
        fit: None,
        mesh_fit: None,
        notes: Vec::new(),
        encoding: None,
        lods: Vec::new(),
        error: None,
    }
}

fn fill(
    row: &mut TreeRow,
    rec: &Reconstruction,
    cloud: &PointCloud,
    truth: Option<&Skeleton>,
    opts: &EvalOptions,
) {
    row.mode = Some(rec.mode);
    row.mode_reason = Some(rec.mode_reason.clone());
    row.nodes = rec.skeleton.len();
    row.metrics = Some(rec.metrics.clone());
    row.notes = rec.notes.clone();
    row.truth = truth.map(|t| truth_figures(t, rec, cloud, opts));
    if rec.mode == Mode::Dense {
        // The fit is the tree's: a plot scan's ground is no cylinder's, and
        // the dense pipeline leaves it out (`reconstruct::dense`, step 0).
        let tree = split_ground(cloud).tree;
        row.fit = Some(surface_fit(&rec.skeleton, &tree));
        let mesh = build_mesh(&rec.skeleton, Lod::L3);
        row.mesh_fit = Some(mesh_fit(&mesh, rec.skeleton.anchor(), &tree));
    }
    row.encoding = Some(encoding_figures(&rec.skeleton));
    row.lods = lod_figures(&rec.skeleton)
        .into_iter()
        .enumerate()
        .map(|(i, f)| LodRow {
            lod: i as u8,
            triangles: f.triangles,
            glb_bytes: f.glb_bytes,
            obj_bytes: f.obj_bytes,
            cityjson_bytes: f.cityjson_bytes,
            glb_build_ms: f.glb_build.as_secs_f64() * 1e3,
        })
        .collect();
}

/// LsJSON and chain code sizes, errors and times for one skeleton.
pub fn encoding_figures(skeleton: &Skeleton) -> EncodingFigures {
    let (ls, enc) = timed_median(1, || lsystem::encode(skeleton, &LsOptions::default()));
    let text = ls.to_json();
    let limits = lsystem::Limits::default();
    let (_, dec) = timed_median(1, || {
        LsJson::parse(&text, &limits).and_then(|l| lsystem::decode(&l, &limits))
    });
    EncodingFigures {
        internodes: skeleton.internode_count(),
        lsjson_bytes: text.len(),
        lsjson_gzip_bytes: gzip_len(text.as_bytes()),
        lsjson_max_error_m: ls.error().max_m,
        lsjson_mean_error_m: ls.error().mean_m,
        lsjson_encode_ms: enc.as_secs_f64() * 1e3,
        lsjson_decode_ms: dec.as_secs_f64() * 1e3,
        chain: [3.0, 5.0, 10.0]
            .into_iter()
            .filter_map(|r| chain_row(skeleton, r))
            .collect(),
    }
}

/// Timed decodes per chain code row (the median is reported). A decode
/// takes 0.05–3 ms, so on a shared machine a few runs still scatter by
/// a third between two evals; 15 cost under 50 ms per tree and resolution.
const DECODE_RUNS: usize = 15;

/// Timed encodings per chain code row (the median is reported): 1–40 ms
/// each, so a few runs suffice.
const ENCODE_RUNS: usize = 3;

fn chain_row(skeleton: &Skeleton, resolution: f32) -> Option<ChainRow> {
    let st = chaincode::stats(skeleton, resolution).ok()?;
    let opts = chaincode::ChainOptions {
        resolution: chaincode::Resolution::PerInternode(resolution),
        ..chaincode::ChainOptions::default()
    };
    let (bytes, enc) = timed_median(ENCODE_RUNS, || {
        chaincode::encode(skeleton, &opts).map(|code| code.compress())
    });
    let bytes = bytes.ok()?;
    let limits = chaincode::Limits::default();
    let (_, dec) = timed_median(DECODE_RUNS, || {
        chaincode::decode_compressed(&bytes, &limits)
    });
    Some(ChainRow {
        code: st,
        encode_ms: enc.as_secs_f64() * 1e3,
        decode_ms: dec.as_secs_f64() * 1e3,
    })
}

fn truth_figures(
    truth: &Skeleton,
    rec: &Reconstruction,
    scan: &PointCloud,
    opts: &EvalOptions,
) -> TruthFigures {
    let c: SkeletonComparison = compare_scanned(
        truth,
        &rec.skeleton,
        scan,
        opts.tolerance_m,
        opts.min_truth_radius_m,
    );
    let base_offset = (rec.skeleton.anchor().origin - truth.anchor().origin).truncate();
    let true_volume_m3 = wood_volume_m3(truth);
    TruthFigures {
        tolerance_m: c.tolerance_m,
        min_truth_radius_m: opts.min_truth_radius_m,
        recall: c.recall,
        precision: c.precision,
        visible_recall: c.visible_recall,
        hidden_share: c.hidden_share,
        scanned_recall: c.scanned_recall,
        scanned_share: c.scanned_share.expect("compare_scanned sets it"),
        mean_distance_m: c.mean_distance_m,
        p95_distance_m: c.p95_distance_m,
        height_error_m: rec.metrics.height_m
            - opts
                .foliage
                .as_ref()
                .map_or_else(|| true_height_m(truth), |f| f.top_height_m(truth)),
        dbh_error_m: rec.metrics.dbh_m - 2.0 * trunk_radius_at(truth, BREAST_HEIGHT_M),
        trunk_base_offset_m: base_offset.length() as f32,
        true_volume_m3,
        volume_ratio: rec.metrics.wood_volume_m3 / true_volume_m3,
        length_ratio: rec.metrics.total_branch_length_m / truth.total_length(),
        branch_count_ratio: branch_count(&rec.metrics.branch_orders) as f32
            / branch_count(&order_stats(truth)) as f32,
    }
}

/// Branches of all orders.
fn branch_count(orders: &[OrderStats]) -> u32 {
    orders.iter().map(|o| o.count).sum()
}

/// Height of a skeleton: its highest node above the root, in metres.
pub fn true_height_m(s: &Skeleton) -> f32 {
    let base = s.position(NodeId::ROOT).z;
    s.nodes()
        .iter()
        .map(|n| n.position.z - base)
        .fold(0.0, f32::max)
}

/// Radius of the trunk (the root's chain of main extensions) at `height_m`
/// above the root, interpolated along the internode that spans it.
pub fn trunk_radius_at(s: &Skeleton, height_m: f32) -> f32 {
    let base = s.position(NodeId::ROOT).z;
    let mut node = NodeId::ROOT;
    while let Some(&next) = s.children(node).first() {
        let (z0, z1) = (s.position(node).z - base, s.position(next).z - base);
        if z1 >= height_m && z1 > z0 {
            let t = ((height_m - z0) / (z1 - z0)).clamp(0.0, 1.0);
            return s.radius(node) + t * (s.radius(next) - s.radius(node));
        }
        node = next;
    }
    s.radius(node)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::skeleton::Anchor;
    use glam::Vec3;

    #[test]
    fn trunk_radius_interpolates_along_the_main_axis() {
        let mut s = Skeleton::new(Anchor::default(), 0.4);
        let a = s.add_child(NodeId::ROOT, Vec3::new(0.0, 0.0, 1.0), 0.3);
        s.add_child(a, Vec3::new(0.0, 0.0, 2.0), 0.1);
        assert!((trunk_radius_at(&s, 1.3) - 0.24).abs() < 1e-5);
        assert_eq!(true_height_m(&s), 2.0);
    }

    /// Synthetic tree `seed` of `species` (as `silva eval --synthetic`
    /// makes it) scanned clean (`--density 1000 --no-occlusion`), evaluated
    /// against its truth.
    fn clean_scan_row(species: crate::synth::Species, seed: u64) -> (TreeRow, Skeleton) {
        use crate::synth::{TlsOptions, TreeParams, generate, simulate_tls};
        let truth = generate(&TreeParams::preset(species), seed, Anchor::default());
        let clean = TlsOptions::clean();
        let cloud = simulate_tls(&truth, &clean, seed);
        let opts = EvalOptions {
            reconstruct: Options::default(),
            repeat: 1,
            tolerance_m: 0.1,
            min_truth_radius_m: 0.0,
            foliage: None,
        };
        let (row, _) = evaluate(
            species.name(),
            Source::Synthetic,
            &cloud,
            Some(&truth),
            &opts,
        );
        (row, truth)
    }

    /// A clean scan of a synthetic birch (`silva eval --synthetic` seed 2):
    /// the report carries the true wood volume and the reconstructed one's
    /// ratio to it, which stays near 1 (1.28 when this test was written).
    #[test]
    fn the_wood_volume_is_compared_with_the_truth() {
        let (row, truth) = clean_scan_row(crate::synth::Species::Birch, 2);
        let t = row.truth.expect("truth figures");
        let volume = row.metrics.expect("metrics").wood_volume_m3;
        assert_eq!(t.true_volume_m3, wood_volume_m3(&truth));
        assert!((t.volume_ratio * t.true_volume_m3 - volume).abs() < 1e-5);
        assert!((0.8..1.6).contains(&t.volume_ratio), "{}", t.volume_ratio);
    }

    /// The report compares the metrics' total branch length and branch
    /// count with the truth's. On this clean scan the reconstruction holds
    /// all the truth's length (recall 0.99) and more: strands of its thin
    /// branches, each a lateral of its own (1.44 times the length and 4.1
    /// times the branches when this test was written).
    #[test]
    fn the_branch_length_and_count_are_compared_with_the_truth() {
        let (row, truth) = clean_scan_row(crate::synth::Species::Birch, 2);
        let t = row.truth.expect("truth figures");
        let metrics = row.metrics.expect("metrics");
        let length = t.length_ratio * truth.total_length();
        assert!((length - metrics.total_branch_length_m).abs() < 1e-3 * length);
        let count = t.branch_count_ratio * branch_count(&order_stats(&truth)) as f32;
        assert_eq!(count.round() as u32, branch_count(&metrics.branch_orders));
        assert!(t.length_ratio > 0.95, "{}", t.length_ratio);
        assert!(t.branch_count_ratio > 0.95, "{}", t.branch_count_ratio);
    }

    /// An airborne scan of a synthetic pine (`silva eval --synthetic 20
    /// --scan als`, seed 4). Crown returns scatter around a branch from the
    /// twigs and needles about it: measured as sections they gave its twigs
    /// 6–7 cm and the wood volume 6.3 times the truth. Airborne radii follow
    /// the pipe model alone, which gives 2.2 times (the reconstruction's
    /// laterals carry more tips than the pine's).
    #[test]
    fn an_airborne_scan_does_not_measure_branches_from_crown_returns() {
        use crate::synth::{AlsOptions, Species, TreeParams, generate, simulate_als};
        let truth = generate(&TreeParams::preset(Species::Pine), 4, Anchor::default());
        let cloud = simulate_als(&truth, &AlsOptions::default(), 4);
        let opts = EvalOptions {
            reconstruct: Options::default(),
            repeat: 1,
            tolerance_m: 0.5,
            min_truth_radius_m: 0.05,
            foliage: None,
        };
        let (row, _) = evaluate("pine", Source::Synthetic, &cloud, Some(&truth), &opts);
        assert_eq!(row.mode, Some(Mode::Airborne));
        let ratio = row.truth.expect("truth figures").volume_ratio;
        assert!((1.0..3.5).contains(&ratio), "{ratio}");
    }

    /// A clean scan of a synthetic poplar (seed 3): with the branches' pipe
    /// law anchored at the DBH its twigs came out at 2 cm and the wood
    /// volume at 1.69 times the truth; with the law fitted to the measured
    /// sections ([`crate::reconstruct::radii`]) it is 1.28.
    #[test]
    fn a_clean_scan_does_not_overestimate_the_wood_volume() {
        let (row, _) = clean_scan_row(crate::synth::Species::Poplar, 3);
        let ratio = row.truth.expect("truth figures").volume_ratio;
        assert!((0.9..1.4).contains(&ratio), "{ratio}");
    }
}
