//! The dense pipeline on synthetic scans with a known skeleton: a Y-shaped
//! tree sampled on its bark with noise, and the bad inputs of issue 3.

mod cli_support;
mod cloud_support;

use cli_support::{Run, silva};
use cloud_support::{lying_with_up, turned_about_x};
use glam::{DVec3, Vec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use silva::cloud::PointCloud;
use silva::reconstruct::radii::DbhMethod;
use silva::reconstruct::{Mode, Options, ReconstructError, reconstruct};
use silva::synth::{Species, TlsGround, TlsOptions, TreeParams, generate, simulate_tls};
use silva::{NodeId, Skeleton};

const OFFSET: DVec3 = DVec3::new(155_000.0, 463_000.0, 10.0);

/// The true tree: (start, end, radius) cylinders.
fn y_tree() -> Vec<(Vec3, Vec3, f32)> {
    let fork = Vec3::new(0.0, 0.0, 3.0);
    vec![
        (Vec3::ZERO, fork, 0.15),
        (fork, Vec3::new(1.2, 0.0, 5.0), 0.07),
        (fork, Vec3::new(-0.8, 0.6, 5.2), 0.07),
    ]
}

/// Points on the cylinders' bark, about one per `spacing_m`², with
/// Gaussian-ish noise of a few millimetres.
fn scan(cylinders: &[(Vec3, Vec3, f32)], spacing_m: f32, seed: u64) -> Vec<Vec3> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut pts = Vec::new();
    for &(a, b, r) in cylinders {
        let axis = b - a;
        let u = axis.normalize();
        let e1 = u.any_orthonormal_vector();
        let e2 = u.cross(e1);
        let area = std::f32::consts::TAU * r * axis.length();
        let n = (area / (spacing_m * spacing_m)) as usize;
        for _ in 0..n {
            let t: f32 = rng.random();
            let phi: f32 = rng.random::<f32>() * std::f32::consts::TAU;
            let noise = (rng.random::<f32>() + rng.random::<f32>() - 1.0) * 0.004;
            pts.push(a + axis * t + (e1 * phi.cos() + e2 * phi.sin()) * (r + noise));
        }
    }
    pts
}

fn dense() -> Options {
    Options {
        mode: Mode::Dense,
        ..Options::default()
    }
}

