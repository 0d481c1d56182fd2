//! Skeletons as L-systems: the LsJSON format with a guaranteed error bound
//! (lsystem-from-adtree-skeletons §2.2, §3.2, §3.3.1; issue 4 items 1–4).
//!
//! GIS and simulation tools (ENVI-met, L-Py) can grow and edit an
//! L-system, so each skeleton is also stored as one. The paper's format is
//! kept — `recursions`, `axiom`, `rules`, `trunk` anchor and radius,
//! `dimensions` defaults, `degrees` — and extended with a format version,
//! per-internode radii (`!(w)`), the stated error bound and (version 2) a
//! length unit, so that lengths print as integer millimetres. The L-string uses
//! the standard 3D turtle of *The Algorithmic Beauty of Plants*, so any
//! L-system tool can read it; `docs/lsjson.md` specifies the grammar and the
//! frame conventions.
//!
//! The paper's writer rounded each step independently, so errors grew along
//! branches, and its Euler-angle turtle flipped near the poles (§4.4,
//! Table 4.1: outliers of metres). Here both are impossible:
//! - the turtle is a rotation matrix turned about its own axes (no poles);
//! - the writer is *closed-loop*: every step is computed from the state the
//!   reader will have after the rounded steps before it, and checked, so
//!   **every decoded node lies within [`LsOptions::tolerance_m`] of the
//!   original, whatever its depth** (radii within
//!   [`LsOptions::radius_tolerance_m`]). The bound holds in absolute
//!   coordinates; tip generalisation, when asked for, adds a measured error
//!   that the document states.
//!
//! ```
//! use glam::{DVec3, Vec3};
//! use silva::encode::lsystem::{self, Limits, LsJson, LsOptions};
//! use silva::{Anchor, NodeId, Skeleton};
//!
//! let mut tree = Skeleton::new(Anchor::at(DVec3::new(155_000.0, 463_000.0, 0.0)), 0.3);
//! let fork = tree.add_child(NodeId::ROOT, Vec3::new(0.0, 0.1, 2.5), 0.2);
//! tree.add_child(fork, Vec3::new(0.1, 0.2, 5.0), 0.15);
//! tree.add_child(fork, Vec3::new(1.2, 0.0, 3.4), 0.05);
//!
//! let ls = lsystem::encode(&tree, &LsOptions::default());
//! let text = ls.to_json();
//! let back = lsystem::decode(&LsJson::parse(&text, &Limits::default())?, &Limits::default())?;
//! for id in tree.ids() {
//!     assert!(back.absolute_position(id).distance(tree.absolute_position(id)) <= 0.001);
//! }
//! # Ok::<(), silva::encode::lsystem::LsError>(())
//! ```

mod decimal;
mod expand;
mod format;
mod generalise;
mod read;
mod rules;
mod turtle;
mod write;

use glam::DVec3;

pub use format::{ErrorBound, LsJson};
pub use generalise::MAX_GENERALISED_STEPS;
pub use read::decode;

use format::{Dimensions, Symbol};
use generalise::TipPlan;
use write::{Favoured, Tolerance, length_unit, shortest_within, write_axiom, write_dimensions};

use crate::interrupt::{Interrupt, Interrupted};
use crate::skeleton::{Anchor, NodeId, Skeleton, SkeletonError};

/// How [`encode`] writes.
#[derive(Debug, Clone, PartialEq)]
pub struct LsOptions {
    /// Largest distance between a decoded node and the original, metres.
    pub tolerance_m: f32,
    /// Largest difference between a decoded radius and the original,
    /// metres, for thin branches; see [`radius_tolerance_rel`](Self::radius_tolerance_rel).
    pub radius_tolerance_m: f32,
    /// Largest difference between a decoded radius and the original, as a
    /// fraction of the radius. The allowed difference is the larger of the
    /// two: radius estimates from LiDAR are good to a few percent, and
    /// millimetres on a 30 cm trunk would cost a `!(w)` at every node.
    pub radius_tolerance_rel: f32,
    /// Tip generalisation (§3.3.1): replace the last `k` steps of every tip
    /// by averaged rules (at most [`MAX_GENERALISED_STEPS`], never beyond the
    /// tip's own branch). `None` keeps every tip exact.
    pub generalise_tips: Option<usize>,
}

