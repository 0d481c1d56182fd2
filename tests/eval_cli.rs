//! `silva eval` end to end: the report's per-tree target tallies and
//! summary medians agree with its rows.

mod cli_support;

use cli_support::{Run, silva};
use serde_json::Value;

#[test]
fn airborne_report_counts_the_trees_that_meet_each_target() {
    let dir = tempfile::tempdir().unwrap();
    let report = dir.path().join("report.json");
    let out = silva()
        .args(["eval", "--synthetic", "2", "--scan", "als", "--repeat", "1"])
        .arg("--report")
        .arg(&report)
        .succeeds();
    let json: Value = serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    let truths: Vec<&Value> = json["trees"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| &t["truth"])
        .collect();
    let f = |t: &Value, k: &str| t[k].as_f64().unwrap();
    let counted = |ok: &dyn Fn(&Value) -> bool| truths.iter().filter(|t| ok(t)).count();
    let recall = counted(&|t| f(t, "recall") >= 0.90);
    let precision = counted(&|t| f(t, "precision") >= 0.85);
    let height = counted(&|t| f(t, "height_error_m").abs() <= 0.3);
    let base = counted(&|t| f(t, "trunk_base_offset_m") <= 0.5);
    let tallies: Vec<(String, u64, u64)> = json["summary"]["targets"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| {
            (
                t["target"].as_str().unwrap().to_string(),
                t["met"].as_u64().unwrap(),
                t["trees"].as_u64().unwrap(),
            )
        })
        .collect();
    let names: Vec<&str> = tallies.iter().map(|t| t.0.as_str()).collect();
    assert_eq!(
        names,
        [
            "recall >= 0.90",
            "precision >= 0.85",
            "|height error| <= 0.3 m",
            "trunk base offset <= 0.5 m",
            "all four"
        ]
    );
    let met: Vec<u64> = tallies.iter().map(|t| t.1).collect();
    assert_eq!(
        met[..4],
        [recall, precision, height, base].map(|n| n as u64)
    );
    let all_four = counted(&|t| {
        f(t, "recall") >= 0.90
            && f(t, "precision") >= 0.85
            && f(t, "height_error_m").abs() <= 0.3
            && f(t, "trunk_base_offset_m") <= 0.5
    });
    assert_eq!(met[4], all_four as u64);
    assert!(tallies.iter().all(|t| t.2 == 2));
    // Two trees: each median is the mean of the two rows' values (f32 in
    // the rows, so compared to f32 precision).
    let mean_of = |k: &str, g: fn(f64) -> f64| truths.iter().map(|t| g(f(t, k))).sum::<f64>() / 2.0;
    let summary = &json["summary"];
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-6 * b.abs().max(1.0);
    for key in [
        "recall",
        "precision",
        "volume_ratio",
        "length_ratio",
        "branch_count_ratio",
    ] {
        let median = f(summary, &format!("median_{key}"));
        assert!(close(median, mean_of(key, |v| v)), "{key}: {median}");
    }
    let height = f(summary, "median_abs_height_error_m");
    assert!(
        close(height, mean_of("height_error_m", f64::abs)),
        "{height}"
    );
    // Each tree has its chain code rows at r = 3, 5 and 10, each with
    // its measured encoding and decoding times.
    for tree in json["trees"].as_array().unwrap() {
        let rows = tree["encoding"]["chain"].as_array().unwrap();
        let resolutions: Vec<f64> = rows.iter().map(|r| f(r, "resolution")).collect();
        assert_eq!(resolutions, [3.0, 5.0, 10.0]);
        assert!(
            rows.iter()
                .all(|r| f(r, "encode_ms") > 0.0 && f(r, "decode_ms") > 0.0)
        );
    }
    let table = String::from_utf8_lossy(&out.stdout);
    assert!(
        table.contains("synthetic trees meeting each target"),
        "{table}"
    );
}

/// Another scan draw scans the same trees with other returns: the truth
/// (its height) stays, the reconstruction changes (a clip holds as many
/// returns in every draw, but not the same ones), and draw 0 is the default.
#[test]
fn a_scan_draw_rescans_the_same_tree() {
    let dir = tempfile::tempdir().unwrap();
    let run = |draw: Option<&str>| {
        let report = dir.path().join(format!("r{}.json", draw.unwrap_or("-")));
        let mut cmd = silva();
        cmd.args(["eval", "--synthetic", "1", "--scan", "als", "--repeat", "1"])
            .arg("--report")
            .arg(&report);
        if let Some(d) = draw {
            cmd.args(["--scan-draw", d]);
        }
        cmd.succeeds();
        let json: Value = serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
        let tree = json["trees"][0].clone();
        let measured = tree["metrics"]["height_m"].as_f64().unwrap();
        let true_height = measured - tree["truth"]["height_error_m"].as_f64().unwrap();
        let name = tree["name"].as_str().unwrap().to_string();
        let points = tree["points"].as_u64().unwrap();
        (name, measured, true_height, points)
    };
    let (default_name, default_measured, default_true, default_points) = run(None);
    let (zero_name, zero_measured, _, _) = run(Some("0"));
    let (one_name, one_measured, one_true, one_points) = run(Some("1"));
    assert_eq!(
        (zero_name.as_str(), zero_measured),
        (default_name.as_str(), default_measured)
    );
    assert_eq!(one_name, format!("{default_name}-d1"));
    assert_eq!(one_points, default_points, "as many returns");
    assert_ne!(one_measured, default_measured, "other returns");
    assert!((one_true - default_true).abs() < 1e-3, "the same tree");
}