fn segment_distance(p: Vec3, a: Vec3, b: Vec3) -> f32 {
    let ab = b - a;
    let t = ((p - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0);
    p.distance(a + ab * t)
}

/// Distance from `p` (relative to the cloud offset) to the skeleton's edges.
fn to_skeleton(s: &Skeleton, p: Vec3) -> f32 {
    let shift = (s.anchor().origin - OFFSET).as_vec3();
    s.internodes()
        .map(|(a, b)| segment_distance(p, s.position(a) + shift, s.position(b) + shift))
        .fold(f32::INFINITY, f32::min)
}

#[test]
fn y_tree_skeleton_radii_and_metrics() {
    let truth = y_tree();
    let cloud = PointCloud::from_points(OFFSET, scan(&truth, 0.015, 1));
    let tree = reconstruct(&cloud, &dense()).unwrap();
    let s = &tree.skeleton;

    // Georeference: the anchor is the absolute trunk base.
    let base = s.anchor().origin;
    assert!((base.x - OFFSET.x).abs() < 0.05 && (base.y - OFFSET.y).abs() < 0.05);
    assert!((base.z - OFFSET.z).abs() < 0.02, "{base:?}");

    // Precision: every node lies inside the true wood (within 2 cm).
    let shift = (base - OFFSET).as_vec3();
    for id in s.ids() {
        let p = s.position(id) + shift;
        let outside = truth
            .iter()
            .map(|&(a, b, r)| segment_distance(p, a, b) - r)
            .fold(f32::INFINITY, f32::min);
        assert!(
            outside < 0.02,
            "node {id:?} at {p} is {outside} m outside the wood"
        );
    }
    // Recall: the true axes are covered, except the last 15 cm of each
    // branch (the skeleton ends at the centroid of the last cross-section)
    // and the first 20 cm of the two branches (the skeleton forks where the
    // cross-sections separate, about a stem radius above the true fork).
    for (k, &(a, b, _)) in truth.iter().enumerate() {
        let len = a.distance(b);
        let steps = (len / 0.05) as usize;
        for i in 0..=steps {
            let t = i as f32 / steps as f32;
            if t * len > len - 0.15 || (k > 0 && t * len < 0.2) {
                continue;
            }
            let p = a.lerp(b, t);
            assert!(to_skeleton(s, p) < 0.1, "true axis point {p} not covered");
        }
    }
    // Two tips (one short bark stub is tolerated).
    let tips = s.ids().filter(|&id| s.is_tip(id)).count();
    let tip_list: Vec<String> = s
        .ids()
        .filter(|&id| s.is_tip(id))
        .map(|id| format!("{:.2}", s.position(id)))
        .collect();
    assert!(
        (2..=3).contains(&tips),
        "{tips} tips in {} nodes: {tip_list:?}",
        s.len()
    );

    // Radii never grow towards the tips; the trunk is fitted within 10 %.
    for id in s.ids().skip(1) {
        let parent = s.parent(id).unwrap_or(NodeId::ROOT);
        assert!(s.radius(id) <= s.radius(parent) + 1e-6);
    }
    let m = &tree.metrics;
    let trunk: Vec<String> = s
        .depth_first()
        .iter()
        .take(6)
        .map(|&id| format!("{:.2}", s.position(id)))
        .collect();
    assert_eq!(
        m.dbh_method,
        DbhMethod::Fitted,
        "{:?} {trunk:?}",
        tree.notes
    );
    assert!((m.dbh_m / 2.0 - 0.15).abs() < 0.015, "dbh {}", m.dbh_m);

    // Metrics: the highest bark point is the top of the second branch.
    assert!((m.height_m - 5.27).abs() < 0.1, "height {}", m.height_m);
    assert!(
        (m.crown_base_height_m - 3.0).abs() < 0.35,
        "cbh {}",
        m.crown_base_height_m
    );
    let true_length: f32 = truth.iter().map(|(a, b, _)| a.distance(*b)).sum();
    assert!(
        (m.total_branch_length_m - true_length).abs() < 0.2 * true_length,
        "length {} vs {true_length}: {:?}",
        m.total_branch_length_m,
        m.branch_orders
    );
    assert_eq!(m.branch_orders[0].count, 1);
    // One lateral (plus at most the bark stub tolerated above).
    let laterals = m.branch_orders.get(1).map_or(0, |o| o.count);
    assert!((1..=2).contains(&laterals), "{laterals} laterals");
    assert!(
        m.crown_area_m2 > 0.3 && m.crown_area_m2 < 2.0,
        "area {}",
        m.crown_area_m2
    );
    assert!(
        m.crown_diameter_m > 1.0 && m.crown_diameter_m < 2.5,
        "cd {}",
        m.crown_diameter_m
    );
    let true_volume: f32 = truth
        .iter()
        .map(|(a, b, r)| std::f32::consts::PI * r * r * a.distance(*b))
        .sum();
    assert!(
        m.wood_volume_m3 > 0.5 * true_volume && m.wood_volume_m3 < 1.5 * true_volume,
        "volume {} vs {true_volume}",
        m.wood_volume_m3
    );
}

#[test]
fn auto_mode_picks_dense_for_a_terrestrial_scan_and_says_why() {
    let cloud = PointCloud::from_points(OFFSET, scan(&y_tree(), 0.015, 2));
    let tree = reconstruct(&cloud, &Options::default()).unwrap();
    assert_eq!(tree.mode, Mode::Dense);
    assert!(
        tree.mode_reason.contains("points/m²"),
        "{}",
        tree.mode_reason
    );
}

/// Slender synthetic trees scanned from the ground have fewer points per m²
/// of crown projection than the density threshold, but centimetre spacing;
/// their airborne scans have neither. Auto mode must tell them apart.
#[test]
fn auto_mode_tells_slender_terrestrial_trees_from_airborne_scans() {
    use silva::reconstruct::survey;
    use silva::synth::{AlsOptions, simulate_als};
    for (species, seed) in [(Species::Birch, 2), (Species::Pine, 8)] {
        let tree = generate(
            &TreeParams::preset(species),
            seed,
            silva::Anchor::at(OFFSET),
        );
        let tls = simulate_tls(&tree, &TlsOptions::default(), seed);
        let (mode, why) = survey(&tls, &Options::default().auto).choose(&Options::default().auto);
        assert_eq!(mode, Mode::Dense, "{species:?} TLS: {why}");
        let als = simulate_als(&tree, &AlsOptions::default(), seed);
        let (mode, why) = survey(&als, &Options::default().auto).choose(&Options::default().auto);
        assert_eq!(mode, Mode::Airborne, "{species:?} ALS: {why}");
    }
}

#[test]
fn the_cylinders_fit_the_scan() {
    let cloud = PointCloud::from_points(OFFSET, scan(&y_tree(), 0.015, 3));
    let tree = reconstruct(&cloud, &dense()).unwrap();
    let fit = silva::eval::fit::surface_fit(&tree.skeleton, &cloud);
    assert!(fit.within_5cm > 0.8, "{fit:?}");
    assert!(fit.supported_share > 0.75, "{fit:?}");
}

fn error_of(points: Vec<Vec3>) -> ReconstructError {
    let cloud = PointCloud::from_points(OFFSET, points);
    match reconstruct(&cloud, &dense()) {
        Ok(t) => panic!("expected an error, got {} nodes", t.skeleton.len()),
        Err(e) => e,
    }
}

#[test]
fn too_few_points_is_an_error() {
    let e = error_of(vec![Vec3::ZERO, Vec3::X, Vec3::Z, Vec3::Y, Vec3::ONE]);
    assert!(
        matches!(e, ReconstructError::TooFewPoints { found: 5, .. }),
        "{e}"
    );
}

#[test]
fn collinear_and_planar_clouds_are_errors() {
    let line = (0..500)
        .map(|i| Vec3::new(0.0, 0.0, i as f32 * 0.01))
        .collect();
    let e = error_of(line).to_string();
    assert!(e.contains("line") && e.contains("z axis points up"), "{e}");
    let plane = (0..2500)
        .map(|i| Vec3::new((i % 50) as f32 * 0.02, 0.5, (i / 50) as f32 * 0.02))
        .collect();
    let e = error_of(plane).to_string();
    assert!(e.contains("plane"), "{e}");
}

#[test]
fn two_separate_trees_are_an_error() {
    let mut pts = scan(&y_tree(), 0.03, 4);
    let shifted: Vec<Vec3> = scan(&y_tree(), 0.03, 5)
        .into_iter()
        .map(|p| p + Vec3::new(6.0, 0.0, 0.0))
        .collect();
    pts.extend(shifted);
    let e = error_of(pts);
    assert!(matches!(e, ReconstructError::Disconnected { .. }), "{e}");
}

/// Two trees whose crowns touch (a synthetic oak and birch, trunks 4 m
/// apart, as one terrestrial scan) join into one graph: no gap separates
/// them. They are refused for their two stems, with where they stand;
/// before, the birch became a branch of the oak hanging down to the ground.
/// In a clip of one tree and a limb that rests on the ground, see
/// `parts::standing_stems`' unit tests.
#[test]
fn two_trees_whose_crowns_touch_are_refused_for_their_stems() {
    let oak = tls_scan(Species::Oak, 3);
    let birch = tls_scan(Species::Birch, 2);
    let apart = Vec3::new(4.0, 0.0, 0.0);
    let pair = side_by_side(&oak, &birch, apart);
    let e = reconstruct(&pair, &dense()).unwrap_err();
    let ReconstructError::SeveralStems {
        stems,
        apart_m,
        first,
        second,
    } = e
    else {
        panic!("expected two stems, got: {e}");
    };
    assert_eq!(stems, 2);
    assert!((apart_m - 4.0).abs() < 0.1, "{apart_m}");
    for (stem, at) in [(first, OFFSET), (second, OFFSET + apart.as_dvec3())] {
        assert!((stem[0] - at.x).hypot(stem[1] - at.y) < 0.1, "{stem:?}");
    }
    let message = e.to_string();
    assert!(
        message.contains("2 stems") && message.contains("one tree per file"),
        "{message}"
    );
    for single in [oak, birch] {
        assert!(reconstruct(&single, &dense()).is_ok());
    }
}

/// The same in `--mode auto`, for a poplar and an oak 4 m apart (`silva
/// synth --scan tls`, seeds 1069 and 1070 as in `tools/tls_pairs.py`):
/// about the centre of both trunks the trunk coverage fell below the dense
/// pipeline's threshold, and the airborne pipeline made one tree of them.
/// Measured about the larger stem, it chooses the dense pipeline, which
/// refuses the pair.
#[test]
fn auto_mode_sends_two_trees_on_their_stems_to_the_dense_pipeline() {
    use silva::reconstruct::{AutoThresholds, survey};
    let pair = side_by_side(
        &tls_scan(Species::Poplar, 1069),
        &tls_scan(Species::Oak, 1070),
        Vec3::new(4.0, 0.0, 0.0),
    );
    let thresholds = AutoThresholds::default();
    let measured = survey(&pair, &thresholds);
    assert!(
        measured.trunk_coverage >= thresholds.min_trunk_coverage,
        "{measured:?}"
    );
    assert_eq!(measured.choose(&thresholds).0, Mode::Dense);
    let auto = Options {
        mode: Mode::Auto,
        ..Options::default()
    };
    let e = reconstruct(&pair, &auto).unwrap_err();
    assert!(
        matches!(e, ReconstructError::SeveralStems { stems: 2, .. }),
        "{e}"
    );
}

/// The default terrestrial scan of a synthetic tree standing at [`OFFSET`].
fn tls_scan(species: Species, seed: u64) -> PointCloud {
    let truth = generate(
        &TreeParams::preset(species),
        seed,
        silva::Anchor::at(OFFSET),
    );
    simulate_tls(&truth, &TlsOptions::default(), seed)
}

/// One cloud of `first` and of `second` moved by `apart`.
fn side_by_side(first: &PointCloud, second: &PointCloud, apart: Vec3) -> PointCloud {
    let mut points = first.points.clone();
    points.extend(second.points.iter().map(|&p| p + apart));
    PointCloud::from_points(OFFSET, points)
}

#[test]
fn a_lying_or_upside_down_tree_is_an_error() {
    let pts = scan(&y_tree(), 0.03, 6);
    let lying = pts.iter().map(|p| Vec3::new(p.x, p.z, p.y)).collect();
    let e = error_of(lying).to_string();
    assert!(e.contains("tilted") && e.contains("z axis"), "{e}");
    let upside_down = pts.iter().map(|p| Vec3::new(p.x, p.y, -p.z)).collect();
    let e = error_of(upside_down).to_string();
    assert!(e.contains("upside down"), "{e}");
}

/// A tree tilted by 40° reconstructs, with a note that the trunk leans and
/// that silva takes z as up; upright, the same scan gets no such note.
#[test]
fn a_tilted_tree_is_a_flagged_best_effort() {
    let pts = scan(&y_tree(), 0.02, 9);
    let leans = |tree: &silva::reconstruct::Reconstruction| {
        tree.notes.iter().find(|n| n.contains("leans")).cloned()
    };
    let upright = reconstruct(&PointCloud::from_points(OFFSET, pts.clone()), &dense()).unwrap();
    assert_eq!(leans(&upright), None);
    let (sin, cos) = 40f32.to_radians().sin_cos();
    let tilted = pts
        .iter()
        .map(|p| Vec3::new(p.x, cos * p.y - sin * p.z, sin * p.y + cos * p.z))
        .collect();
    let tree = reconstruct(&PointCloud::from_points(OFFSET, tilted), &dense()).unwrap();
    let note = leans(&tree).expect("a lean note");
    assert!(note.contains("z axis points up"), "{note}");
}

/// An upright oak whose lowest branches spread into the second tenth of its
/// height is not flagged as leaning: the centroid of that tenth, which the
/// lean was once measured by, sits 1 m off the trunk and read as 31°.
#[test]
fn low_branches_are_no_lean() {
    let truth = generate(
        &TreeParams::preset(Species::Oak),
        20,
        silva::Anchor::default(),
    );
    let scan = simulate_tls(&truth, &TlsOptions::default(), 20);
    let tree = reconstruct(&scan, &Options::default()).unwrap();
    let leans: Vec<&String> = tree.notes.iter().filter(|n| n.contains("leans")).collect();
    assert!(leans.is_empty(), "{leans:?}");
}

/// A Weber–Penn tree of each species (seeds 1–4), scanned from four
/// positions with the default terrestrial settings.
fn one_scan_per_species() -> Vec<(Species, PointCloud)> {
    [Species::Oak, Species::Birch, Species::Poplar, Species::Pine]
        .into_iter()
        .zip(1..)
        .map(|(species, seed)| {
            let truth = generate(&TreeParams::preset(species), seed, silva::Anchor::default());
            (species, simulate_tls(&truth, &TlsOptions::default(), seed))
        })
        .collect()
}

/// The tree stands where its trunk does: a scan from four positions sees
/// each side of the stem's foot unevenly, and the root, the skeleton's
/// georeferenced anchor, once sat at the centroid of the lowest slice, up
/// to 0.21 m (oak 1) and 0.16 m (pine 4) off the true base. It now sits on
/// the centre of the circle fitted at the foot.
#[test]
fn the_root_stands_on_the_trunk_axis_of_a_one_sided_scan() {
    for (species, scan) in one_scan_per_species() {
        let tree = reconstruct(&scan, &Options::default()).unwrap();
        let truth_base = silva::Anchor::default().origin;
        let off = (tree.skeleton.anchor().origin - truth_base)
            .truncate()
            .length();
        assert!(off < 0.03, "{species:?}: root {off:.3} m off the true base");
    }
}

/// A sparse scan (30 points/m² of bark) rings the stem's foot only in a
/// slice taller than 10 cm: the root of poplar 3 sat 0.30 m off the true
/// base with the 10 cm slice alone.
#[test]
fn the_root_of_a_sparse_scan_stands_on_the_trunk_axis() {
    let truth = generate(
        &TreeParams::preset(Species::Poplar),
        3,
        silva::Anchor::default(),
    );
    let sparse = TlsOptions {
        points_per_m2: 30.0,
        ..TlsOptions::default()
    };
    let tree = reconstruct(&simulate_tls(&truth, &sparse, 3), &dense()).unwrap();
    let off = (tree.skeleton.anchor().origin - truth.anchor().origin)
        .truncate()
        .length();
    assert!(off < 0.05, "root {off:.3} m off the true base");
}

/// A Weber–Penn tree of every species, scanned from four positions and
/// turned upside down, is rejected in the automatic mode (the pine's then
/// goes to the airborne pipeline, whose trunk test sees no trunk at the
/// bottom either); upright, the same scans reconstruct. The spread test
/// alone let the conical and columnar crowns through.
#[test]
fn a_synthetic_tree_of_any_species_upside_down_is_an_error() {
    for (species, scan) in one_scan_per_species() {
        let upright = reconstruct(&scan, &Options::default());
        assert!(upright.is_ok(), "{species:?}: {:?}", upright.err());
        let flipped = PointCloud::from_points(
            scan.offset,
            scan.points.iter().map(|p| p.with_z(-p.z)).collect(),
        );
        let err = reconstruct(&flipped, &Options::default())
            .err()
            .unwrap_or_else(|| panic!("{species:?} upside down was reconstructed"));
        let e = err.to_string();
        assert!(
            e.contains("upside down") && e.contains("z axis"),
            "{species:?}: {e}"
        );
    }
}

/// The same scans lying on their side, as exported with `y` or `x` up, are
/// rejected too, and the error says that silva takes z as up. Before the
/// sideways tests, seven of these eight reconstructed (five without any
/// note; `silva synth --scan tls` of the same species and seeds).
#[test]
fn a_synthetic_tree_lying_on_its_side_is_an_error() {
    for (species, scan) in one_scan_per_species() {
        for up in ['y', 'x'] {
            let lying = lying_with_up(&scan, up);
            let err = reconstruct(&lying, &Options::default())
                .err()
                .unwrap_or_else(|| panic!("{species:?} on its side was reconstructed"));
            let e = err.to_string();
            assert!(
                (e.contains("onto its side") || e.contains("lying")) && e.contains("z axis"),
                "{species:?} {up}: {e}"
            );
        }
    }
}

#[test]
fn a_small_stray_cluster_is_dropped_with_a_note() {
    let mut pts = scan(&y_tree(), 0.02, 7);
    pts.extend((0..20).map(|i| Vec3::new(4.0 + 0.01 * i as f32, 0.0, 1.0)));
    let tree = reconstruct(&PointCloud::from_points(OFFSET, pts), &dense()).unwrap();
    assert!(
        tree.notes
            .iter()
            .any(|n| n.contains("detached part of 20 points")),
        "{:?}",
        tree.notes
    );
}

#[test]
fn cli_writes_a_georeferenced_ply_and_metrics() {
    let dir = tempfile::tempdir().unwrap();
    let cloud_path = dir.path().join("tree.xyz");
    let cloud = PointCloud::from_points(OFFSET, scan(&y_tree(), 0.02, 8));
    silva::cloud::write_path(&cloud, &cloud_path).unwrap();
    let ply = dir.path().join("skeleton.ply");
    let metrics = dir.path().join("metrics.json");
    let out = silva()
        .arg("reconstruct")
        .arg(&cloud_path)
        .args(["--mode", "dense", "--skeleton"])
        .arg(&ply)
        .arg("--metrics")
        .arg(&metrics)
        .succeeds();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("mode dense"), "{stderr}");
    let bytes = std::fs::read(&ply).unwrap();
    let end = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .unwrap()
        + 11;
    let header = String::from_utf8_lossy(&bytes[..end]);
    assert!(
        header.starts_with("ply\nformat binary_little_endian 1.0\n"),
        "{header}"
    );
    assert!(header.contains("element edge") && header.contains("property double x"));
    let xyz: Vec<f64> = (0..3)
        .map(|k| f64::from_le_bytes(bytes[end + 8 * k..end + 8 * k + 8].try_into().unwrap()))
        .collect();
    assert!((xyz[0] - OFFSET.x).abs() < 0.05 && (xyz[1] - OFFSET.y).abs() < 0.05);
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&metrics).unwrap()).unwrap();
    assert_eq!(m["mode"], "dense");
    assert!(m["metrics"]["height_m"].as_f64().unwrap() > 5.0);
}

