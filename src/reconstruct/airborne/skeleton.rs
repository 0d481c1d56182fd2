//! Skeleton production and provisional radii: Hu et al. §5.4, Algorithm 2
//! (SkeletonProduce), and §5.5, Eq. 6 (pipe model).
//!
//! Algorithm 2 grows the skeleton greedily from the first trunk segment. A
//! priority queue holds segments keyed by bending angle α / α_max, so the
//! smoothest continuation is always extended first. Popping segment (k, i),
//! every unvisited graph neighbour j of i becomes a child candidate when the
//! bending angle α_j between p_i − p_k and p_j − p_i is below α_max and the
//! angle β_j between p_j − p_i and the direction field u_j is below β_max;
//! candidates are marked visited. Of candidates closer in direction than
//! φ_max only the one with the smallest α stays (pruning); the rest become
//! segments and enter the queue. No backtracking: each point is reached at
//! most once, so the result is a tree.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use glam::Vec3;

use super::Params;
use crate::skeleton::{Anchor, Node, NodeId, Skeleton};

/// The tree Algorithm 2 produced, as skeleton nodes over candidate points.
#[derive(Debug, Clone)]
pub(super) struct Produced {
    /// Per skeleton node: its candidate point and its parent node (parents
    /// first; node 0 is the start point, node 1 the end point).
    pub(super) nodes: Vec<(u32, Option<u32>)>,
    /// Candidate points marked visited (skeleton nodes and pruned ones).
    pub(super) visited: usize,
}

/// A child candidate of the popped point (the paper's node n_s).
struct Candidate {
    child: Vec3,
    alpha: f32,
    j: u32,
}

/// Algorithm 2 over `points` with graph `adjacency` and direction field
/// `field`, starting with the segment `start` → `end` (§5.4).
pub(super) fn skeleton_produce(
    points: &[Vec3],
    adjacency: &[Vec<u32>],
    field: &[Vec3],
    start: usize,
    end: usize,
    params: &Params,
) -> Produced {
    let alpha_max = params.alpha_max_deg.to_radians();
    let beta_max = params.beta_max_deg.to_radians();
    let phi_max = params.phi_max_deg.to_radians();
    let mut visited = vec![false; points.len()];
    visited[start] = true;
    visited[end] = true;
    let mut nodes = vec![(start as u32, None), (end as u32, Some(0))];
    // Queue entries: (key bits, sequence, k, i, node of i). Keys are in
    // [0, 1], where the bit pattern of a non-negative f32 orders like its
    // value; the sequence number breaks ties in insertion order.
    let mut queue = BinaryHeap::new();
    queue.push(Reverse((
        1.0f32.to_bits(),
        0u64,
        start as u32,
        end as u32,
        1u32,
    )));
    let mut sequence = 1u64;
    let mut candidates: Vec<Candidate> = Vec::new();
    while let Some(Reverse((_, _, k, i, node_i))) = queue.pop() {
        let p_i = points[i as usize];
        let parent = p_i - points[k as usize];
        candidates.clear();
        for &j in &adjacency[i as usize] {
            if visited[j as usize] {
                continue;
            }
            let child = points[j as usize] - p_i;
            let alpha = angle(child, parent);
            let beta = angle(field[j as usize], child);
            if alpha < alpha_max && beta < beta_max {
                candidates.push(Candidate { child, alpha, j });
                visited[j as usize] = true;
            }
        }
        candidates.sort_by(|a, b| {
            a.alpha.total_cmp(&b.alpha).then(
                a.child
                    .length_squared()
                    .total_cmp(&b.child.length_squared()),
            )
        });
        prune(&mut candidates, phi_max);
        for c in &candidates {
            let node = nodes.len() as u32;
            nodes.push((c.j, Some(node_i)));
            let key = (c.alpha / alpha_max).clamp(0.0, 1.0);
            queue.push(Reverse((key.to_bits(), sequence, i, c.j, node)));
            sequence += 1;
        }
    }
    Produced {
        nodes,
        visited: visited.iter().filter(|&&v| v).count(),
    }
}