impl Default for LsOptions {
    fn default() -> Self {
        Self {
            tolerance_m: 0.001,
            radius_tolerance_m: 0.0005,
            radius_tolerance_rel: 0.01,
            generalise_tips: None,
        }
    }
}

/// Bounds on what reading an LsJSON document may cost. The defaults admit
/// any real tree with a wide margin and keep memory below a few hundred MB.
#[derive(Debug, Clone, PartialEq)]
pub struct Limits {
    /// Longest document text, bytes.
    pub max_input_bytes: usize,
    /// Largest `recursions`.
    pub max_recursions: u32,
    /// Longest L-string after any recursion, symbols.
    pub max_symbols: usize,
    /// Deepest bracket nesting.
    pub max_depth: usize,
    /// Most nodes (`F`s) drawn.
    pub max_nodes: usize,
    /// Farthest a node may be from the trunk anchor, metres.
    pub max_extent_m: f64,
}

impl Default for Limits {
    fn default() -> Self {
        Self {
            max_input_bytes: 16 << 20,
            max_recursions: 64,
            max_symbols: 4_000_000,
            max_depth: 10_000,
            max_nodes: 1_000_000,
            max_extent_m: 10_000.0,
        }
    }
}

impl Limits {
    /// Limits that admit whatever [`encode`] wrote for `skeleton`.
    fn for_own(skeleton: &Skeleton, ls: &LsJson) -> Self {
        Self {
            max_input_bytes: usize::MAX,
            max_recursions: ls.recursions,
            max_symbols: usize::MAX / 32,
            max_depth: skeleton.len() + 1,
            max_nodes: skeleton.len(),
            max_extent_m: f64::INFINITY,
        }
    }
}

/// Why an LsJSON document was rejected.
#[derive(Debug, thiserror::Error)]
pub enum LsError {
    /// The text is longer than [`Limits::max_input_bytes`].
    #[error("LsJSON: document of {bytes} bytes exceeds the limit of {limit}")]
    InputTooLarge {
        /// Length of the text.
        bytes: usize,
        /// The limit.
        limit: usize,
    },
    /// Not JSON, or not of the LsJSON shape.
    #[error("LsJSON: {0}")]
    Json(#[from] serde_json::Error),
    /// Not an LsJSON version this build reads.
    #[error(
        "LsJSON: expected format \"lsjson\" version 1 or 2, found \"{format}\" version {version}"
    )]
    Version {
        /// The `format` field.
        format: String,
        /// The `version` field.
        version: u32,
    },
    /// A field has an impossible value.
    #[error("LsJSON: {field} {reason}")]
    Invalid {
        /// The field, e.g. `trunk.radius`.
        field: &'static str,
        /// What is wrong with it.
        reason: &'static str,
    },
    /// A rule name is not a single ASCII letter.
    #[error("LsJSON: rule name {0:?} is not a single letter A-Z or a-z")]
    RuleName(String),
    /// An L-string could not be lexed.
    #[error("LsJSON: {field} at byte {offset}: {reason}")]
    Syntax {
        /// `axiom` or `rules.X`.
        field: String,
        /// Byte offset in that string.
        offset: usize,
        /// What is wrong.
        reason: &'static str,
    },
    /// `recursions` exceeds [`Limits::max_recursions`].
    #[error("LsJSON: {recursions} recursions exceed the limit of {limit}")]
    Recursions {
        /// The document's value.
        recursions: u32,
        /// The limit.
        limit: u32,
    },
    /// Expansion would exceed [`Limits::max_symbols`].
    #[error("LsJSON: the rules would expand beyond {limit} symbols")]
    TooManySymbols {
        /// The limit.
        limit: usize,
    },
    /// Brackets nest deeper than [`Limits::max_depth`].
    #[error("LsJSON: brackets nest deeper than {limit}")]
    TooDeep {
        /// The limit.
        limit: usize,
    },
    /// Brackets do not balance in the expanded string.
    #[error("LsJSON: unbalanced brackets at expanded symbol {symbol}: {reason}")]
    Unbalanced {
        /// Index in the expanded L-string.
        symbol: usize,
        /// Which way it fails.
        reason: &'static str,
    },
    /// More `F`s than [`Limits::max_nodes`].
    #[error("LsJSON: more than {limit} nodes")]
    TooManyNodes {
        /// The limit.
        limit: usize,
    },
    /// A node lands farther from the anchor than [`Limits::max_extent_m`].
    #[error("LsJSON: node {node} lies more than {limit_m} m from the trunk anchor")]
    OutOfRange {
        /// The node's index in drawing order.
        node: usize,
        /// The limit.
        limit_m: f64,
    },
    /// The decoded nodes do not form a valid skeleton.
    #[error("LsJSON: {0}")]
    Skeleton(#[from] SkeletonError),
}