/// The synthetic Lombardy poplar of `silva eval --synthetic` seed 3 and a
/// clean, dense terrestrial scan of it (see [`clean_scan`]).
fn clean_poplar_scan() -> (Skeleton, PointCloud) {
    clean_scan(Species::Poplar, 3)
}

/// The synthetic tree of `silva eval --synthetic` (species and seed as
/// there) and a clean, dense terrestrial scan of it (1,000 points/m², no
/// occlusion).
fn clean_scan(species: Species, seed: u64) -> (Skeleton, PointCloud) {
    let truth = generate(
        &TreeParams::preset(species),
        seed,
        silva::Anchor::at(OFFSET),
    );
    let clean = TlsOptions::clean();
    let cloud = simulate_tls(&truth, &clean, seed);
    (truth, cloud)
}

/// Recall and precision at 0.1 m of the reconstruction of `cloud` with
/// `opts`, against `truth`.
fn recall_precision(truth: &Skeleton, cloud: &PointCloud, opts: &Options) -> (f32, f32) {
    let tree = reconstruct(cloud, opts).unwrap();
    let c = silva::eval::compare::compare(truth, &tree.skeleton, 0.1, 0.0);
    (c.recall, c.precision)
}

/// The synthetic tree of `silva eval --synthetic` (species and seed as
/// there) and its default terrestrial scan: 150 points/m² of bark, seen
/// from the scanner positions, with occlusion.
/// Asserts that `tree`'s DBH was fitted and lies within `tolerance_m` of
/// the truth's at 1.3 m.
fn assert_fitted_dbh(
    tree: &silva::reconstruct::Reconstruction,
    truth: &Skeleton,
    tolerance_m: f32,
) {
    let true_dbh = 2.0 * silva::eval::run::trunk_radius_at(truth, 1.3);
    let m = &tree.metrics;
    assert_eq!(m.dbh_method, DbhMethod::Fitted, "{:?}", tree.notes);
    assert!(
        (m.dbh_m - true_dbh).abs() < tolerance_m,
        "DBH {} against {true_dbh}",
        m.dbh_m
    );
}

