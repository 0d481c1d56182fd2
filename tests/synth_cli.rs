//! `silva synth` end to end: the true skeleton written, read back and compared.

mod cli_support;

use glam::DVec3;
use silva::cloud::{PointCloud, ReadOptions, read_path};
use silva::synth::{
    AlsOptions, Foliage, Leaves, Species, TlsOptions, TreeParams, generate, scan_seed,
    simulate_als, simulate_tls,
};
use silva::{Anchor, Skeleton};

use cli_support::{Run, silva};

#[test]
fn truth_written_by_the_cli_reads_back_as_the_generated_tree() {
    let dir = tempfile::tempdir().unwrap();
    let truth = dir.path().join("skeleton.json");
    let out = silva()
        .args([
            "synth",
            "--species",
            "pine",
            "--seed",
            "7",
            "--crs",
            "EPSG:28992",
        ])
        .args(["--anchor", "85000,446000,0.5", "--truth"])
        .arg(&truth)
        .succeeds();
    let back = Skeleton::from_json(&std::fs::read_to_string(&truth).unwrap()).unwrap();
    let anchor = Anchor {
        origin: DVec3::new(85_000.0, 446_000.0, 0.5),
        crs: Some("EPSG:28992".into()),
    };
    assert_eq!(
        back,
        generate(&TreeParams::preset(Species::Pine), 7, anchor)
    );
    let summary: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(summary["internodes"], back.internode_count());
}

#[test]
fn als_summary_reports_the_requested_density() {
    let out = silva()
        .args([
            "synth",
            "--species",
            "oak",
            "--seed",
            "7",
            "--scan",
            "als",
            "--density",
            "20",
        ])
        .succeeds();
    let summary: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let density = summary["density_pts_per_m2"].as_f64().unwrap();
    assert!((16.0..=24.0).contains(&density), "{density}");
}

#[test]
fn clouds_written_by_the_cli_keep_their_coordinates_to_the_millimetre() {
    let dir = tempfile::tempdir().unwrap();
    let anchor = Anchor::at(DVec3::new(85_000.0, 446_000.0, 0.0));
    let tree = generate(&TreeParams::preset(Species::Birch), 3, anchor);
    for (scan, file) in [
        ("als", "clip.laz"),
        ("als", "clip.las"),
        ("tls", "tree.ply"),
        ("tls", "tree.xyz"),
    ] {
        let path = dir.path().join(file);
        silva()
            .args(["synth", "--species", "birch", "--seed", "3", "--scan", scan])
            .args(["--anchor", "85000,446000,0", "-o"])
            .arg(&path)
            .succeeds();
        let expected = if scan == "als" {
            // The CLI's default: a leaf-off deciduous crown, as AHN.
            let opts = AlsOptions {
                foliage: Foliage::for_species(Species::Birch, Leaves::Off),
                ..AlsOptions::default()
            };
            simulate_als(&tree, &opts, 3)
        } else {
            simulate_tls(&tree, &TlsOptions::default(), 3)
        };
        assert_file_holds(&path, &expected, file);
    }
}

/// `--scan-draw` scans the same tree with the scanner seeded by
/// `scan_seed(seed, draw)`, as `silva eval --scan-draw` does; draw 0 is the
/// seed's own scan.
#[test]
fn a_scan_draw_rescans_the_same_tree_with_another_scanner_seed() {
    let dir = tempfile::tempdir().unwrap();
    let anchor = Anchor::at(DVec3::new(85_000.0, 446_000.0, 0.0));
    let tree = generate(&TreeParams::preset(Species::Pine), 4, anchor);
    assert_eq!(scan_seed(4, 0), 4, "draw 0 is the seed's own scan");
    for draw in [0, 2] {
        let path = dir.path().join(format!("draw{draw}.ply"));
        let out = silva()
            .args(["synth", "--species", "pine", "--seed", "4", "--scan", "tls"])
            .args([
                "--anchor",
                "85000,446000,0",
                "--scan-draw",
                &draw.to_string(),
            ])
            .arg("-o")
            .arg(&path)
            .succeeds();
        let summary: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(summary["scan_draw"], draw);
        assert_eq!(
            summary["internodes"],
            tree.internode_count(),
            "the same tree"
        );
        let expected = simulate_tls(&tree, &TlsOptions::default(), scan_seed(4, draw));
        assert_file_holds(&path, &expected, &format!("draw {draw}"));
    }
    let own = simulate_tls(&tree, &TlsOptions::default(), 4);
    let other = simulate_tls(&tree, &TlsOptions::default(), scan_seed(4, 2));
    assert_ne!(own.points, other.points, "another draw, other points");
}

/// The cloud written at `path` holds `expected`'s points, every 97th
/// checked to the millimetre in absolute coordinates.
fn assert_file_holds(path: &std::path::Path, expected: &PointCloud, what: &str) {
    let (back, _) = read_path(path, &ReadOptions::default()).unwrap();
    assert!(!expected.is_empty(), "{what}: nothing to compare");
    assert_eq!(back.len(), expected.len(), "{what}");
    for i in (0..back.len()).step_by(97) {
        let d = back.absolute(i) - expected.absolute(i);
        assert!(
            d.abs().max_element() <= 1.0e-3,
            "{what}: point {i} off by {d}"
        );
    }
}

#[test]
fn bad_arguments_fail_with_one_line() {
    // In a directory of its own, so that a wrongly accepted case writes
    // nowhere in the repository.
    let dir = tempfile::tempdir().unwrap();
    for args in [
        vec!["synth", "--species", "oak"],
        vec!["synth", "--scan", "als", "--density", "0"],
        vec!["synth", "--scan", "tls", "--noise", "NaN"],
        vec![
            "synth",
            "--scan",
            "tls",
            "--ground-radius",
            "60",
            "-o",
            "c.xyz",
        ],
        vec!["synth", "--scan", "als", "--ground-slope=-5", "-o", "c.xyz"],
        vec![
            "synth",
            "--scan",
            "als",
            "--ground-slope",
            "inf",
            "-o",
            "c.xyz",
        ],
        vec!["synth", "--truth", "t.json", "-o", "cloud.laz"],
        vec!["synth", "--scan", "als", "-o", "cloud.e57"],
    ] {
        silva()
            .current_dir(dir.path())
            .args(&args)
            .fails_with_one_line();
    }
}
