//! Laterals of thick stems start on their parent's axis.
//!
//! The cross-sections of [`super::skeletonize`] start a lateral at its
//! first section outside the stem, on or near the stem's bark, and join it
//! to the stem's section one geodesic bin lower: the joining internode runs
//! across the stem's wood, roughly at right angles to the stem, while the
//! branch itself leaves the axis lower down at its own angle. On a thick
//! stem that internode is neither near the branch nor on the stem.
//!
//! Quantitative structure models start a branch on its parent's axis: TreeQSM
//! (Raumonen et al. 2013; not among the project's papers) extends a
//! branch's first cylinder back until it meets its parent cylinder. In
//! AdTree (lsystem-from-adtree-skeletons §2.1.1, "Skeleton initialization"
//! and "Branch fitting") mean shift centralises the skeleton onto the
//! branch axes and the cylinders are fitted along the skeleton's nodes, so
//! a lateral starts at a vertex of its parent's axis; the synthetic truth
//! (`crate::synth`) also starts every lateral on its parent's axis.
//! [`to_parent_axis`]
//! extends each lateral of a thick stem back along its initial direction
//! (fitted to its first internodes outside the bark) to the closest
//! approach with the stem's axis polyline, splits the stem internode there
//! and attaches the lateral to the new node.

use glam::Vec3;

use crate::skeleton::{Node, NodeId, Skeleton};

/// When and how far [`to_parent_axis`] moves a lateral's base.
#[derive(Debug, Clone, Copy)]
pub(super) struct BaseRule {
    /// Forks whose cross-section spread (held in `radius_m` before the
    /// radius stage) reaches this, in metres, are on a thick stem
    /// (infinite: off).
    pub(super) thick_spread_m: f32,
    /// The lateral's initial direction is fitted to its main chain over this
    /// many stem spreads beyond its first node…
    pub(super) direction_spreads: f32,
    /// …but at least this far, in metres.
    pub(super) min_direction_m: f32,
    /// The base goes down the stem's chain at most this many stem spreads
    /// below the fork (the fork's own internode always counts)…
    pub(super) max_drop_spreads: f32,
    /// The line back along the lateral must pass the stem's axis within
    /// this many stem spreads (else its direction is not to be trusted)…
    pub(super) max_miss_spreads: f32,
    /// A base closer than this to an existing stem node moves to that node
    /// instead of splitting the internode, in metres.
    pub(super) snap_m: f32,
}

/// Where a lateral's base goes: on the incoming internode of stem node
/// `segment`, at `t` (0 at its parent, 1 at `segment`).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Base {
    lateral: NodeId,
    segment: NodeId,
    t: f32,
}

/// Moves the base of every lateral of a thick stem onto the stem's axis
/// (see the module docs). Children must be in main-extension-first order.
/// New stem nodes get the spread interpolated along the stem internode they
/// split; the laterals keep their own nodes and spreads.
pub(super) fn to_parent_axis(skeleton: &Skeleton, rule: &BaseRule) -> Skeleton {
    let bases: Vec<Base> = skeleton
        .ids()
        .filter(|&v| skeleton.radius(v) >= rule.thick_spread_m)
        .flat_map(|v| {
            let laterals = skeleton.children(v).get(1..).unwrap_or_default();
            laterals
                .iter()
                .filter_map(move |&c| base_of(skeleton, v, c, rule))
        })
        .collect();
    if bases.is_empty() {
        return skeleton.clone();
    }
    rebuild(skeleton, &bases)
}

/// The base on the stem's axis for lateral `lateral` of fork `fork`, if it
/// moves: the stem is the polyline from the fork's main child down the
/// stem's chain, at most [`BaseRule::max_drop_spreads`] stem spreads below
/// the fork ([`stem_below`]), and the base is the point of it closest to the line back from the lateral's
/// first node along its initial direction, no higher along the stem than
/// that first node and not below the ground (z = 0, the trunk base).
fn base_of(skeleton: &Skeleton, fork: NodeId, lateral: NodeId, rule: &BaseRule) -> Option<Base> {
    let main = *skeleton.children(fork).first()?;
    let start = skeleton.position(lateral);
    let reach = (rule.direction_spreads * skeleton.radius(fork)).max(rule.min_direction_m);
    let dir = initial_direction(skeleton, lateral, reach)?;
    let stem = stem_below(
        skeleton,
        fork,
        main,
        rule.max_drop_spreads * skeleton.radius(fork),
    );
    let (segment, t, miss) = stem
        .into_iter()
        .map(|(seg, from)| {
            let (a, b) = (skeleton.position(from), skeleton.position(seg));
            let t = closest_on_segment_to_ray(a, b, start, -dir);
            (seg, t, a.lerp(b, t))
        })
        .filter(|&(_, _, p)| p.z >= 0.0 && (start - p).dot(stem_axis(skeleton, fork)) >= 0.0)
        .map(|(seg, t, p)| (seg, t, ray_distance(p, start, -dir)))
        .min_by(|x, y| x.2.total_cmp(&y.2))?;
    if miss > rule.max_miss_spreads * skeleton.radius(fork) {
        return None;
    }
    snapped(
        skeleton,
        Base {
            lateral,
            segment,
            t,
        },
        fork,
        rule.snap_m,
    )
}

