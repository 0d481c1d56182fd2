//! Twin laterals: one twig joined to its stem more than once.
//!
//! A twig that runs along a thick stem's bark before it leaves it lies
//! within graph-edge reach of the bark over its whole first stretch. The
//! shortest paths then reach its cross-sections from the stem's rings
//! rather than along the twig, and [`super::skeletonize`] starts it several
//! times: a few short laterals side by side, each joined to a different
//! stem node across the stem's wood. Only one of those joins can be where
//! the twig leaves the stem; the others cross wood in which no branch runs.
//! On four clean synthetic scans (poplars s7 and s11, oaks s1 and s9),
//! 42–70 % of the skeleton length that lies off the true branches is first
//! internodes of laterals of thick stems.
//!
//! [`rejoin_twins`] attaches such a lateral to the nearest thin node of
//! another branch when that node lies within a gap much shorter than the
//! lateral's join: the twig then grows from its twin. Only joins that turn
//! into their lateral are moved. A join that runs straight on into the
//! lateral's first internode follows the branch's own line, usually because
//! [`super::lateral_base`] extended it back to the stem's axis along the
//! true branch's hidden first stretch; moving those lost more recall than
//! the precision it gained. This refines AdTree's merging of near-duplicate
//! branches (lsystem-from-adtree-skeletons §2.1.1, "Skeleton
//! simplification") for duplicates that meet away from their fork.

use crate::skeleton::{NodeId, Skeleton};
use crate::spatial::PointIndex;

/// Which laterals [`rejoin_twins`] moves, and how far.
#[derive(Debug, Clone, Copy)]
pub(super) struct TwinRule {
    /// Forks whose cross-section spread (held in `radius_m` before the
    /// radius stage) reaches this, in metres, are on a thick stem; nodes
    /// below it are thin (infinite: off).
    pub(super) thick_spread_m: f32,
    /// A twin lies within this many metres of the lateral's first node…
    pub(super) max_gap_m: f32,
    /// …and within this share of the lateral's join to its stem.
    pub(super) max_gap_share: f32,
    /// Only joins that turn by at least this angle, in degrees, into the
    /// lateral's first internode move (a tip's join always may).
    pub(super) min_turn_deg: f32,
}

/// Attaches laterals of thick stems to their twins (module docs), the
/// sharpest turn first. The result's children are in depth-first order, to
/// be reordered by the caller.
pub(super) fn rejoin_twins(skeleton: &Skeleton, rule: &TwinRule) -> Skeleton {
    if !rule.thick_spread_m.is_finite() || rule.max_gap_m <= 0.0 {
        return skeleton.clone();
    }
    let thin: Vec<NodeId> = skeleton
        .ids()
        .filter(|&id| id != NodeId::ROOT && skeleton.radius(id) < rule.thick_spread_m)
        .collect();
    let positions: Vec<_> = thin.iter().map(|&id| skeleton.position(id)).collect();
    let index = PointIndex::new(&positions);
    let mut parent: Vec<Option<NodeId>> = skeleton.ids().map(|id| skeleton.parent(id)).collect();
    let mut moved = false;
    for (join_m, lateral) in kinked_joins(skeleton, rule) {
        let gap_m = rule.max_gap_m.min(rule.max_gap_share * join_m);
        let twin = index
            .within(skeleton.position(lateral), gap_m)
            .into_iter()
            .map(|n| thin[n.index])
            .find(|&t| !descends_from(t, lateral, &parent));
        if let Some(twin) = twin {
            parent[lateral.index()] = Some(twin);
            moved = true;
        }
    }
    if !moved {
        return skeleton.clone();
    }
    let mut nodes = skeleton.nodes().to_vec();
    for (node, p) in nodes.iter_mut().zip(parent) {
        node.parent = p;
    }
    super::lateral_base::in_parent_order(skeleton, nodes)
}

/// The thin first nodes of laterals of thick forks whose join turns by at
/// least the rule's angle, with the join's length, sharpest turn first.
fn kinked_joins(skeleton: &Skeleton, rule: &TwinRule) -> Vec<(f32, NodeId)> {
    let min_turn = rule.min_turn_deg.to_radians();
    let mut joins: Vec<(f32, f32, NodeId)> = skeleton
        .ids()
        .filter(|&fork| skeleton.radius(fork) >= rule.thick_spread_m)
        .flat_map(|fork| {
            let laterals = skeleton.children(fork).get(1..).unwrap_or_default();
            laterals.iter().map(move |&c| (fork, c))
        })
        .filter(|&(_, c)| skeleton.radius(c) < rule.thick_spread_m)
        .map(|(fork, c)| (turn(skeleton, fork, c), skeleton.internode_length(c), c))
        .filter(|&(turn, _, _)| turn >= min_turn)
        .collect();
    joins.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.2.cmp(&b.2)));
    joins.into_iter().map(|(_, join, c)| (join, c)).collect()
}