/// Encodes a skeleton as LsJSON with the closed-loop writer.
///
/// The document's [`ErrorBound`] holds the stated bound (the tolerance, or
/// the generalisation error when larger) and the errors measured by
/// decoding the document with [`decode`] and comparing node by node.
/// Nodes are written in canonical order (see [`Skeleton::canonical`]).
pub fn encode(skeleton: &Skeleton, opts: &LsOptions) -> LsJson {
    match encode_within(skeleton, opts, &Interrupt::never()) {
        Ok(ls) => ls,
        // Only a deadline interrupts, and `never` has none.
        Err(interrupted) => unreachable!("{interrupted}"),
    }
}

/// [`encode`], checking `interrupt` before each writing pass, each Re-Pair
/// round and the measurement of the error; the document is the same when
/// it is not interrupted.
pub fn encode_within(
    skeleton: &Skeleton,
    opts: &LsOptions,
    interrupt: &Interrupt,
) -> Result<LsJson, Interrupted> {
    let canon = skeleton.canonical();
    // The trunk anchor is the root's absolute position, printable exactly;
    // targets are relative to it, computed without cancellation.
    let origin = canon.anchor().origin;
    let anchor = canon.absolute_position(NodeId::ROOT).map(json_exact);
    let shift = origin - anchor;
    let targets: Vec<DVec3> = canon
        .nodes()
        .iter()
        .map(|n| shift + n.position.as_dvec3())
        .collect();
    let tolerance = Tolerance {
        position_m: non_negative(opts.tolerance_m),
        radius_m: non_negative(opts.radius_tolerance_m),
        radius_rel: non_negative(opts.radius_tolerance_rel),
    };
    let dims = write_dimensions(length_unit(tolerance.position_m));
    let plan = opts
        .generalise_tips
        .filter(|&k| k > 0)
        .map(|k| TipPlan::new(&canon, &targets, k, tolerance, dims.unit_m));
    let root_radius = f64::from(canon.radius(NodeId::ROOT));
    let writing = Writing {
        canon: &canon,
        targets,
        anchor: Anchor {
            origin: anchor,
            crs: canon.anchor().crs.clone(),
        },
        trunk_radius_m: shortest_within(root_radius, tolerance.radius_budget(root_radius).max(0.0)),
        tolerance,
        dims,
        plan,
    };
    // A second pass prefers the parameters that the first turned into
    // rules or defaults; it is kept only when it is shorter.
    let first = writing.document(&Favoured::default(), interrupt)?;
    let second = writing.document(
        &Favoured::from(first.rules.values(), &first.dimensions),
        interrupt,
    )?;
    let mut ls = if second.to_json().len() < first.to_json().len() {
        second
    } else {
        first
    };
    interrupt.check("measuring the L-system's error")?;
    ls.error = measure(&canon, &ls, tolerance, writing.plan.as_ref());
    Ok(ls)
}

