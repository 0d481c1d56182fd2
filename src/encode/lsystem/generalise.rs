//! Tip generalisation (lsystem-from-adtree-skeletons §3.3.1): the last `k`
//! steps of every tip are replaced by one rule letter whose rule holds the
//! averaged steps.
//!
//! Two changes to the paper's method:
//! - A tip is never generalised further than its own branch is long (from
//!   the tip back to the nearest fork or the root), the flaw §3.3.1 admits.
//!   A tip with a branch of `m < k` internodes uses the rule for `m` steps.
//! - Steps are averaged in a consistent frame. Each generalised tip keeps
//!   its own first roll (written explicitly before the rule letter), which
//!   sets the plane it bends in; the rule then holds, per step, the mean
//!   pitch (in [0°, 180°]), mean length, mean radius and the circular mean of
//!   the roll *between* consecutive steps. Averaging raw roll angles, as the
//!   paper does, mixes frames of arbitrary orientation.
//!
//! The rules nest: `T_i → !(r_i) &(θ_i) F(l_i) \(φ_{i-1}) T_{i-1}`, so the
//! document needs `recursions = k`. The error this adds is measured by the
//! encoder after decoding and stored in the document.

use std::collections::BTreeMap;

use glam::DVec3;

use super::format::{Dimensions, Symbol};
use super::turtle::TurtleState;
use super::write::{Tolerance, roll_pitch, shortest_within, simulate};
use crate::skeleton::{NodeId, Skeleton};

/// Rule letters, for 1, 2, … generalised steps (`F` is the turtle's).
const RULE_LETTERS: &[u8] = b"ABCDEGHIJKLMNOPQRSTUVWXYZ";
/// Largest `k` of tip generalisation: one rule letter per step count.
pub const MAX_GENERALISED_STEPS: usize = RULE_LETTERS.len();

/// One generalised tip branch.
struct Chain {
    /// Nodes from the first generalised one to the tip.
    nodes: Vec<NodeId>,
}

/// One measured step of a tip branch, in the frame the turtle has there.
#[derive(Clone, Copy)]
struct Step {
    roll_deg: f64,
    pitch_deg: f64,
    length_m: f64,
    radius_m: f64,
}

/// Which tips are generalised and the rules that draw them.
pub(crate) struct TipPlan {
    /// For the first node of each generalised chain: its rule letter.
    start_letter: Vec<Option<u8>>,
    /// Nodes drawn by a rule rather than written step by step.
    generalised: Vec<bool>,
    /// `T_i` rules.
    pub(crate) rules: BTreeMap<u8, Vec<Symbol>>,
    /// The `k` actually used (the longest chain).
    pub(crate) steps: usize,
}

impl TipPlan {
    /// Plans generalisation of the last `k` steps of every tip of a
    /// canonical skeleton; `targets` are positions relative to the root.
    pub(crate) fn new(
        skeleton: &Skeleton,
        targets: &[DVec3],
        k: usize,
        tolerance: Tolerance,
        unit_m: f64,
    ) -> TipPlan {
        let k = k.min(MAX_GENERALISED_STEPS);
        let chains = tip_chains(skeleton, k);
        let measured: Vec<Vec<Step>> = chains
            .iter()
            .map(|c| measure(skeleton, targets, c))
            .collect();
        let steps = chains.iter().map(|c| c.nodes.len()).max().unwrap_or(0);
        let mut plan = TipPlan {
            start_letter: vec![None; skeleton.len()],
            generalised: vec![false; skeleton.len()],
            rules: BTreeMap::new(),
            steps,
        };
        for chain in &chains {
            plan.start_letter[chain.nodes[0].index()] = Some(RULE_LETTERS[chain.nodes.len() - 1]);
            for n in &chain.nodes {
                plan.generalised[n.index()] = true;
            }
        }
        for i in 1..=steps {
            plan.rules.insert(
                RULE_LETTERS[i - 1],
                rule_body(&measured, i, tolerance, unit_m),
            );
        }
        plan
    }

    /// The rule letter that draws the chain starting at node `id`, if any.
    pub(crate) fn rule_at(&self, id: NodeId) -> Option<u8> {
        self.start_letter[id.index()]
    }

    /// True for nodes drawn by a generalisation rule.
    pub(crate) fn is_generalised(&self, id: NodeId) -> bool {
        self.generalised[id.index()]
    }