/// The stem's internodes as (node, its parent) from the fork's main child
/// down along the stem's chain: the fork's own internode, and the ones
/// below it while they start within `max_drop_m` of arc length below the
/// fork. The chain stops where it is a lateral's first internode (that
/// internode is that lateral's to move).
fn stem_below(
    skeleton: &Skeleton,
    fork: NodeId,
    main: NodeId,
    max_drop_m: f32,
) -> Vec<(NodeId, NodeId)> {
    let mut stem = vec![(main, fork)];
    let (mut node, mut dropped) = (fork, 0.0);
    while let Some(below) = skeleton.parent(node) {
        if skeleton.children(below).first() != Some(&node) {
            break;
        }
        stem.push((node, below));
        dropped += skeleton.internode_length(node);
        if dropped >= max_drop_m {
            break;
        }
        node = below;
    }
    stem
}

/// The stem's direction at `fork`: from its parent (or itself, at the
/// root) to its main child.
fn stem_axis(skeleton: &Skeleton, fork: NodeId) -> Vec3 {
    let below = skeleton.parent(fork).unwrap_or(fork);
    let above = skeleton.children(fork).first().copied().unwrap_or(fork);
    (skeleton.position(above) - skeleton.position(below)).normalize_or(Vec3::Z)
}

/// `None` when the base stays at the fork (within `snap_m` of it); a base
/// within `snap_m` of either end of its internode moves to that end
/// (t = 0 or 1, which [`rebuild`] attaches to the existing node).
fn snapped(skeleton: &Skeleton, base: Base, fork: NodeId, snap_m: f32) -> Option<Base> {
    let seg = base.segment;
    let from = skeleton.parent(seg)?;
    let (a, b) = (skeleton.position(from), skeleton.position(seg));
    let p = a.lerp(b, base.t);
    let fork_at = skeleton.position(fork);
    if p.distance(fork_at) < snap_m {
        return None;
    }
    let t = if p.distance(a) < snap_m {
        0.0
    } else if p.distance(b) < snap_m {
        1.0
    } else {
        base.t
    };
    Some(Base { t, ..base })
}

/// The lateral's direction at its first node `first`: the principal axis
/// of its main chain (first children) sampled over `reach_m` of arc length
/// from `first`, pointing away from the stem. `None` for a chain shorter
/// than a quarter of the reach (too little to fit).
fn initial_direction(skeleton: &Skeleton, first: NodeId, reach_m: f32) -> Option<Vec3> {
    let pts = chain_samples(skeleton, first, reach_m);
    let last = *pts.last()?;
    let span = last - pts[0];
    if span.length() < 0.25 * reach_m {
        return None;
    }
    let axis = principal_axis(&pts).unwrap_or(span.normalize());
    Some(if axis.dot(span) < 0.0 { -axis } else { axis })
}

/// Points every tenth of `reach_m` along the main chain from `first`, up to
/// `reach_m` of arc length (or the chain's tip).
fn chain_samples(skeleton: &Skeleton, first: NodeId, reach_m: f32) -> Vec<Vec3> {
    let step = reach_m / 10.0;
    let mut pts = vec![skeleton.position(first)];
    let mut walked = 0.0;
    let mut at = first;
    while let Some(&next) = skeleton.children(at).first() {
        let (a, b) = (skeleton.position(at), skeleton.position(next));
        let len = a.distance(b);
        let mut s = step - (walked % step);
        while s <= len && walked + s <= reach_m {
            pts.push(a.lerp(b, s / len));
            s += step;
        }
        walked += len;
        if walked >= reach_m {
            break;
        }
        at = next;
    }
    pts
}

/// The direction of largest spread of `pts` (power iteration on their
/// covariance), `None` when they do not spread.
fn principal_axis(pts: &[Vec3]) -> Option<Vec3> {
    let mean = pts.iter().copied().sum::<Vec3>() / pts.len() as f32;
    let cov = pts.iter().fold(glam::Mat3::ZERO, |m, &p| {
        let d = p - mean;
        m + glam::Mat3::from_cols(d * d.x, d * d.y, d * d.z)
    });
    let mut v = (pts[pts.len() - 1] - pts[0]).try_normalize()?;
    for _ in 0..20 {
        v = (cov * v).try_normalize()?;
    }
    Some(v)
}