/// What every pass of the writer shares.
struct Writing<'a> {
    /// The skeleton in canonical order.
    canon: &'a Skeleton,
    /// Node positions relative to the root.
    targets: Vec<DVec3>,
    anchor: Anchor,
    trunk_radius_m: f64,
    tolerance: Tolerance,
    /// The writer's dimensions, with the length unit.
    dims: Dimensions,
    plan: Option<TipPlan>,
}

impl Writing<'_> {
    /// Writes the document, preferring `favoured` parameters, then fills in
    /// the defaults and rules; the errors are not measured yet.
    fn document(&self, favoured: &Favoured, interrupt: &Interrupt) -> Result<LsJson, Interrupted> {
        interrupt.check("writing the L-system's axiom")?;
        let mut axiom = write_axiom(
            self.canon,
            &self.targets,
            self.trunk_radius_m,
            self.tolerance,
            &self.dims,
            self.plan.as_ref(),
            favoured,
        );
        let mut rules = self
            .plan
            .as_ref()
            .map(|p| p.rules.clone())
            .unwrap_or_default();
        let dimensions = use_defaults(&mut axiom, rules.values_mut(), self.dims.unit_m);
        let mut depth = rules::rule_depths(&rules);
        rules::compress(&mut axiom, &mut rules, &mut depth, interrupt)?;
        Ok(LsJson {
            recursions: depth.values().copied().max().unwrap_or(0),
            axiom,
            rules,
            anchor: self.anchor.clone(),
            trunk_radius_m: self.trunk_radius_m,
            dimensions,
            degrees: true,
            error: ErrorBound::default(),
        })
    }
}

/// A tolerance as `f64` at the decimal value the user typed (0.001, not
/// 0.0010000000474974513); 0 when not a positive number.
fn non_negative(v: f32) -> f64 {
    if v.is_finite() && v > 0.0 {
        v.to_string().parse().unwrap_or(f64::from(v))
    } else {
        0.0
    }
}

/// Picks the most frequent length and angles as `dimensions` and drops the
/// parameters equal to them. Values are compared exactly, so the decoded
/// state is bit-for-bit unchanged.
fn use_defaults<'a>(
    axiom: &mut Vec<Symbol>,
    rules: impl Iterator<Item = &'a mut Vec<Symbol>>,
    unit_m: f64,
) -> Dimensions {
    let mut rules: Vec<&mut Vec<Symbol>> = rules.collect();
    let mode = |chars: &[u8], all: &[&Vec<Symbol>]| {
        let mut counts: foldhash::HashMap<u64, usize> = foldhash::HashMap::default();
        for s in all.iter().flat_map(|v| v.iter()) {
            if let (true, Some(p)) = (chars.contains(&s.ch), s.param) {
                *counts.entry(p.to_bits()).or_default() += 1;
            }
        }
        counts
            .into_iter()
            .filter(|&(bits, n)| n >= 2 && json_exact(f64::from_bits(bits)).to_bits() == bits)
            .max_by_key(|&(bits, n)| (n, std::cmp::Reverse(bits)))
            .map(|(bits, _)| f64::from_bits(bits))
    };
    let all: Vec<&Vec<Symbol>> = std::iter::once(&*axiom)
        .chain(rules.iter().map(|r| &**r))
        .collect();
    let forward = mode(b"F", &all);
    let rotation = mode(b"+-&^", &all);
    let roll = mode(b"\\/", &all);
    for list in std::iter::once(axiom).chain(rules.iter_mut().map(|r| &mut **r)) {
        for s in list.iter_mut() {
            let default = match s.ch {
                b'F' => forward,
                b'+' | b'-' | b'&' | b'^' => rotation,
                b'\\' | b'/' => roll,
                _ => None,
            };
            if default.is_some() && s.param.map(f64::to_bits) == default.map(f64::to_bits) {
                s.param = None;
            }
        }
    }
    Dimensions {
        unit_m,
        forward: forward.unwrap_or(1.0),
        rotation: rotation.unwrap_or(0.0),
        roll: roll.unwrap_or(0.0),
    }
}