/// The angle, in radians, between the join `fork`→`first` and the
/// lateral's first internode; π for a tip (nothing continues the join).
fn turn(skeleton: &Skeleton, fork: NodeId, first: NodeId) -> f32 {
    let Some(&next) = skeleton.children(first).first() else {
        return std::f32::consts::PI;
    };
    let join = skeleton.position(first) - skeleton.position(fork);
    let on = skeleton.position(next) - skeleton.position(first);
    join.angle_between(on)
}

/// Whether `node` is `ancestor` or lies in its subtree, by `parent`.
fn descends_from(node: NodeId, ancestor: NodeId, parent: &[Option<NodeId>]) -> bool {
    let mut at = Some(node);
    while let Some(v) = at {
        if v == ancestor {
            return true;
        }
        at = parent[v.index()];
    }
    false
}

#[cfg(test)]
mod tests {
    use glam::{DVec3, Vec3};

    use super::*;
    use crate::skeleton::Anchor;

    const RULE: TwinRule = TwinRule {
        thick_spread_m: 0.1,
        max_gap_m: 0.09,
        max_gap_share: 0.5,
        min_turn_deg: 30.0,
    };

    /// A stem of spread 0.3 up to 3 m with a twig along its bark at x = 0.3
    /// from 1 m up: a lateral from the stem node at 1 m (nodes at 1.0 and
    /// 1.25 m on the bark, then up and out), and a second lateral joined
    /// across the wood from the stem node at 1.3 m, with its first node at
    /// `first_at` and its tip at `second_at`. Returns it and the second
    /// lateral's first node.
    fn stem_with_twin(first_at: Vec3, second_at: Vec3) -> (Skeleton, NodeId) {
        let mut s = Skeleton::new(Anchor::at(DVec3::ZERO), 0.3);
        let low = s.add_child(NodeId::ROOT, Vec3::new(0.0, 0.0, 1.0), 0.3);
        let high = s.add_child(low, Vec3::new(0.0, 0.0, 1.3), 0.3);
        s.add_child(high, Vec3::new(0.0, 0.0, 3.0), 0.3);
        let a = s.add_child(low, Vec3::new(0.3, 0.0, 1.0), 0.01);
        let b = s.add_child(a, Vec3::new(0.3, 0.0, 1.25), 0.01);
        s.add_child(b, Vec3::new(0.8, 0.0, 1.8), 0.01);
        let twin = s.add_child(high, first_at, 0.01);
        s.add_child(twin, second_at, 0.01);
        (s, twin)
    }

    fn parent_position(s: &Skeleton, p: Vec3) -> Vec3 {
        let id = s.ids().find(|&id| s.position(id) == p).expect("node kept");
        s.position(s.parent(id).expect("not the root"))
    }

    #[test]
    fn a_twig_joined_twice_grows_from_its_first_join() {
        let (first, next) = (Vec3::new(0.32, 0.0, 1.3), Vec3::new(0.5, 0.0, 1.5));
        let (s, _) = stem_with_twin(first, next);
        let out = rejoin_twins(&s, &RULE);
        assert_eq!(out.len(), s.len());
        // Moved from the stem node at 1.3 m to the twig node 5 cm away.
        assert_eq!(parent_position(&out, first), Vec3::new(0.3, 0.0, 1.25));
        assert_eq!(
            parent_position(&out, Vec3::new(0.3, 0.0, 1.0)),
            Vec3::new(0.0, 0.0, 1.0)
        );
    }

    #[test]
    fn a_join_that_runs_on_into_its_branch_stays() {
        // The join from (0, 0, 1.3) runs straight on into the lateral.
        let (first, next) = (Vec3::new(0.32, 0.0, 1.3), Vec3::new(0.64, 0.0, 1.3));
        let (s, _) = stem_with_twin(first, next);
        let out = rejoin_twins(&s, &RULE);
        assert_eq!(parent_position(&out, first), Vec3::new(0.0, 0.0, 1.3));
    }

    #[test]
    fn a_lateral_with_no_twin_near_stays_on_its_stem() {
        let (first, next) = (Vec3::new(-0.3, 0.0, 1.3), Vec3::new(-0.3, 0.2, 1.6));
        let (s, _) = stem_with_twin(first, next);
        let out = rejoin_twins(&s, &RULE);
        assert_eq!(parent_position(&out, first), Vec3::new(0.0, 0.0, 1.3));
    }

    #[test]
    fn two_twins_never_hang_from_each_other() {
        // Both pieces' first nodes lie within the gap of the other's nodes:
        // one moves, the other keeps its join, and the result is a tree.
        let (first, next) = (Vec3::new(0.31, 0.0, 1.05), Vec3::new(0.31, 0.05, 1.28));
        let (s, _) = stem_with_twin(first, next);
        let out = rejoin_twins(&s, &RULE);
        assert_eq!(out.len(), s.len());
        let on_stem = [first, Vec3::new(0.3, 0.0, 1.0)]
            .iter()
            .filter(|&&p| parent_position(&out, p).x == 0.0)
            .count();
        assert_eq!(on_stem, 1);
    }
}