/// The parameter `t` in [0, 1] of the point on segment `a`–`b` closest to
/// the ray from `origin` along the unit vector `dir` (closest approach of
/// two lines, clamped to the segment and to the ray's start).
fn closest_on_segment_to_ray(a: Vec3, b: Vec3, origin: Vec3, dir: Vec3) -> f32 {
    let ab = b - a;
    let len2 = ab.length_squared();
    if len2 <= f32::EPSILON {
        return 0.0;
    }
    let w = a - origin;
    let (p, q) = (ab.dot(dir), w.dot(dir));
    let denom = len2 - p * p;
    // Minimise |a + t·ab − (origin + s·dir)| with s = max(0, (w + t·ab)·dir).
    let t_lines = if denom > 1e-9 * len2 {
        (p * q - ab.dot(w)) / denom
    } else {
        0.0
    };
    let t = t_lines.clamp(0.0, 1.0);
    if q + t * p >= 0.0 {
        return t;
    }
    // The closest point of the line lies behind the ray's start: the ray's
    // start itself is the closest point of the ray.
    ((origin - a).dot(ab) / len2).clamp(0.0, 1.0)
}

/// Distance from `p` to the ray from `origin` along the unit vector `dir`.
fn ray_distance(p: Vec3, origin: Vec3, dir: Vec3) -> f32 {
    let s = (p - origin).dot(dir).max(0.0);
    p.distance(origin + dir * s)
}

/// The skeleton with the stem internodes split at the bases (the new nodes
/// get the spread interpolated along the internode) and each lateral
/// attached to its base.
fn rebuild(skeleton: &Skeleton, bases: &[Base]) -> Skeleton {
    let mut nodes: Vec<Node> = skeleton.nodes().to_vec();
    let mut parent_of: Vec<Option<usize>> =
        nodes.iter().map(|n| n.parent.map(|p| p.index())).collect();
    let mut by_segment: Vec<Vec<Base>> = vec![Vec::new(); skeleton.len()];
    for b in bases {
        by_segment[b.segment.index()].push(*b);
    }
    for (seg, splits) in by_segment.iter_mut().enumerate() {
        if splits.is_empty() {
            continue;
        }
        splits.sort_by(|x, y| x.t.total_cmp(&y.t));
        let seg_id = NodeId::from_index(seg);
        let from = skeleton
            .parent(seg_id)
            .expect("a split internode has a parent");
        let mut below = from.index();
        let mut last_t = f32::NAN;
        for s in splits.iter() {
            let at = match s.t {
                0.0 => from.index(),
                1.0 => seg,
                t if t == last_t => below,
                t => {
                    nodes.push(split_node(skeleton, from, seg_id, t));
                    parent_of.push(Some(below));
                    below = nodes.len() - 1;
                    last_t = t;
                    below
                }
            };
            parent_of[s.lateral.index()] = Some(at);
        }
        parent_of[seg] = Some(below);
    }
    for (node, p) in nodes.iter_mut().zip(&parent_of) {
        node.parent = p.map(NodeId::from_index);
    }
    in_parent_order(skeleton, nodes)
}

/// A node at `t` along the internode from `from` to `to`, with the spread
/// interpolated between theirs (it lies on the stem).
fn split_node(skeleton: &Skeleton, from: NodeId, to: NodeId, t: f32) -> Node {
    Node {
        position: skeleton.position(from).lerp(skeleton.position(to), t),
        radius_m: skeleton.radius(from) + (skeleton.radius(to) - skeleton.radius(from)) * t,
        parent: None,
    }
}

