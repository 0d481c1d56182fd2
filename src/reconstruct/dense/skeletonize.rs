//! From the shortest-path tree to skeleton nodes at branch centres.
//!
//! AdTree's minimum spanning tree runs over the bark, zigzagging between
//! surface points, and AdTree then centres it (mean shift) and simplifies it
//! (lsystem-from-adtree-skeletons §2.1.1; multi-temporal-tree-growth §3.2.1
//! describes the same zigzag). silva does both in one step: points are
//! binned by their geodesic distance from the trunk base; within a bin, the
//! points that are linked by graph edges form one cross-section of one
//! branch, and its centroid becomes a skeleton node. A node's parent is the
//! cross-section that holds the shortest-path predecessor of its closest
//! point, so the skeleton inherits the shortest-path tree's topology while
//! its nodes sit inside the branches, not on the bark.

use glam::{DVec3, Vec3};

use super::graph::{Graph, UnionFind};
use crate::skeleton::{Node, NodeId};

/// Skeleton nodes (relative to the points' frame) and the number of points
/// behind each; node 0 is the root at `root`.
pub(super) struct Sections {
    pub(super) nodes: Vec<Node>,
    pub(super) counts: Vec<u32>,
    /// RMS distance of each section's points to its centroid, in metres.
    pub(super) spread_m: Vec<f32>,
}

/// Builds one node per branch cross-section. `dist` and `pred` come from the
/// shortest-path tree over `graph`; every point must be reachable.
pub(super) fn cross_sections(
    points: &[Vec3],
    graph: &Graph,
    dist: &[f32],
    pred: &[u32],
    bin_m: f32,
    root: Vec3,
) -> Sections {
    let n = points.len();
    let bin: Vec<u32> = dist.iter().map(|&d| (d / bin_m) as u32).collect();
    let mut uf = UnionFind::new(n);
    // Bin 0 (everything within one bin of the base slice) is the root.
    let first_base = (0..n).find(|&i| bin[i] == 0).unwrap_or(0) as u32;
    for i in 0..n as u32 {
        if bin[i as usize] == 0 {
            uf.union(first_base, i);
        }
    }
    // Points of one bin join when linked directly or through a common
    // neighbour: thin bins on a sparsely sampled stem would otherwise break
    // into arcs whose centroids sit on the bark.
    let mut around: Vec<(u32, u32)> = Vec::new();
    for v in 0..n {
        around.clear();
        around.push((bin[v], v as u32));
        around.extend(
            graph
                .neighbours(v)
                .iter()
                .map(|&(w, _)| (bin[w as usize], w)),
        );
        around.sort_unstable();
        for pair in around.windows(2) {
            if pair[0].0 == pair[1].0 {
                uf.union(pair[0].1, pair[1].1);
            }
        }
    }
    // Per cross-section: its closest point to the base, centroid, count.
    let mut lowest = vec![u32::MAX; n];
    let mut sum = vec![DVec3::ZERO; n];
    let mut sum_sq = vec![0f64; n];
    let mut count = vec![0u32; n];
    for i in 0..n as u32 {
        let r = uf.find(i) as usize;
        if lowest[r] == u32::MAX || dist[i as usize] < dist[lowest[r] as usize] {
            lowest[r] = i;
        }
        let p = points[i as usize].as_dvec3();
        sum[r] += p;
        sum_sq[r] += p.length_squared();
        count[r] += 1;
    }
    let mut sections: Vec<usize> = (0..n).filter(|&r| count[r] > 0).collect();
    sections.sort_by(|&a, &b| {
        let (la, lb) = (lowest[a] as usize, lowest[b] as usize);
        (bin[la], dist[la])
            .partial_cmp(&(bin[lb], dist[lb]))
            .unwrap_or(std::cmp::Ordering::Equal)
    });
    let mut node_of = vec![u32::MAX; n];
    let mut nodes = Vec::with_capacity(sections.len());
    let mut counts = Vec::with_capacity(sections.len());
    let mut spread_m = Vec::with_capacity(sections.len());
    for (id, &r) in sections.iter().enumerate() {
        node_of[r] = id as u32;
        let low = lowest[r] as usize;
        let (position, parent) = if id == 0 {
            (root, None)
        } else {
            let p = pred[low];
            // Reachability guarantees a predecessor in a lower bin, whose
            // section is already numbered; fall back to the root otherwise.
            let parent_node = if p == u32::MAX {
                0
            } else {
                node_of[uf.find(p) as usize]
            };
            let parent_node = if parent_node == u32::MAX {
                0
            } else {
                parent_node
            };
            let centroid = (sum[r] / f64::from(count[r])).as_vec3();
            (centroid, Some(NodeId::from_index(parent_node as usize)))
        };
        let c = f64::from(count[r]);
        let mean = sum[r] / c;
        let spread = (sum_sq[r] / c - mean.length_squared()).max(0.0).sqrt() as f32;
        // The spread stands in for the radius until the radius stage runs;
        // pruning uses it to tell bark noise from branches.
        nodes.push(Node {
            position,
            radius_m: spread,
            parent,
        });
        counts.push(count[r]);
        spread_m.push(spread);
    }
    Sections {
        nodes,
        counts,
        spread_m,
    }
}

#[cfg(test)]
mod tests {
    use super::super::graph::{Graph, shortest_path_tree};
    use super::*;

    #[test]
    fn a_ring_of_points_collapses_to_its_centre() {
        // Two rings of 8 points, 0.1 m apart vertically: bin 0 holds the
        // lower ring, the upper ring becomes one node at its centre.
        let mut pts = Vec::new();
        for z in [0.0, 0.1] {
            for k in 0..8 {
                let a = k as f32 * std::f32::consts::TAU / 8.0;
                pts.push(Vec3::new(1.0 + 0.05 * a.cos(), 0.05 * a.sin(), z));
            }
        }
        let mut edges = Vec::new();
        for k in 0..8u32 {
            edges.push((k, (k + 1) % 8, 0.04));
            edges.push((8 + k, 8 + (k + 1) % 8, 0.04));
            edges.push((k, k + 8, 0.1));
        }
        let g = Graph::from_edges(pts.len(), &edges);
        let (dist, pred) = shortest_path_tree(&g, &(0..8).collect::<Vec<_>>());
        let s = cross_sections(&pts, &g, &dist, &pred, 0.08, Vec3::new(1.0, 0.0, 0.0));
        assert_eq!(s.nodes.len(), 2);
        assert!(s.nodes[1].position.distance(Vec3::new(1.0, 0.0, 0.1)) < 1e-4);
        assert_eq!(s.nodes[1].parent, Some(NodeId::ROOT));
        assert_eq!(s.counts, vec![8, 8]);
    }
}