    /// Writes a generalised tip whose first node is at `target`: the tip's
    /// own roll towards it, then the rule letter; applies both to `turtle`.
    pub(crate) fn write_tip(
        &self,
        turtle: &mut TurtleState,
        target: DVec3,
        letter: u8,
        tolerance: Tolerance,
        dims: &Dimensions,
        out: &mut Vec<Symbol>,
    ) {
        let offset = target - turtle.position;
        let length = offset.length();
        if length > 0.0 {
            let (roll, pitch) = roll_pitch(turtle, offset / length, false);
            let lever = length * pitch.to_radians().sin().abs();
            let half_width = (tolerance.position_budget(target) / lever.max(1e-300)).to_degrees();
            let roll = shortest_within(roll, half_width.max(0.0));
            if roll != 0.0 {
                let s = Symbol::with(if roll > 0.0 { b'\\' } else { b'/' }, roll.abs());
                turtle.apply(s, dims, true);
                out.push(s);
            }
        }
        let s = Symbol::bare(letter);
        out.push(s);
        let rules = |c: u8| self.rules.get(&c).map(Vec::as_slice);
        simulate(turtle, &[s], &rules, dims, &mut Vec::new());
    }
}

/// For every tip, the last `min(k, m)` nodes of its branch (`m` internodes
/// back to the nearest fork or the root), first to tip.
fn tip_chains(skeleton: &Skeleton, k: usize) -> Vec<Chain> {
    let mut chains = Vec::new();
    if k == 0 {
        return chains;
    }
    for tip in skeleton.ids().skip(1).filter(|&id| skeleton.is_tip(id)) {
        let mut nodes = vec![tip];
        while nodes.len() < k {
            let parent = skeleton
                .parent(nodes[nodes.len() - 1])
                .expect("non-root node");
            if parent == NodeId::ROOT || skeleton.is_fork(parent) {
                break;
            }
            nodes.push(parent);
        }
        nodes.reverse();
        chains.push(Chain { nodes });
    }
    chains
}

/// Steps of a chain, each measured in the frame an exact turtle has after
/// the previous steps (pitch ≥ 0, roll in (−180°, 180°]), indexed from the
/// tip: `result[0]` is the last step.
fn measure(skeleton: &Skeleton, targets: &[DVec3], chain: &Chain) -> Vec<Step> {
    let first = chain.nodes[0];
    let start = skeleton
        .parent(first)
        .expect("chain nodes are never the root");
    let incoming = skeleton
        .parent(start)
        .map(|g| targets[start.index()] - targets[g.index()])
        .and_then(|d| d.try_normalize())
        .unwrap_or(DVec3::Z);
    let left = incoming.any_orthonormal_vector();
    let mut turtle = TurtleState {
        position: targets[start.index()],
        heading: incoming,
        left,
        up: incoming.cross(left),
        width_m: 0.0,
    };
    let mut steps = Vec::with_capacity(chain.nodes.len());
    for &node in &chain.nodes {
        let offset = targets[node.index()] - turtle.position;
        let length = offset.length();
        let (roll, pitch) = if length > 0.0 {
            roll_pitch(&turtle, offset / length, false)
        } else {
            (0.0, 0.0)
        };
        turtle.roll(roll.to_radians());
        turtle.pitch(pitch.to_radians());
        turtle.position = targets[node.index()];
        steps.push(Step {
            roll_deg: roll,
            pitch_deg: pitch,
            length_m: length,
            radius_m: f64::from(skeleton.radius(node)),
        });
    }
    steps.reverse();
    steps
}

/// Body of `T_i`: the mean of step `i` (from the tip) over chains that have
/// it, and, for `i ≥ 2`, the mean roll into step `i − 1` and `T_{i−1}`.
/// Lengths are written in units of `unit_m` metres.
fn rule_body(measured: &[Vec<Step>], i: usize, tolerance: Tolerance, unit_m: f64) -> Vec<Symbol> {
    let with_step: Vec<&Vec<Step>> = measured.iter().filter(|m| m.len() >= i).collect();
    let n = with_step.len().max(1) as f64;
    let mean = |f: fn(&Step) -> f64| with_step.iter().map(|m| f(&m[i - 1])).sum::<f64>() / n;
    let length = mean(|s| s.length_m);
    let pitch = mean(|s| s.pitch_deg);
    let radius = mean(|s| s.radius_m);
    let angle_half_width = (tolerance.position_m / length.max(1e-9)).to_degrees();
    let mut body = vec![
        Symbol::with(
            b'!',
            shortest_within(radius / unit_m, tolerance.radius_allowed(radius) / unit_m),
        ),
        Symbol::with(b'&', shortest_within(pitch, angle_half_width)),
        Symbol::with(
            b'F',
            shortest_within(length / unit_m, tolerance.position_m / unit_m),
        ),
    ];
    if i >= 2 {
        let (sin, cos) = with_step.iter().fold((0.0, 0.0), |(s, c), m| {
            let (ms, mc) = m[i - 2].roll_deg.to_radians().sin_cos();
            (s + ms, c + mc)
        });
        let roll = shortest_within(sin.atan2(cos).to_degrees(), angle_half_width);
        if roll != 0.0 {
            body.push(Symbol::with(
                if roll > 0.0 { b'\\' } else { b'/' },
                roll.abs(),
            ));
        }
        body.push(Symbol::bare(RULE_LETTERS[i - 2]));
    }
    body.retain(|s| s.ch != b'&' || s.param != Some(0.0));
    body
}