/// `v` rounded to 15 significant digits. serde_json (without its
/// `float_roundtrip` feature) parses such numbers exactly, so the document
/// reads back bit for bit; for a national-grid anchor that is nanometres.
fn json_exact(v: f64) -> f64 {
    format!("{v:.14e}").parse().unwrap_or(v)
}

/// `v` rounded up to a multiple of 0.1 µm.
fn round_up(v: f64) -> f64 {
    let r = (v * 1e7).ceil() / 1e7;
    if r < v { v } else { r }
}

/// Decodes `ls` and compares it, node by node, with the canonical skeleton
/// it was written from.
fn measure(
    canon: &Skeleton,
    ls: &LsJson,
    tolerance: Tolerance,
    plan: Option<&TipPlan>,
) -> ErrorBound {
    let mut bound = ErrorBound {
        generalised_steps: plan.map_or(0, |p| p.steps as u32),
        ..ErrorBound::default()
    };
    let decoded = match decode(ls, &Limits::for_own(canon, ls)) {
        Ok(d) if d.len() == canon.len() => d,
        // Cannot happen for a skeleton of finite f32 coordinates; state the
        // failure rather than a bound that does not hold.
        _ => {
            bound.bound_m = 1e300;
            bound.radius_bound_m = 1e300;
            return bound;
        }
    };
    let mut sum = 0.0;
    let mut radius_within = true;
    for id in canon.ids() {
        let error = decoded
            .absolute_position(id)
            .distance(canon.absolute_position(id));
        let radius_error = f64::from((decoded.radius(id) - canon.radius(id)).abs());
        sum += error;
        bound.max_m = bound.max_m.max(error);
        bound.radius_max_m = bound.radius_max_m.max(radius_error);
        radius_within &= radius_error <= tolerance.radius_allowed(f64::from(canon.radius(id)));
        if plan.is_some_and(|p| p.is_generalised(id)) {
            bound.generalisation_max_m = bound.generalisation_max_m.max(error);
        }
    }
    // Statistics to 0.1 µm keep the document short; maxima round up so
    // that they still bound.
    bound.max_m = round_up(bound.max_m);
    bound.radius_max_m = round_up(bound.radius_max_m);
    bound.generalisation_max_m = round_up(bound.generalisation_max_m);
    bound.mean_m = (sum / canon.len() as f64 * 1e7).round() / 1e7;
    bound.bound_m = tolerance.position_m.max(bound.max_m);
    // Generalised tips may leave the radius tolerance; then the largest
    // error measured is the bound.
    bound.radius_bound_m = if radius_within {
        tolerance.radius_m
    } else {
        tolerance.radius_m.max(bound.radius_max_m)
    };
    bound.radius_bound_rel = tolerance.radius_rel;
    bound
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;

    /// A passed deadline stops the writer before its first pass; without
    /// one the document is the one [`encode`] writes.
    #[test]
    fn a_passed_deadline_stops_the_writer_at_a_step() {
        let mut tree = Skeleton::new(Anchor::at(DVec3::ZERO), 0.3);
        let mut tip = NodeId::ROOT;
        for i in 1..40 {
            tip = tree.add_child(tip, Vec3::new(0.0, 0.1 * (i % 2) as f32, i as f32), 0.1);
        }
        let opts = LsOptions::default();
        let passed = Interrupt::at(Some(std::time::Instant::now()));
        let err = encode_within(&tree, &opts, &passed).unwrap_err();
        assert_eq!(err.step, "writing the L-system's axiom");
        let never = encode_within(&tree, &opts, &Interrupt::never()).unwrap();
        assert_eq!(never.to_json(), encode(&tree, &opts).to_json());
    }
}