/// A synthetic tree (at the origin) and its default scan as a plot: with
/// ground scanned `radius_m` around the trunk, rising `slope_deg` along +x.
fn plot_scan(species: Species, seed: u64, radius_m: f32, slope_deg: f32) -> (Skeleton, PointCloud) {
    let truth = generate(&TreeParams::preset(species), seed, silva::Anchor::default());
    let opts = TlsOptions {
        ground: Some(TlsGround {
            radius_m,
            slope: glam::Vec2::new(slope_deg.to_radians().tan(), 0.0),
        }),
        ..TlsOptions::default()
    };
    let scan = simulate_tls(&truth, &opts, seed);
    (truth, scan)
}

fn default_scan(species: Species, seed: u64) -> (Skeleton, PointCloud) {
    let truth = generate(
        &TreeParams::preset(species),
        seed,
        silva::Anchor::at(OFFSET),
    );
    let cloud = simulate_tls(&truth, &TlsOptions::default(), seed);
    (truth, cloud)
}

/// A clean, dense terrestrial scan of a synthetic Lombardy poplar (the
/// `silva eval --synthetic` seed 3): its thick trunk's ring breaks into
/// pieces of bark at ragged distance fronts, and without the spur rule each
/// piece hangs off the axis as a lateral as long as the trunk's radius,
/// away from every true branch.
#[test]
fn a_poplars_trunk_grows_no_spurs_to_its_bark() {
    let (truth, cloud) = clean_poplar_scan();
    let (_, now) = recall_precision(&truth, &cloud, &dense());
    let mut without = dense();
    without.dense.spur_spread_bins = f32::INFINITY;
    let (_, before) = recall_precision(&truth, &cloud, &without);
    assert!(now > 0.97, "precision {now}");
    assert!(before < 0.96, "precision without the spur rule {before}");
}