/// A skeleton from `nodes` whose parents may come after them (the split
/// nodes are appended): renumbered depth-first, children in their previous
/// order, a split node taking its internode's place in the stem's order.
pub(super) fn in_parent_order(skeleton: &Skeleton, nodes: Vec<Node>) -> Skeleton {
    let mut children: Vec<Vec<usize>> = vec![Vec::new(); nodes.len()];
    // Visit original children in their order, then the new nodes, so that a
    // lateral's slot does not jump ahead of the stem's main extension.
    for (i, node) in nodes.iter().enumerate().skip(1) {
        if let Some(p) = node.parent {
            children[p.index()].push(i);
        }
    }
    let mut out = Skeleton::new(skeleton.anchor().clone(), nodes[0].radius_m);
    out.set_position(NodeId::ROOT, nodes[0].position);
    let mut stack: Vec<(usize, NodeId)> = children[0]
        .iter()
        .rev()
        .map(|&c| (c, NodeId::ROOT))
        .collect();
    while let Some((old, parent)) = stack.pop() {
        let id = out.add_child(parent, nodes[old].position, nodes[old].radius_m);
        stack.extend(children[old].iter().rev().map(|&c| (c, id)));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::skeleton::Anchor;

    const RULE: BaseRule = BaseRule {
        thick_spread_m: 0.12,
        direction_spreads: 2.0,
        min_direction_m: 0.12,
        max_drop_spreads: 0.0,
        max_miss_spreads: 0.5,
        snap_m: 0.03,
    };

    #[test]
    fn a_steep_lateral_starts_below_the_forks_parent_when_allowed() {
        let (s, bark) = stem_with_lateral(0.7, 0.85, 0.6);
        let deep = BaseRule {
            max_drop_spreads: 4.0,
            ..RULE
        };
        let moved = to_parent_axis(&s, &deep);
        assert_eq!(moved.len(), s.len() + 1);
        let base = parent_of_position(&moved, bark);
        assert!(base.distance(Vec3::new(0.0, 0.0, 0.6)) < 1e-3, "{base}");
    }

    /// A 0.2 m-radius stem (spread 0.2) up the z axis whose true lateral
    /// leaves the axis at `true_base_z`, 35° from vertical: the skeleton
    /// starts the lateral at the bark (x = 0.2) and joins it to the stem
    /// node `fork_z` high. Returns the skeleton and the lateral's first node.
    fn stem_with_lateral(below_z: f32, fork_z: f32, true_base_z: f32) -> (Skeleton, Vec3) {
        let dir = Vec3::new(35f32.to_radians().sin(), 0.0, 35f32.to_radians().cos());
        let at = |s: f32| Vec3::new(0.0, 0.0, true_base_z) + dir * s;
        let bark = at(0.2 / dir.x);
        let mut s = Skeleton::new(Anchor::default(), 0.2);
        let below = s.add_child(NodeId::ROOT, Vec3::new(0.0, 0.0, below_z), 0.2);
        let fork = s.add_child(below, Vec3::new(0.0, 0.0, fork_z), 0.2);
        s.add_child(fork, Vec3::new(0.0, 0.0, 3.0), 0.15);
        let first = s.add_child(fork, bark, 0.03);
        let mid = s.add_child(first, at(1.0), 0.03);
        s.add_child(mid, at(2.0), 0.02);
        (s, bark)
    }

    fn parent_of_position(s: &Skeleton, p: Vec3) -> Vec3 {
        let id = s.ids().find(|&id| s.position(id) == p).unwrap();
        s.position(s.parent(id).unwrap())
    }

    #[test]
    fn a_lateral_of_a_thick_stem_starts_on_the_axis_where_it_leaves_it() {
        let (s, bark) = stem_with_lateral(0.4, 0.85, 0.6);
        let moved = to_parent_axis(&s, &RULE);
        assert_eq!(moved.len(), s.len() + 1, "one stem internode split");
        let base = parent_of_position(&moved, bark);
        assert!(base.distance(Vec3::new(0.0, 0.0, 0.6)) < 1e-3, "{base}");
        // The new node is on the stem chain and carries the stem's spread.
        let id = moved.ids().find(|&id| moved.position(id) == base).unwrap();
        assert_eq!(moved.radius(id), 0.2);
        assert_eq!(moved.children(id).len(), 2);
        let off = BaseRule {
            thick_spread_m: f32::INFINITY,
            ..RULE
        };
        assert_eq!(to_parent_axis(&s, &off), s);
    }

    #[test]
    fn the_base_stays_between_the_forks_parent_and_the_ground() {
        // The true base lies below the fork's parent: the lateral moves to
        // the parent node, not beyond it.
        let (s, bark) = stem_with_lateral(0.7, 0.85, 0.6);
        let moved = to_parent_axis(&s, &RULE);
        assert_eq!(moved.len(), s.len());
        assert_eq!(parent_of_position(&moved, bark), Vec3::new(0.0, 0.0, 0.7));
        // A base that would lie below the ground (z = 0) is not taken (a
        // stem internode that dips below the trunk base, as a ragged lowest
        // section can make it).
        let (s, bark) = stem_with_lateral(-0.3, 0.2, -0.1);
        let moved = to_parent_axis(&s, &RULE);
        assert_eq!(parent_of_position(&moved, bark), Vec3::new(0.0, 0.0, 0.2));
    }

    #[test]
    fn closest_approach_of_a_ray_to_a_segment() {
        let (a, b) = (Vec3::ZERO, Vec3::new(0.0, 0.0, 2.0));
        let dir = Vec3::new(-1.0, 0.0, -1.0).normalize();
        let t = closest_on_segment_to_ray(a, b, Vec3::new(1.0, 0.0, 1.5), dir);
        assert!((t - 0.25).abs() < 1e-5, "{t}");
        // Pointing away: the ray's start is the closest point.
        let t = closest_on_segment_to_ray(a, b, Vec3::new(1.0, 0.0, 1.5), -dir);
        assert!((t - 0.75).abs() < 1e-5, "{t}");
    }
}