/// Removes every candidate whose direction is within `phi_max` of a
/// candidate with a smaller bending angle (candidates sorted by α), the
/// paper's pruning of overlapping segments.
fn prune(candidates: &mut Vec<Candidate>, phi_max: f32) {
    let mut kept: Vec<Candidate> = Vec::with_capacity(candidates.len());
    for c in candidates.drain(..) {
        if kept.iter().all(|k| angle(k.child, c.child) >= phi_max) {
            kept.push(c);
        }
    }
    *candidates = kept;
}

/// Angle between two vectors in radians; π (never accepted) when either is
/// of zero length, so that duplicate points cannot form segments.
fn angle(a: Vec3, b: Vec3) -> f32 {
    let denom = (a.length_squared() * b.length_squared()).sqrt();
    if denom <= 1e-12 {
        return std::f32::consts::PI;
    }
    (a.dot(b) / denom).clamp(-1.0, 1.0).acos()
}

/// The produced tree as a [`Skeleton`] anchored at `anchor`, positions
/// relative to `root` (the start point), radii zero until
/// [`pipe_radii`].
pub(super) fn to_skeleton(
    anchor: Anchor,
    points: &[Vec3],
    produced: &Produced,
    root: Vec3,
) -> Skeleton {
    let nodes: Vec<Node> = produced
        .nodes
        .iter()
        .map(|&(point, parent)| Node {
            position: points[point as usize] - root,
            radius_m: 0.0,
            parent: parent.map(|p| NodeId::from_index(p as usize)),
        })
        .collect();
    // Parents precede children by construction (a node is created when its
    // parent is popped), and positions are finite, so this cannot fail; the
    // fallback keeps the function total.
    Skeleton::from_nodes(anchor.clone(), nodes).unwrap_or_else(|_| Skeleton::new(anchor, 0.0))
}

/// Provisional pipe-model radii (§5.5, Eq. 6): a tip has R_const; a node's
/// radius is the root of the sum of its children's squared radii. The shared
/// radius stage replaces these.
pub(super) fn pipe_radii(skeleton: &mut Skeleton, tip_radius_m: f32) {
    let mut squared = vec![0.0f32; skeleton.len()];
    for id in skeleton.ids().rev() {
        let own = if skeleton.is_tip(id) {
            tip_radius_m * tip_radius_m
        } else {
            squared[id.index()]
        };
        squared[id.index()] = own;
        if let Some(parent) = skeleton.parent(id) {
            squared[parent.index()] += own;
        }
    }
    for id in skeleton.ids() {
        skeleton.set_radius(id, squared[id.index()].sqrt());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pruning_keeps_the_smoothest_of_close_directions() {
        let mut c = vec![
            Candidate {
                child: Vec3::Z,
                alpha: 0.0,
                j: 0,
            },
            Candidate {
                child: Vec3::new(0.1, 0.0, 1.0),
                alpha: 0.1,
                j: 1,
            },
            Candidate {
                child: Vec3::X,
                alpha: 1.5,
                j: 2,
            },
        ];
        prune(&mut c, 30f32.to_radians());
        assert_eq!(c.iter().map(|c| c.j).collect::<Vec<_>>(), vec![0, 2]);
    }

    #[test]
    fn grows_up_a_vertical_chain_and_forks() {
        let points = vec![
            Vec3::ZERO,
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(0.0, 0.0, 2.0),
            Vec3::new(0.8, 0.0, 2.6),
            Vec3::new(0.0, 0.0, -1.0),
        ];
        let adjacency: Vec<Vec<u32>> =
            vec![vec![1, 4], vec![0, 2, 4], vec![1, 3], vec![2], vec![0, 1]];
        let field = vec![Vec3::Z; 5];
        let produced = skeleton_produce(&points, &adjacency, &field, 0, 1, &Params::default());
        assert_eq!(
            produced.nodes,
            vec![(0, None), (1, Some(0)), (2, Some(1)), (3, Some(2))]
        );
        assert_eq!(produced.visited, 4);
    }
}