/// A clean, dense terrestrial scan of a synthetic birch (the `silva eval
/// --synthetic` seed 2): its twigs are hit a point or two per bin on each
/// side, and the sides run as two chains. Without the strand rule the
/// reconstruction has 1.4 times the true branch length in 4 times as many
/// branches; with it, the length is within a seventh of the truth's.
#[test]
fn a_thin_twig_is_one_branch_not_two_strands() {
    let (truth, cloud) = clean_scan(Species::Birch, 2);
    let ratios = |opts: &Options| {
        let tree = reconstruct(&cloud, opts).unwrap();
        let branches = |orders: &[silva::reconstruct::metrics::OrderStats]| {
            orders.iter().map(|o| o.count).sum::<u32>() as f32
        };
        let true_orders = silva::reconstruct::metrics::order_stats(&truth);
        (
            tree.metrics.total_branch_length_m / truth.total_length(),
            branches(&tree.metrics.branch_orders) / branches(&true_orders),
        )
    };
    let (length, count) = ratios(&dense());
    let mut without = dense();
    without.dense.strand_reach_bins = 0.0;
    let (length_before, count_before) = ratios(&without);
    assert!(length < 1.15, "length / true {length}");
    assert!(count < 2.2, "branches / true {count}");
    assert!(
        length_before > 1.35,
        "length / true without the rule {length_before}"
    );
    assert!(
        count_before > 3.5,
        "branches / true without the rule {count_before}"
    );
}

/// The default, occluded terrestrial scan of a synthetic birch (`silva eval
/// --synthetic` seed 2, 150 points/m² of bark): its twigs are hit every
/// decimetre or so, and a twig's nearest neighbours reach across to the next
/// twig. With graph links up to 20 point spacings, shortest paths hopped
/// between twigs and the skeleton drew internodes through the air; cut at
/// 10 (pieces joined again by one bridge each), it follows the twigs.
#[test]
fn a_sparsely_hit_crown_keeps_its_twigs_apart() {
    let (truth, cloud) = default_scan(Species::Birch, 2);
    let (recall, precision) = recall_precision(&truth, &cloud, &dense());
    let mut long_links = dense();
    long_links.dense.max_edge_spacings = 20.0;
    let (recall_before, precision_before) = recall_precision(&truth, &cloud, &long_links);
    assert!(precision > 0.92, "precision {precision}");
    assert!(
        precision_before < 0.88,
        "precision with long links {precision_before}"
    );
    assert!(
        recall >= recall_before,
        "recall {recall} against {recall_before}"
    );
}

/// An occluded terrestrial scan of a thick poplar trunk (the default scan of
/// `silva eval --synthetic` seed 3) with the bark-detour step off, so that
/// the main chain zigzags out to the bark as it did before that step: the
/// zigzag's own internodes claim most of the breast-height slice, and the
/// fit on the points nearest the trunk has too few inliers. The trunk is
/// then fitted on all points near its axis (the robust circle rejects the
/// branches'), not estimated allometrically.
#[test]
fn a_trunk_chain_that_zigzags_still_gets_a_fitted_dbh() {
    let (truth, cloud) = default_scan(Species::Poplar, 3);
    let mut zigzag = dense();
    zigzag.dense.detour_thin_share = 0.0;
    let tree = reconstruct(&cloud, &zigzag).unwrap();
    assert_fitted_dbh(&tree, &truth, 0.05);
}

/// A clean, dense terrestrial scan of a synthetic Lombardy poplar (the
/// `silva eval --synthetic` seed 3), whose steep branches leave the trunk's
/// axis and run inside its wood for up to a metre before they come out of
/// the bark. The cross-sections start each branch where it comes out and
/// join it across the wood to the trunk; extended back to the trunk's axis
/// along its own direction, the branch covers the true branch inside the
/// wood as well.
#[test]
fn a_poplars_branches_start_on_the_trunks_axis() {
    let (truth, cloud) = clean_poplar_scan();
    let (recall, precision) = recall_precision(&truth, &cloud, &dense());
    let mut at_the_bark = dense();
    at_the_bark.dense.lateral_base_spread_bins = f32::INFINITY;
    let (recall_before, precision_before) = recall_precision(&truth, &cloud, &at_the_bark);
    assert!(
        recall > recall_before + 0.01,
        "recall {recall} against {recall_before} with laterals starting at the bark"
    );
    assert!(
        precision >= precision_before,
        "precision {precision} against {precision_before}"
    );
}

fn median_turn_deg(s: &Skeleton) -> f32 {
    let mut turns = s.turning_angles_deg();
    let mid = turns.len() / 2;
    *turns.select_nth_unstable_by(mid, f32::total_cmp).1
}

/// A straight 1.5 cm twig on a trunk, sampled sparsely: each cross-section
/// of the twig holds a handful of points, so the centroids zigzag. Smoothed
/// along the chain (Taubin's λ|μ filter, each node within its section's
/// reach), the twig's chain turns less, its chain code at a fixed voxel
/// size is smaller, and its nodes stay inside the twig.
#[test]
fn a_sparsely_sampled_twig_gets_a_smooth_chain_inside_it() {
    use silva::encode::chaincode::{self, ChainOptions, Resolution};
    let fork = Vec3::new(0.0, 0.0, 1.5);
    let twig_tip = Vec3::new(1.6, 0.0, 2.7);
    let tree = vec![
        (Vec3::ZERO, fork, 0.08),
        (fork, Vec3::new(0.0, 0.0, 2.0), 0.06),
        (fork, twig_tip, 0.015),
    ];
    let cloud = PointCloud::from_points(OFFSET, scan(&tree, 0.02, 7));
    let skeleton = |rounds: usize| {
        let mut opts = dense();
        opts.dense.thin_smoothing_rounds = rounds;
        reconstruct(&cloud, &opts).unwrap().skeleton
    };
    let bytes = |s: &Skeleton| {
        let opts = ChainOptions {
            resolution: Resolution::VoxelSize(0.01),
            ..ChainOptions::default()
        };
        chaincode::encode(s, &opts).unwrap().compress().len()
    };
    let (noisy, smooth) = (skeleton(0), skeleton(10));
    let (turn, turn_before) = (median_turn_deg(&smooth), median_turn_deg(&noisy));
    assert!(
        turn < 20.0,
        "median turn {turn}° (unsmoothed {turn_before}°)"
    );
    let (size, size_before) = (bytes(&smooth), bytes(&noisy));
    assert!(
        (size as f32) < 0.85 * size_before as f32,
        "chain code {size} B (unsmoothed {size_before} B)"
    );
    let shift = (smooth.anchor().origin - OFFSET).as_vec3();
    let twig: Vec<Vec3> = smooth
        .ids()
        .map(|id| smooth.position(id) + shift)
        .filter(|p| p.x > 0.2)
        .collect();
    // The twig is kept, to within a decimetre of its tip, and not as one
    // straight internode.
    assert!(twig.len() >= 3, "{} twig nodes", twig.len());
    let reach = twig
        .iter()
        .map(|p| p.distance(twig_tip))
        .fold(f32::MAX, f32::min);
    assert!(reach < 0.1, "the twig ends {reach} m short of its tip");
    for p in twig {
        let off_axis = segment_distance(p, fork, twig_tip);
        assert!(off_axis < 0.015, "a twig node {off_axis} m off its axis");
    }
}

