//! Property tests of the closed-loop guarantee: over thousands of random and
//! synthetic skeletons, every decoded node lies within the stated tolerance
//! of the original (absolute coordinates, any depth), topology and child
//! order survive, radii stay within their stated precision. And no L-string
//! makes the reader panic.

mod lsystem_common;

use lsystem_common::{random_tree, synthetic_tree};
use proptest::prelude::*;
use silva::Skeleton;
use silva::encode::lsystem::{self, Limits, LsError, LsJson, LsOptions};

/// Encodes, prints, parses, decodes, and checks every node.
fn check(s: &Skeleton, opts: &LsOptions) -> Result<(), TestCaseError> {
    let ls = lsystem::encode(s, opts);
    let text = ls.to_json();
    let parsed =
        LsJson::parse(&text, &Limits::default()).map_err(|e| TestCaseError::fail(e.to_string()))?;
    let back = lsystem::decode(&parsed, &Limits::default())
        .map_err(|e| TestCaseError::fail(e.to_string()))?;
    let original = s.canonical();
    // The tolerances as stated: the decimals the user typed. The radii are
    // checked against these, not against the document's own bound, which
    // the encoder would widen to what it measured.
    let typed = |v: f32| -> f64 { v.to_string().parse().unwrap() };
    let tolerance = typed(opts.tolerance_m);
    let (radius_m, radius_rel) = (
        typed(opts.radius_tolerance_m),
        typed(opts.radius_tolerance_rel),
    );
    let e = parsed.error();
    prop_assert_eq!(e.bound_m, tolerance);
    prop_assert_eq!(
        (e.radius_bound_m, e.radius_bound_rel),
        (radius_m, radius_rel)
    );
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
            (r - r2).abs() <= radius_m.max(radius_rel * r),
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

/// Whole L-string symbols, with and without parameters (huge, negative,
/// zero), so that generated strings pass the lexer and reach expansion and
/// the turtle; brackets come unbalanced as often as not.
const TOKENS: &[&str] = &[
    "F", "F(0.5)", "F(-2)", "F(1e3)", "F(0)", "+", "+(30)", "-", "-(1e-3)", "&", "&(90)", "^",
    "^(-400)", "/", "/(45)", "\\", "|", "!(0.1)", "!(0)", "!(1e30)", "[", "]", "A", "B", "C",
];

fn l_string(max_tokens: usize) -> impl Strategy<Value = String> {
    prop::collection::vec(prop::sample::select(TOKENS), 0..max_tokens).prop_map(|t| t.concat())
}

/// An LsJSON document around `axiom` and `rule_a` (`B` expands to `F[A]`).
fn document(axiom: &str, rule_a: &str, recursions: u32) -> String {
    serde_json::json!({
        "format": "lsjson", "version": 1, "degrees": true, "recursions": recursions,
        "trunk": {"anchor": [0, 0, 0], "radius": 0.1},
        "dimensions": {"forward": 1, "rotation": 30, "roll": 45},
        "error": {"bound_m": 0.001, "radius_bound_m": 0.001, "radius_bound_rel": 0,
                  "max_m": 0, "mean_m": 0, "radius_max_m": 0},
        "rules": {"A": rule_a, "B": "F[A]"},
        "axiom": axiom,
    })
    .to_string()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, ..ProptestConfig::default() })]

    /// Strings of whole symbols always lex; expansion and the turtle then
    /// either refuse them with an error or return a skeleton within the
    /// limits, with finite coordinates and radii.
    #[test]
    fn arbitrary_l_strings_never_panic(
        axiom in l_string(60),
        rule_a in l_string(12),
        recursions in 0u32..70,
    ) {
        let limits = Limits { max_symbols: 200_000, ..Limits::default() };
        // Parsing also expands, so it may refuse a string as too long or
        // unbalanced, but never as unlexable.
        let ls = match LsJson::parse(&document(&axiom, &rule_a, recursions), &limits) {
            Err(e @ LsError::Syntax { .. }) => {
                return Err(TestCaseError::fail(format!("whole symbols must lex: {e}")));
            }
            Err(_) => return Ok(()),
            Ok(ls) => ls,
        };
        if let Ok(tree) = lsystem::decode(&ls, &limits) {
            prop_assert!(tree.len() <= limits.max_symbols + 1);
            prop_assert!(tree.nodes().iter().all(|n| n.position.is_finite() && n.radius_m.is_finite()));
        }
    }

    /// Raw characters, most of them refused by the lexer.
    #[test]
    fn arbitrary_characters_never_panic(
        axiom in "[F+\\-&^/|!\\[\\]AB()0-9.e]{0,60}",
        rule_a in "[F+\\-&^AB\\[\\]()0-9.]{0,12}",
        recursions in 0u32..70,
    ) {
        let limits = Limits { max_symbols: 200_000, ..Limits::default() };
        if let Ok(ls) = LsJson::parse(&document(&axiom, &rule_a, recursions), &limits) {
            let _ = lsystem::decode(&ls, &limits);
        }
    }
}