/// Several draws: each tree is scanned once per draw, the tallies count
/// every scan, and each draw's tallies add up to them.
#[test]
fn several_scan_draws_are_tallied_per_draw_and_together() {
    let dir = tempfile::tempdir().unwrap();
    let report = dir.path().join("draws.json");
    let out = silva()
        .args(["eval", "--synthetic", "2", "--scan", "als", "--repeat", "1"])
        .args(["--scan-draw", "1", "--scan-draws", "2"])
        .arg("--report")
        .arg(&report)
        .succeeds();
    let json: Value = serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    let names: Vec<&str> = json["trees"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| t["name"].as_str().unwrap())
        .collect();
    assert_eq!(
        names,
        [
            "oak-s1-als-d1",
            "birch-s2-als-d1",
            "oak-s1-als-d2",
            "birch-s2-als-d2"
        ]
    );
    let summary = &json["summary"];
    let by_draw = summary["targets_by_draw"].as_array().unwrap();
    let draws: Vec<u64> = by_draw
        .iter()
        .map(|d| d["draw"].as_u64().unwrap())
        .collect();
    assert_eq!(draws, [1, 2]);
    let totals = summary["targets"].as_array().unwrap();
    assert_eq!(totals.len(), 5, "the four airborne targets and all four");
    for (k, total) in totals.iter().enumerate() {
        assert_eq!(total["trees"], 4);
        let met: u64 = by_draw
            .iter()
            .map(|d| {
                assert_eq!(d["targets"][k]["trees"], 2);
                d["targets"][k]["met"].as_u64().unwrap()
            })
            .sum();
        assert_eq!(total["met"].as_u64().unwrap(), met);
    }
    let table = String::from_utf8_lossy(&out.stdout);
    assert!(table.contains("per draw"), "{table}");
    let refused = silva()
        .args(["eval", "--synthetic", "1", "--scan-draws", "0"])
        .output()
        .unwrap();
    assert!(!refused.status.success());
    assert!(String::from_utf8_lossy(&refused.stderr).contains("--scan-draws"));
    let last = u64::MAX.to_string();
    let line = silva()
        .args(["eval", "--synthetic", "1", "--scan-draws", "2"])
        .args(["--scan-draw", &last])
        .fails_with_one_line();
    assert!(line.contains("--scan-draws"), "{line}");
}

/// Flags that clap's types let through are refused before any tree is
/// made: a seed range past `u64` wrapped to other trees under the same
/// names, a NaN tolerance scored every tree's recall 0, and a huge
/// `--repeat` panicked on a capacity overflow.
#[test]
fn out_of_range_flags_are_refused_with_a_message() {
    let dir = tempfile::tempdir().unwrap();
    let report = dir.path().join("r.json");
    let eval = |extra: &[&str]| {
        let mut cmd = silva();
        cmd.args(["eval", "--synthetic", "2", "--scan", "als", "--repeat", "1"])
            .args(extra)
            .arg("--report")
            .arg(&report);
        cmd
    };
    for (flags, says) in [
        (&["--seed", "18446744073709551615"][..], "--seed"),
        (&["--tolerance", "NaN"][..], "--tolerance"),
        (&["--tolerance=-0.5"][..], "--tolerance"),
        (&["--min-truth-radius", "inf"][..], "--min-truth-radius"),
    ] {
        let line = eval(flags).fails_with_one_line();
        assert!(line.contains(says), "{flags:?}: {line}");
    }
    let out = eval(&["--repeat", "100000000000000000"]).output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "a huge --repeat was accepted");
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(stderr.contains("--repeat"), "{stderr}");
    assert!(!report.exists(), "a refused run wrote a report");
    // The last seed is fine for one tree.
    silva()
        .args(["eval", "--synthetic", "1", "--scan", "als", "--repeat", "1"])
        .args(["--seed", "18446744073709551615", "--report"])
        .arg(&report)
        .succeeds();
    let json: Value = serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    let name = json["trees"][0]["name"].as_str().unwrap();
    assert!(name.contains("-s18446744073709551615-"), "{name}");
}