/// A thick trunk that forks at a narrow angle into two stems almost as
/// thick (a codominant fork), scanned on its outer bark only: bark inside
/// another stem's wood is no surface.
fn narrow_fork() -> (Vec<(Vec3, Vec3, f32)>, Vec<Vec3>) {
    let fork = Vec3::new(0.0, 0.0, 3.0);
    let stems = vec![
        (Vec3::ZERO, fork, 0.2),
        (fork, fork + Vec3::new(0.7, 0.0, 3.0), 0.17),
        (fork, fork + Vec3::new(-0.6, 0.2, 3.0), 0.15),
    ];
    let inside = |p: Vec3, own: usize| {
        stems.iter().enumerate().any(|(k, &(a, b, r))| {
            let ab = b - a;
            let t = (p - a).dot(ab) / ab.length_squared();
            k != own && (0.0..=1.0).contains(&t) && p.distance(a + ab * t) < r
        })
    };
    let mut points = Vec::new();
    for (k, stem) in stems.iter().enumerate() {
        let bark = scan(std::slice::from_ref(stem), 0.012, 7 + k as u64);
        points.extend(bark.into_iter().filter(|&p| !inside(p, k)));
    }
    (stems, points)
}

/// Where the two stems of a narrow fork part, their rings touch for a metre
/// or more, and one cross-section held both: its node sat in the crotch, on
/// the bark between the two axes. Split in two, each half stays on its own
/// stem's axis.
#[test]
fn a_narrow_fork_keeps_both_stems_on_their_axes() {
    let (stems, points) = narrow_fork();
    // The stems' node at the fork itself lies between their axes.
    let fork = stems[0].1;
    let cloud = PointCloud::from_points(OFFSET, points);
    let farthest_node = |opts: &Options| {
        let s = reconstruct(&cloud, opts).unwrap().skeleton;
        let shift = (s.anchor().origin - OFFSET).as_vec3();
        // Both stems are there: a node near each one's top.
        for &(_, top, _) in &stems[1..] {
            let near = s.ids().map(|v| (s.position(v) + shift).distance(top));
            let near = near.fold(f32::MAX, f32::min);
            assert!(near < 0.3, "the stem to {top} ends {near} m short");
        }
        s.ids()
            .filter(|&v| !s.children(v).is_empty())
            .map(|v| s.position(v) + shift)
            .filter(|p| p.distance(fork) > 0.4)
            .map(|p| {
                stems
                    .iter()
                    .map(|&(a, b, _)| segment_distance(p, a, b))
                    .fold(f32::INFINITY, f32::min)
            })
            .fold(0.0, f32::max)
    };
    let split = farthest_node(&dense());
    let mut whole = dense();
    whole.dense.split_two_stems = false;
    let merged = farthest_node(&whole);
    assert!(split < 0.05, "a node {split} m off the stems' axes");
    assert!(merged > 0.1, "without the split a node is {merged} m off");
}

/// A plot scan holds the ground around the stem, here a disc of 8 m radius
/// (level, and on a 20° slope) under an oak crown that overhangs all of it
/// (its radius is 9.6 m), so that no ground cell is open to the sky. The ground is found and left
/// out: the skeleton matches the truth as well as the scan of the tree
/// alone, and height and DBH agree with it. Before the dense pipeline
/// removed ground, its check rejected such a plot as a tilted or lying tree
/// (the lowest tenth spread metres sideways), and before a cell counted as
/// open ground with clear air above its ground layer (rather than nothing
/// at all above it), no ground was found under a crown.
#[test]
fn a_plot_scan_keeps_its_ground_out_of_the_tree() {
    use silva::eval::compare::compare;
    let truth = generate(
        &TreeParams::preset(Species::Oak),
        1,
        silva::Anchor::default(),
    );
    let alone = reconstruct(
        &simulate_tls(&truth, &TlsOptions::default(), 1),
        &Options::default(),
    )
    .unwrap();
    let alone_fit = compare(&truth, &alone.skeleton, 0.1, 0.0);
    for degrees in [0.0f32, 20.0] {
        let opts = TlsOptions {
            ground: Some(TlsGround {
                radius_m: 8.0,
                slope: glam::Vec2::new(degrees.to_radians().tan(), 0.0),
            }),
            ..TlsOptions::default()
        };
        let scan = simulate_tls(&truth, &opts, 1);
        let plot = reconstruct(&scan, &Options::default()).unwrap();
        let ground = plot.notes.iter().find(|n| n.starts_with("ground:"));
        let slope = format!("by terrain fit, terrain slope {degrees:.0}°");
        assert!(
            ground.is_some_and(|n| n.contains(&slope)),
            "{degrees}°: {ground:?}"
        );
        let fit = compare(&truth, &plot.skeleton, 0.1, 0.0);
        assert!(
            fit.recall >= alone_fit.recall - 0.01 && fit.precision >= alone_fit.precision - 0.01,
            "{degrees}°: recall {:.3} precision {:.3}, alone {:.3} {:.3}",
            fit.recall,
            fit.precision,
            alone_fit.recall,
            alone_fit.precision
        );
        let height = plot.metrics.height_m - alone.metrics.height_m;
        let dbh = plot.metrics.dbh_m - alone.metrics.dbh_m;
        assert!(height.abs() <= 0.05, "{degrees}°: height {height:+.3} m");
        assert!(dbh.abs() <= 0.01, "{degrees}°: DBH {dbh:+.3} m");
    }
}

/// A plot scan turned by 135° or 180° shows its ground on top, and is
/// rejected for it, in the dense pipeline and in the automatic mode. Before
/// the dense pipeline ran the ground-on-top test of the airborne one, this
/// poplar's plot turned by 135° reconstructed with only a lean note; turned
/// by 180°, the automatic mode sent it to the airborne pipeline, whose
/// terrain fit took the disc on top for the ground and rejected the cloud
/// for having "only 0 points above the ground".
#[test]
fn a_plot_scan_with_its_ground_on_top_is_an_error() {
    let (_, scan) = plot_scan(Species::Poplar, 3, 8.0, 0.0);
    for degrees in [135.0f32, 180.0] {
        let cloud = turned_about_x(&scan, degrees);
        for options in [dense(), Options::default()] {
            let result = reconstruct(&cloud, &options);
            let error = result.map(|tree| tree.notes).expect_err("an error");
            assert!(
                error.to_string().contains("upside down"),
                "{degrees}°: {error}"
            );
        }
    }
}

