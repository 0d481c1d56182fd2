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

/// Resolution of the bending-angle ordering of child candidates (radians,
/// 5°); see the sort in [`skeleton_produce`].
const ALPHA_STEP: f32 = 5.0 * std::f32::consts::PI / 180.0;

/// The tree Algorithm 2 produced, as skeleton nodes over candidate points.
#[derive(Debug, Clone)]
pub(super) struct Produced {
    /// Per skeleton node: its candidate point and its parent node (parents
    /// first; node 0 is the start point, node 1 the end point).
    pub(super) nodes: Vec<(u32, Option<u32>)>,
    /// Candidate points marked visited (skeleton nodes and pruned ones).
    pub(super) visited: usize,
    /// Of those, the points Algorithm 2 itself reached, before re-attachment.
    pub(super) reached_by_algorithm2: usize,
}

/// A child candidate of the popped point (the paper's node n_s).
struct Candidate {
    child: Vec3,
    alpha: f32,
    j: u32,
}

/// Algorithm 2 over `points` with graph `adjacency` and direction field
/// `field`, starting with the segment `start` → `end` (§5.4), followed by
/// [`Growth::reattach`] rounds until no unvisited point borders the
/// skeleton.
pub(super) fn skeleton_produce(
    points: &[Vec3],
    adjacency: &[Vec<u32>],
    field: &[Vec3],
    start: usize,
    end: usize,
    params: &Params,
) -> Produced {
    let mut growth = Growth::new(points, adjacency, field, params);
    growth.visit(start, None);
    let end_node = growth.visit(end, Some(0));
    growth.push(0.0, start as u32, end as u32, end_node);
    growth.run();
    let reached = growth.visited_count();
    let mut rounds = 0;
    while rounds < MAX_REATTACH_ROUNDS && growth.reattach() {
        growth.run();
        rounds += 1;
    }
    Produced {
        reached_by_algorithm2: reached,
        visited: growth.visited_count(),
        nodes: growth.nodes,
    }
}

/// Most rounds of re-attachment after Algorithm 2; each round extends the
/// skeleton by at least one graph hop, and crowns are a few dozen hops wide.
const MAX_REATTACH_ROUNDS: usize = 200;

/// A segment waiting in Q: (key bits, sequence, k, i, node of i).
type QueueEntry = (u32, u64, u32, u32, u32);

/// The state of Algorithm 2: visited flags, the tree T (as nodes) and the
/// priority queue Q.
struct Growth<'a> {
    points: &'a [Vec3],
    adjacency: &'a [Vec<u32>],
    field: &'a [Vec3],
    alpha_max: f32,
    beta_max: f32,
    phi_max: f32,
    visited: Vec<bool>,
    /// Skeleton node of each point that is one, `u32::MAX` otherwise.
    node_of: Vec<u32>,
    nodes: Vec<(u32, Option<u32>)>,
    /// Entries (key bits, sequence, k, i, node of i). Keys are in [0, 1],
    /// where the bit pattern of a non-negative f32 orders like its value;
    /// the sequence number breaks ties in insertion order.
    queue: BinaryHeap<Reverse<QueueEntry>>,
    sequence: u64,
}

impl<'a> Growth<'a> {
    fn new(
        points: &'a [Vec3],
        adjacency: &'a [Vec<u32>],
        field: &'a [Vec3],
        params: &Params,
    ) -> Self {
        Self {
            points,
            adjacency,
            field,
            alpha_max: params.alpha_max_deg.to_radians(),
            beta_max: params.beta_max_deg.to_radians(),
            phi_max: params.phi_max_deg.to_radians(),
            visited: vec![false; points.len()],
            node_of: vec![u32::MAX; points.len()],
            nodes: Vec::new(),
            queue: BinaryHeap::new(),
            sequence: 0,
        }
    }

    fn visited_count(&self) -> usize {
        self.visited.iter().filter(|&&v| v).count()
    }

    /// Makes point `j` a skeleton node under `parent` and returns the node.
    fn visit(&mut self, j: usize, parent: Option<u32>) -> u32 {
        let node = self.nodes.len() as u32;
        self.nodes.push((j as u32, parent));
        self.visited[j] = true;
        self.node_of[j] = node;
        node
    }

    fn push(&mut self, key: f32, k: u32, i: u32, node_i: u32) {
        let key = key.clamp(0.0, 1.0).to_bits();
        self.queue.push(Reverse((key, self.sequence, k, i, node_i)));
        self.sequence += 1;
    }

    /// The main loop of Algorithm 2, until Q is empty.
    fn run(&mut self) {
        let mut candidates: Vec<Candidate> = Vec::new();
        while let Some(Reverse((_, _, k, i, node_i))) = self.queue.pop() {
            let p_i = self.points[i as usize];
            let parent = p_i - self.points[k as usize];
            candidates.clear();
            for &j in &self.adjacency[i as usize] {
                if self.visited[j as usize] {
                    continue;
                }
                let child = self.points[j as usize] - p_i;
                let alpha = angle(child, parent);
                let beta = angle(self.field[j as usize], child);
                if alpha < self.alpha_max && beta < self.beta_max {
                    candidates.push(Candidate { child, alpha, j });
                    self.visited[j as usize] = true;
                }
            }
            // Sort by α (the paper's C.sort()), in steps of ALPHA_STEP so
            // that near-ties (collinear points, float noise) go to the
            // farther point: every qualifying neighbour was just marked
            // visited, so a near survivor would find its own neighbourhood
            // used up and stall.
            candidates.sort_by(|a, b| {
                let bucket = |c: &Candidate| (c.alpha / ALPHA_STEP).floor();
                bucket(a).total_cmp(&bucket(b)).then(
                    b.child
                        .length_squared()
                        .total_cmp(&a.child.length_squared()),
                )
            });
            prune(&mut candidates, self.phi_max);
            for c in &candidates {
                let node = self.visit(c.j as usize, Some(node_i));
                self.push(c.alpha / self.alpha_max, i, c.j, node);
            }
        }
    }

    /// Sparse airborne graphs leave points that Algorithm 2's greedy claims
    /// cut off: a pruned candidate stays visited and walls off what lies
    /// behind it (Hu et al. §6.2 retry parameter sets until 85 % are
    /// visited). Instead, every point that is not yet a skeleton node (pruned
    /// or never visited) and is adjacent to one is attached to the nearest
    /// such node and grown from. False when no point could be attached.
    fn reattach(&mut self) -> bool {
        let mut attached = false;
        for j in 0..self.points.len() {
            if self.node_of[j] != u32::MAX {
                continue;
            }
            let p_j = self.points[j];
            let nearest = self.adjacency[j]
                .iter()
                .filter(|&&i| self.node_of[i as usize] != u32::MAX)
                .min_by(|&&a, &&b| {
                    let da = self.points[a as usize].distance_squared(p_j);
                    let db = self.points[b as usize].distance_squared(p_j);
                    da.total_cmp(&db)
                });
            if let Some(&i) = nearest {
                let node = self.visit(j, Some(self.node_of[i as usize]));
                self.push(1.0, i, j as u32, node);
                attached = true;
            }
        }
        attached
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
        // Point 4 lies behind the start; only re-attachment reaches it.
        assert_eq!(
            produced.nodes,
            vec![
                (0, None),
                (1, Some(0)),
                (2, Some(1)),
                (3, Some(2)),
                (4, Some(0))
            ]
        );
        assert_eq!(produced.reached_by_algorithm2, 4);
        assert_eq!(produced.visited, 5);
    }
}
