//! The reconstruction issue's per-tree accuracy targets, tallied over the
//! synthetic trees of a report.
//!
//! A median can meet a target that a fifth of the trees miss, and an
//! inventory user meets trees one at a time, so `silva eval` counts the trees
//! that meet each target as well as giving medians. The thresholds are those
//! of issue 3 (clean terrestrial scans: recall and precision at least 0.99 at
//! 10 cm; AHN-like airborne scans: recall at least 0.90 for branches of 5 cm
//! radius and more, precision at least 0.85, both at 0.5 m, height within
//! 0.3 m, trunk base within 0.5 m). Recall and precision are taken at the
//! report's own tolerance and radius filter, which the CLI defaults to the
//! issue's.
//!
//! A tally is one draw of the scanner's randomness (`silva eval
//! --scan-draw`), and it moves with the draw. Measured 2026-12-06 (release
//! build, `silva eval --synthetic 100 --scan als --repeat 1 --scan-draw D`,
//! D = 0…9, the same 100 trees): height within 0.3 m 88, 89, 88, 80, 82, 82,
//! 86, 83, 81, 84 trees (median 83.5); recall 90–95 (median 94); base 93–97
//! (95); precision 100 throughout; all four 73–83 (median 77). Only 36 of the
//! 100 trees meet the height target in all ten draws. Draw 0, the default and
//! the draw that every earlier note reported, is the best or nearly the best
//! of the ten on height and on all four, so figures tuned on it flatter the
//! pipeline by about 5 trees in 100; compare changes over several draws
//! (`--scan-draws N` runs N of them and lists each draw's tallies). On
//! the clean terrestrial scans (`--synthetic 20 --density 1000
//! --no-occlusion`), draws 0, 1 and 2 give 15, 13 and 14 trees meeting both
//! 0.99: the five poplars miss in every draw, oaks 1, 9 and 17 reach
//! precision 0.988–0.989 in one draw each.
//!
//! Over the same ten airborne draws, a tree's height error scatters from
//! draw to draw with a standard deviation of a median 0.17 m for oaks, 0.21
//! for birches, 0.20 for poplars and 0.08 for pines, about a per-tree mean
//! error of a median −0.11, −0.07, −0.07 and −0.03 m. Of the 1,000 scans,
//! 84.3 % are within 0.3 m; with each tree's mean error taken off (an
//! estimate that knew every tree's bias), 89.9 % would be. So most of the
//! height misses are the scatter of the highest returns within one tree,
//! which a better expected gap alone cannot remove.

use serde::Serialize;

use super::run::TruthFigures;

/// A per-tree target on the figures against a truth.
#[derive(Debug, Clone, Copy)]
pub struct Target {
    /// What is required, as printed (tolerance not included).
    pub name: &'static str,
    /// Whether a tree's figures meet it.
    pub met: fn(&TruthFigures) -> bool,
}

/// A list of targets and the name of meeting them all at once, which
/// [`tally`] counts last.
#[derive(Debug, Clone, Copy)]
pub struct Targets {
    /// The single targets.
    pub each: &'static [Target],
    /// Name of the tally of trees that meet every one of them.
    pub all: &'static str,
}

/// Targets for terrestrial scans (issue 3, "Dense, accuracy").
pub const TERRESTRIAL: Targets = Targets {
    each: &[
        Target {
            name: "recall >= 0.99",
            met: |t| t.recall >= 0.99,
        },
        Target {
            name: "precision >= 0.99",
            met: |t| t.precision >= 0.99,
        },
    ],
    all: "recall and precision >= 0.99",
};

/// Targets for airborne scans (issue 3, "Airborne, accuracy").
pub const AIRBORNE: Targets = Targets {
    each: &[
        Target {
            name: "recall >= 0.90",
            met: |t| t.recall >= 0.90,
        },
        Target {
            name: "precision >= 0.85",
            met: |t| t.precision >= 0.85,
        },
        Target {
            name: "|height error| <= 0.3 m",
            met: |t| t.height_error_m.abs() <= 0.3,
        },
        Target {
            name: "trunk base offset <= 0.5 m",
            met: |t| t.trunk_base_offset_m <= 0.5,
        },
    ],
    all: "all four",
};

/// How many trees met one target.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Tally {
    /// The target's [`Target::name`].
    pub target: &'static str,
    /// Trees that met it.
    pub met: usize,
    /// Trees with a truth.
    pub trees: usize,
}

/// Counts, for each target and then for all of them together, the trees
/// whose `figures` meet it.
///
/// ```
/// use silva::eval::targets::{tally, TERRESTRIAL};
/// let counts = tally(&TERRESTRIAL, &[]);
/// assert_eq!((counts[0].target, counts[0].met, counts[0].trees), ("recall >= 0.99", 0, 0));
/// assert_eq!(counts[2].target, "recall and precision >= 0.99");
/// ```
pub fn tally(targets: &Targets, figures: &[&TruthFigures]) -> Vec<Tally> {
    let count = |target, met: &dyn Fn(&TruthFigures) -> bool| Tally {
        target,
        met: figures.iter().filter(|f| met(f)).count(),
        trees: figures.len(),
    };
    let mut tallies: Vec<Tally> = targets.each.iter().map(|t| count(t.name, &t.met)).collect();
    let all = |f: &TruthFigures| targets.each.iter().all(|t| (t.met)(f));
    tallies.push(count(targets.all, &all));
    tallies
}

#[cfg(test)]
mod tests {
    use super::*;

    fn figures(recall: f32, precision: f32, height_error_m: f32, base_m: f32) -> TruthFigures {
        TruthFigures {
            tolerance_m: 0.5,
            min_truth_radius_m: 0.05,
            recall,
            precision,
            visible_recall: recall,
            hidden_share: 0.0,
            scanned_recall: Some(recall),
            scanned_share: 1.0,
            mean_distance_m: 0.1,
            p95_distance_m: 0.2,
            height_error_m,
            dbh_error_m: 0.0,
            trunk_base_offset_m: base_m,
            true_volume_m3: 1.0,
            volume_ratio: 1.0,
            length_ratio: 1.0,
            branch_count_ratio: 1.0,
        }
    }

    #[test]
    fn each_airborne_target_counts_its_own_trees_at_the_thresholds() {
        let trees = [
            figures(0.90, 0.85, -0.3, 0.5), // every threshold met exactly
            figures(0.89, 0.99, 0.0, 0.0),  // recall short
            figures(0.99, 0.84, 0.0, 0.0),  // precision short
            figures(0.99, 0.99, 0.31, 0.0), // too tall
            figures(0.99, 0.99, 0.0, 0.51), // base off
        ];
        let refs: Vec<&TruthFigures> = trees.iter().collect();
        let met: Vec<usize> = tally(&AIRBORNE, &refs).iter().map(|t| t.met).collect();
        assert_eq!(met, [4, 4, 4, 4, 1]);
    }

    #[test]
    fn terrestrial_trees_meet_both_figures_or_not() {
        let trees = [
            figures(0.995, 0.99, 0.0, 0.0),
            figures(0.98, 0.999, 0.0, 0.0),
        ];
        let refs: Vec<&TruthFigures> = trees.iter().collect();
        let met: Vec<usize> = tally(&TERRESTRIAL, &refs).iter().map(|t| t.met).collect();
        assert_eq!(met, [1, 2, 1]);
    }
}