/// A plot scan turned by 60° is too steep for the terrain grid to find its
/// ground, and before the ground was looked for as a plane in 3D, oak 5 and
/// pine 1 (4 m of ground) reconstructed without any note: no slope, no
/// lean. Now the note gives the tilt and the direction that is up; upright,
/// the same plots get no such note.
#[test]
fn a_plot_scan_turned_sixty_degrees_is_flagged_by_its_ground_plane() {
    for (species, seed) in [(Species::Oak, 5), (Species::Pine, 1)] {
        let (_, scan) = plot_scan(species, seed, 4.0, 0.0);
        let tilted = |cloud: &PointCloud| {
            let tree = reconstruct(cloud, &Options::default()).unwrap();
            tree.notes
                .into_iter()
                .find(|n| n.contains("looks tilted by"))
        };
        assert_eq!(tilted(&scan), None, "{species:?} {seed} upright");
        let note = tilted(&turned_about_x(&scan, 60.0)).expect("a tilt note");
        assert!(
            note.contains("tilted by 60°") && note.contains("z axis points up"),
            "{note}"
        );
    }
}

/// A plot scan turned so far that its ground's note names the tilt (the
/// terrain's slope at 45°, the ground plane's at 60°) used to get a second
/// angle from the lean check, measured askew: oak 1 turned 60° read "tilted
/// by 60°" and "the trunk leans 30°", pine 1 turned 45° "slopes 45°" and
/// "leans 54°". The trunk stands square to its ground, so the ground's
/// note, which gives the turn that levels the cloud, is the only one.
#[test]
fn a_plot_scan_turned_with_its_ground_gets_one_tilt_angle() {
    for (species, degrees, tilt) in [
        (Species::Oak, 60.0, "tilted by 60°"),
        (Species::Pine, 45.0, "slopes 45°"),
    ] {
        let (_, scan) = plot_scan(species, 1, 4.0, 0.0);
        let tree = reconstruct(&turned_about_x(&scan, degrees), &Options::default()).unwrap();
        let said = |words: &str| tree.notes.iter().any(|n| n.contains(words));
        assert!(said(tilt), "{species:?}: {:?}", tree.notes);
        assert!(!said("trunk leans"), "{species:?}: {:?}", tree.notes);
    }
}

/// A plot scan turned 60° stands nearer to its side than upright, and its
/// ground, at one side end, rejects it as lying on that side. The error
/// used to ask for the turn that brings that side's axis up, 90° where the
/// cloud is turned 60°; it now gives the ground plane's tilt and the turn
/// that levels it. Turned 90°, it names the axis that is up, as before.
#[test]
fn a_plot_scan_turned_sixty_degrees_onto_a_side_is_told_the_turn_that_levels_it() {
    let (_, scan) = plot_scan(Species::Poplar, 2, 4.0, 0.0);
    let error = |degrees: f32| {
        reconstruct(&turned_about_x(&scan, degrees), &Options::default())
            .map(|tree| tree.notes)
            .expect_err("rejected")
            .to_string()
    };
    let e = error(60.0);
    assert!(
        e.contains("tilted by 60°")
            && e.contains("turn the cloud by 60° about the axis (-1.00, 0.00, 0.00) to level it"),
        "{e}"
    );
    let e = error(90.0);
    assert!(
        e.contains("onto its side") && e.contains("turn the cloud so that −y becomes +z"),
        "{e}"
    );
}

/// The default occluded scan of a synthetic Scots pine (the `silva eval
/// --synthetic 20` seed 20): the skeleton's trunk chain zigzags out to
/// pieces of bark, and its chord at breast height leans 26° where the
/// trunk stands upright. The slice's points projected along that chord
/// smeared into a disc, and the DBH came out 0.71 m against 0.42 m.
#[test]
fn a_zigzagging_trunk_chain_does_not_smear_the_dbh_slice() {
    let (truth, cloud) = default_scan(Species::Pine, 20);
    let tree = reconstruct(&cloud, &dense()).unwrap();
    assert_fitted_dbh(&tree, &truth, 0.02);
}

/// Returns the producer classified as noise (LAS classes 7 and 18) around
/// the trunk at breast height: ignored, with a note, so that the DBH and
/// the skeleton are those of the scan without them. Left in, the same
/// returns change the skeleton.
#[test]
fn returns_classified_as_noise_are_ignored() {
    let tree_points = scan(&y_tree(), 0.02, 7);
    let clean = PointCloud::from_points(OFFSET, tree_points.clone());
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let noise: Vec<Vec3> = (0..400)
        .map(|_| {
            let (s, c) = (rng.random::<f32>() * std::f32::consts::TAU).sin_cos();
            let r = 0.2 + 0.5 * rng.random::<f32>();
            Vec3::new(r * c, r * s, 0.5 + 2.0 * rng.random::<f32>())
        })
        .collect();
    let noise_classes = (0..noise.len()).map(|i| if i % 2 == 0 { 7 } else { 18 });
    let mut noisy = PointCloud::from_points(OFFSET, [tree_points, noise].concat());
    noisy.classification = Some(
        vec![1; clean.len()]
            .into_iter()
            .chain(noise_classes)
            .collect(),
    );
    let expected = reconstruct(&clean, &dense()).unwrap();
    let ignored = reconstruct(&noisy, &dense()).unwrap();
    assert!(
        ignored
            .notes
            .contains(&"400 points classified as noise ignored (LAS classes 7 and 18)".into()),
        "{:?}",
        ignored.notes
    );
    assert_eq!(ignored.skeleton, expected.skeleton);
    assert_eq!(ignored.metrics.dbh_m, expected.metrics.dbh_m);
    noisy.classification = None;
    let kept = reconstruct(&noisy, &dense()).unwrap();
    assert_ne!(kept.skeleton.len(), expected.skeleton.len());
}

/// The default occluded scan of a synthetic silver birch (the `silva eval
/// --synthetic` seed 50), cut out of its plot without ground: the ends of
/// its drooping twigs, 4–5 m up around a bare stem, look like open ground
/// from the grid of lowest points. A surface with the trunk more than a
/// metre below it is not the ground the tree stands on; taken for it, the
/// stem went as below-ground noise and the DBH came out 1.6 m.
#[test]
fn a_drooping_crown_is_not_taken_for_the_ground() {
    let (truth, cloud) = default_scan(Species::Birch, 50);
    let tree = reconstruct(&cloud, &dense()).unwrap();
    assert!(
        !tree.notes.iter().any(|n| n.contains("by terrain fit")),
        "{:?}",
        tree.notes
    );
    assert_fitted_dbh(&tree, &truth, 0.02);
}

