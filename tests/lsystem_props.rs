//! Property tests of the closed-loop guarantee: over thousands of random and
//! synthetic skeletons, every decoded node lies within the stated tolerance
//! of the original (absolute coordinates, any depth), topology and child
//! order survive, radii stay within their stated precision. And no L-string
//! makes the reader panic.

mod lsystem_common;

use lsystem_common::{random_tree, synthetic_tree};
use proptest::prelude::*;
use silva::Skeleton;
use silva::encode::lsystem::{self, Limits, LsJson, LsOptions};

/// Encodes, prints, parses, decodes, and checks every node.
fn check(s: &Skeleton, opts: &LsOptions) -> Result<(), TestCaseError> {
    let ls = lsystem::encode(s, opts);
    let text = ls.to_json();
    let parsed =
        LsJson::parse(&text, &Limits::default()).map_err(|e| TestCaseError::fail(e.to_string()))?;
    let back = lsystem::decode(&parsed, &Limits::default())
        .map_err(|e| TestCaseError::fail(e.to_string()))?;
    let original = s.canonical();
    // The tolerance as stated: the decimal the user typed.
    let tolerance: f64 = opts.tolerance_m.to_string().parse().unwrap();
    let e = parsed.error();
    prop_assert_eq!(e.bound_m, tolerance);
    prop_assert_eq!(original.len(), back.len());
    for id in original.ids() {
        prop_assert_eq!(original.parent(id), back.parent(id));
        prop_assert_eq!(original.children(id), back.children(id));
        let d = original
            .absolute_position(id)
            .distance(back.absolute_position(id));
        prop_assert!(d <= tolerance, "node {:?}: {} m > {} m", id, d, tolerance);
        let (r, r2) = (f64::from(original.radius(id)), f64::from(back.radius(id)));
        prop_assert!(
            (r - r2).abs() <= e.radius_bound_m.max(e.radius_bound_rel * r),
            "radius {} vs {}",
            r,
            r2
        );
    }
    prop_assert!(e.max_m <= tolerance);
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 3000, ..ProptestConfig::default() })]

    #[test]
    fn random_skeletons_within_tolerance(
        seed in any::<u64>(),
        nodes in 1usize..200,
        chain_bias in 0.0f64..1.0,
        tolerance in prop::sample::select(vec![0.001f32, 0.0002, 0.01]),
    ) {
        let opts = LsOptions { tolerance_m: tolerance, ..LsOptions::default() };
        check(&random_tree(seed, nodes, chain_bias), &opts)?;
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 40, ..ProptestConfig::default() })]

    #[test]
    fn deep_chains_within_tolerance(seed in any::<u64>(), nodes in 200usize..1500) {
        // Nearly every node continues the previous one: depth in the hundreds.
        check(&random_tree(seed, nodes, 0.98), &LsOptions::default())?;
    }

    #[test]
    fn synthetic_trees_within_tolerance(seed in any::<u64>(), internodes in 10usize..2500) {
        check(&synthetic_tree(seed, internodes), &LsOptions::default())?;
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, ..ProptestConfig::default() })]

    #[test]
    fn arbitrary_l_strings_never_panic(
        axiom in "[F+\\-&^/|!\\[\\]AB()0-9.e]{0,60}",
        rule_a in "[F+\\-&^AB\\[\\]()0-9.]{0,12}",
        recursions in 0u32..70,
    ) {
        let doc = serde_json::json!({
            "format": "lsjson", "version": 1, "degrees": true, "recursions": recursions,
            "trunk": {"anchor": [0, 0, 0], "radius": 0.1},
            "dimensions": {"forward": 1, "rotation": 30, "roll": 45},
            "error": {"bound_m": 0.001, "radius_bound_m": 0.001, "radius_bound_rel": 0,
                      "max_m": 0, "mean_m": 0, "radius_max_m": 0},
            "rules": {"A": rule_a, "B": "F[A]"},
            "axiom": axiom,
        });
        let limits = Limits { max_symbols: 200_000, ..Limits::default() };
        if let Ok(ls) = LsJson::parse(&doc.to_string(), &limits) {
            let _ = lsystem::decode(&ls, &limits);
        }
    }
}