/// The synthetic oak 1 on a plot whose scanned ground, 5 m in radius,
/// rises 20° along +x: a limb tip 10 m out, beyond the scanned ground, lies
/// on the ground plane's extrapolation. Its cell, apart from the ground's
/// one surface, is no ground; taken for it, the tip became the trunk base
/// (10.1 m off) and the DBH was estimated.
#[test]
fn a_limb_tip_beyond_the_plots_ground_is_no_trunk_base() {
    let (truth, scan) = plot_scan(Species::Oak, 1, 5.0, 20.0);
    let tree = reconstruct(&scan, &Options::default()).unwrap();
    let base = tree.skeleton.anchor().origin;
    assert!(base.truncate().length() < 0.5, "trunk base at {base}");
    assert_fitted_dbh(&tree, &truth, 0.03);
}

/// The main stem's nodes between `lo` and `hi` metres above the root:
/// absolute positions and radii.
fn stem_between(s: &Skeleton, lo: f32, hi: f32) -> Vec<(DVec3, f32)> {
    let mut out = Vec::new();
    let mut node = NodeId::ROOT;
    while let Some(&next) = s.children(node).first() {
        let z = s.position(next).z - s.position(NodeId::ROOT).z;
        if (lo..=hi).contains(&z) {
            out.push((s.absolute_position(next), s.radius(next)));
        }
        node = next;
    }
    out
}

/// A scan from four positions sees each side of a thick trunk in pieces:
/// the sections' centroids lie towards the scanners, and the trunk's
/// skeleton ran 5–25 cm off the true axis (median 0.3–4 m above the root
/// over seeds 1–8; 23.5 cm on this poplar, 25 cm on this oak), its radii
/// about three quarters of the true ones.
/// Tracked by circles on tall slices (`dense::stem_axis`), the trunk from
/// 0.3 to 4 m lies on the truth's axis and is as thick as the truth's.
#[test]
fn an_occluded_trunk_is_reconstructed_on_its_axis() {
    for (species, seed) in [(Species::Poplar, 3), (Species::Oak, 5)] {
        let truth = generate(&TreeParams::preset(species), seed, silva::Anchor::default());
        let scan = simulate_tls(&truth, &TlsOptions::default(), seed);
        let tree = reconstruct(&scan, &dense()).expect("a tree").skeleton;
        let true_stem = stem_between(&truth, 0.0, 6.0);
        let at_height = |z: f64| {
            true_stem
                .iter()
                .min_by(|a, b| (a.0.z - z).abs().total_cmp(&(b.0.z - z).abs()))
                .copied()
                .expect("a true stem")
        };
        let mut offsets = Vec::new();
        let mut ratios = Vec::new();
        for (p, r) in stem_between(&tree, 0.3, 4.0) {
            let (t, tr) = at_height(p.z);
            offsets.push((p - t).truncate().length());
            ratios.push(f64::from(r / tr));
        }
        assert!(
            offsets.len() >= 5,
            "{species:?}: {} stem nodes",
            offsets.len()
        );
        let median = |v: &mut Vec<f64>| {
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        };
        let offset = median(&mut offsets);
        let ratio = median(&mut ratios);
        assert!(
            offset < 0.03,
            "{species:?}: trunk {offset:.3} m off its axis"
        );
        assert!(
            (0.9..1.2).contains(&ratio),
            "{species:?}: radius {ratio:.2} of the truth's"
        );
    }
}

/// Inside its crown a poplar's stem chain strayed onto the bark and onto
/// twigs hugging it: from 8 to 12 m it ran 0.18–0.26 m off the axis of a
/// 0.2 m trunk, where the tracking of `dense::stem_axis` stopped. Twigs
/// that run inside the trunk then took its bark for their own girth, and
/// the wood volume came out at 1.8 times the truth's. Tracked where its
/// axis leads, the trunk stays on the truth's axis up to 18 m, and the
/// branches inside it are not measured on its bark (`radii::StemWood`).
#[test]
fn a_poplars_trunk_is_followed_through_its_crown() {
    use silva::reconstruct::metrics::wood_volume_m3;
    let truth = generate(
        &TreeParams::preset(Species::Poplar),
        3,
        silva::Anchor::default(),
    );
    let scan = simulate_tls(&truth, &TlsOptions::default(), 3);
    let tree = reconstruct(&scan, &dense()).expect("a tree");
    let true_stem = stem_between(&truth, 0.0, 30.0);
    let mut offsets: Vec<f64> = stem_between(&tree.skeleton, 8.0, 18.0)
        .iter()
        .map(|(p, _)| {
            let t = true_stem
                .iter()
                .min_by(|a, b| (a.0.z - p.z).abs().total_cmp(&(b.0.z - p.z).abs()))
                .expect("a true stem")
                .0;
            (*p - t).truncate().length()
        })
        .collect();
    assert!(offsets.len() >= 20, "{} stem nodes", offsets.len());
    offsets.sort_by(f64::total_cmp);
    let median = offsets[offsets.len() / 2];
    assert!(median < 0.03, "the stem 8-18 m up lies {median:.3} m off");
    let ratio = tree.metrics.wood_volume_m3 / wood_volume_m3(&truth);
    assert!(
        (0.8..1.5).contains(&ratio),
        "wood volume {ratio:.2} of the truth's"
    );
}

/// Occluded terrestrial scans (`silva eval --synthetic 8 --scan tls`, the
/// eval's species and seeds): the crown hides the twigs at its top, and the
/// highest point lay 0.11–0.46 m below the true top (median 0.18 m). With
/// the expected gap to the apex added, as for airborne scans, the height
/// errors centre on 0 (median −0.07 m when this test was written) and the
/// reconstruction says so in a note.
#[test]
fn the_height_reaches_past_the_hidden_top_of_an_occluded_crown() {
    let species = [Species::Oak, Species::Birch, Species::Poplar, Species::Pine];
    let mut errors: Vec<f32> = (1..=8u64)
        .map(|seed| {
            let (truth, cloud) = default_scan(species[(seed as usize - 1) % 4], seed);
            let tree = reconstruct(&cloud, &dense()).expect("reconstructs");
            assert!(
                tree.notes
                    .iter()
                    .any(|n| n.contains("expected gap to the apex")),
                "{:?}",
                tree.notes
            );
            tree.metrics.height_m - silva::eval::run::true_height_m(&truth)
        })
        .collect();
    errors.sort_by(f32::total_cmp);
    let median = 0.5 * (errors[3] + errors[4]);
    assert!(
        median.abs() < 0.1,
        "median height error {median}: {errors:?}"
    );
    assert!(errors.iter().all(|e| e.abs() < 0.45), "{errors:?}");
}
