//! The neighbourhood graph and the shortest-path tree (AdTree's skeleton
//! initialisation, lsystem-from-adtree-skeletons §2.1.1).
//!
//! AdTree triangulates the points (Delaunay) and runs Dijkstra on the edge
//! lengths. spade triangulates in 2D only, so silva links each point to its
//! `k` nearest neighbours (kiddo via [`PointIndex`]), symmetrises the links,
//! and joins separate components by their closest point pairs so that every
//! point is reachable from the trunk base.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use glam::Vec3;

use crate::spatial::PointIndex;

/// An undirected weighted graph in compressed adjacency form.
pub(super) struct Graph {
    start: Vec<u32>,
    adjacent: Vec<(u32, f32)>,
}

impl Graph {
    /// Builds the symmetric graph from undirected edges `(a, b, length)`.
    pub(super) fn from_edges(n: usize, edges: &[(u32, u32, f32)]) -> Self {
        let mut degree = vec![0u32; n + 1];
        for &(a, b, _) in edges {
            degree[a as usize + 1] += 1;
            degree[b as usize + 1] += 1;
        }
        for i in 0..n {
            degree[i + 1] += degree[i];
        }
        let start = degree.clone();
        let mut fill = degree;
        let mut adjacent = vec![(0u32, 0f32); edges.len() * 2];
        for &(a, b, w) in edges {
            adjacent[fill[a as usize] as usize] = (b, w);
            fill[a as usize] += 1;
            adjacent[fill[b as usize] as usize] = (a, w);
            fill[b as usize] += 1;
        }
        Self { start, adjacent }
    }

    /// Number of vertices.
    pub(super) fn len(&self) -> usize {
        self.start.len() - 1
    }

    /// Neighbours of `v` with edge lengths.
    pub(super) fn neighbours(&self, v: usize) -> &[(u32, f32)] {
        &self.adjacent[self.start[v] as usize..self.start[v + 1] as usize]
    }
}

/// Undirected edges from every point to its `k` nearest neighbours, each
/// pair once, leaving out links longer than `max_edge_m` (an isolated
/// outlier's k nearest neighbours may be metres away).
///
/// The queries are bounded by `max_edge_m`: a neighbour beyond it gives no
/// edge, and leaving it out of the lists cannot change the mutual-pair test
/// below, which only concerns pairs within `max_edge_m`. The lists are found
/// cell by cell ([`PointIndex::each_nearest_k_within`]): one kd-tree query
/// per point took a quarter of the dense pipeline's time on tree1.
pub(super) fn knn_edges(
    points: &[Vec3],
    index: &PointIndex,
    k: usize,
    max_edge_m: f32,
) -> Vec<(u32, u32, f32)> {
    // Short lists (tiny clouds) are padded so that list i starts at i·k.
    let mut lists: Vec<u32> = (0..points.len() as u32)
        .flat_map(|i| std::iter::repeat_n(i, k))
        .collect();
    let mut lengths = vec![f32::INFINITY; points.len() * k];
    index.each_nearest_k_within(points, k, max_edge_m, |i, near| {
        for (slot, n) in near.iter().enumerate() {
            lists[i * k + slot] = n.index as u32;
            lengths[i * k + slot] = n.distance_sq.sqrt();
        }
    });
    let list = |j: usize| &lists[j * k..(j + 1) * k];
    let mut edges = Vec::with_capacity(points.len() * k);
    for i in 0..points.len() {
        for (slot, &j) in list(i).iter().enumerate() {
            let w = lengths[i * k + slot];
            let j = j as usize;
            // A mutual pair is emitted once, by its smaller end.
            let mutual_elsewhere = j < i && list(j).contains(&(i as u32));
            if j != i && w <= max_edge_m && !mutual_elsewhere {
                edges.push((i.min(j) as u32, i.max(j) as u32, w));
            }
        }
    }
    edges
}

/// Disjoint-set forest with path halving and union by size.
#[derive(Clone)]
pub(crate) struct UnionFind {
    parent: Vec<u32>,
    size: Vec<u32>,
}

impl UnionFind {
    /// `n` singleton sets.
    pub(crate) fn new(n: usize) -> Self {
        Self {
            parent: (0..n as u32).collect(),
            size: vec![1; n],
        }
    }

    /// Representative of `v`'s set.
    pub(crate) fn find(&mut self, mut v: u32) -> u32 {
        while self.parent[v as usize] != v {
            let grand = self.parent[self.parent[v as usize] as usize];
            self.parent[v as usize] = grand;
            v = grand;
        }
        v
    }

    /// Joins the sets of `a` and `b`.
    pub(crate) fn union(&mut self, a: u32, b: u32) {
        let (a, b) = (self.find(a), self.find(b));
        if a == b {
            return;
        }
        let (big, small) = if self.size[a as usize] >= self.size[b as usize] {
            (a, b)
        } else {
            (b, a)
        };
        self.parent[small as usize] = big;
        self.size[big as usize] += self.size[small as usize];
    }
}

/// Connected components: a label per point, labels numbered from 0 by
/// decreasing size.
pub(super) fn components(n: usize, edges: &[(u32, u32, f32)]) -> (Vec<u32>, Vec<usize>) {
    let mut uf = UnionFind::new(n);
    for &(a, b, _) in edges {
        uf.union(a, b);
    }
    let roots: Vec<u32> = (0..n as u32).map(|v| uf.find(v)).collect();
    let mut count = vec![0usize; n];
    for &r in &roots {
        count[r as usize] += 1;
    }
    let mut order: Vec<u32> = (0..n as u32).filter(|&r| count[r as usize] > 0).collect();
    order.sort_by_key(|&r| (Reverse(count[r as usize]), r));
    let mut label_of_root = vec![u32::MAX; n];
    for (label, &r) in order.iter().enumerate() {
        label_of_root[r as usize] = label as u32;
    }
    let labels = roots.iter().map(|&r| label_of_root[r as usize]).collect();
    let sizes = order.iter().map(|&r| count[r as usize]).collect();
    (labels, sizes)
}

/// A component that joined the tree through a bridging edge.
#[derive(Debug, Clone, Copy)]
pub(super) struct Bridge {
    /// The bridging edge `(a, b, length)`.
    pub(super) edge: (u32, u32, f32),
    /// Points in the component it joined.
    pub(super) points: usize,
}

/// Joins every component to component 0 (the largest), nearest component
/// first, like Prim's algorithm on components. Each round finds every
/// pending component's closest pair to the joined points; the closest
/// component joins, together with any component within `near_m` (their
/// order cannot matter). Returns the bridges in joining order.
///
/// The joined set only grows, so a component's closest pair to it is the
/// closest of its pairs to each round's newcomers: each round indexes only
/// the points that joined in the round before, and every point is indexed
/// once (rebuilding one index of all joined points per round cost a tenth
/// of the dense pipeline's time on tree1).
pub(super) fn bridge_components(
    points: &[Vec3],
    labels: &[u32],
    sizes: &[usize],
    near_m: f32,
) -> Vec<Bridge> {
    let mut members: Vec<Vec<u32>> = vec![Vec::new(); sizes.len()];
    for (i, &l) in labels.iter().enumerate() {
        members[l as usize].push(i as u32);
    }
    let mut newcomers: Vec<u32> = std::mem::take(&mut members[0]);
    // Each pending component's closest pair (joined, member, length) so far.
    let mut best: Vec<(usize, (u32, u32, f32))> = (1..sizes.len())
        .map(|c| {
            (
                c,
                (0, members[c].first().copied().unwrap_or(0), f32::INFINITY),
            )
        })
        .collect();
    let mut bridges = Vec::new();
    while !best.is_empty() {
        closer_to_newcomers(points, &newcomers, &members, &mut best);
        best.sort_by(|a, b| a.1.2.total_cmp(&b.1.2));
        let cutoff = best[0].1.2.max(near_m);
        let joining = best.iter().take_while(|(_, e)| e.2 <= cutoff).count();
        newcomers.clear();
        for (c, edge) in best.drain(..joining) {
            bridges.push(Bridge {
                edge,
                points: members[c].len(),
            });
            newcomers.append(&mut members[c]);
        }
    }
    bridges
}

/// Lowers each pending component's closest pair to its closest pair to
/// `newcomers`, when that is strictly shorter.
fn closer_to_newcomers(
    points: &[Vec3],
    newcomers: &[u32],
    members: &[Vec<u32>],
    best: &mut [(usize, (u32, u32, f32))],
) {
    let newcomer_pts: Vec<Vec3> = newcomers.iter().map(|&i| points[i as usize]).collect();
    let index = PointIndex::new(&newcomer_pts);
    for (c, edge) in best.iter_mut() {
        for &i in &members[*c] {
            let Some(n) = index.nearest(points[i as usize]) else {
                return;
            };
            let length = n.distance_sq.sqrt();
            if length < edge.2 {
                *edge = (newcomers[n.index], i, length);
            }
        }
    }
}

/// Dijkstra's shortest-path tree from several sources at distance 0.
/// Returns the geodesic distance and the predecessor of every vertex
/// (`u32::MAX` for sources and unreachable vertices).
pub(super) fn shortest_path_tree(graph: &Graph, sources: &[u32]) -> (Vec<f32>, Vec<u32>) {
    let n = graph.len();
    let mut dist = vec![f32::INFINITY; n];
    let mut pred = vec![u32::MAX; n];
    let mut heap = BinaryHeap::new();
    for &s in sources {
        dist[s as usize] = 0.0;
        heap.push(Reverse((OrdF32(0.0), s)));
    }
    while let Some(Reverse((OrdF32(d), v))) = heap.pop() {
        if d > dist[v as usize] {
            continue;
        }
        for &(w, len) in graph.neighbours(v as usize) {
            let nd = d + len;
            if nd < dist[w as usize] {
                dist[w as usize] = nd;
                pred[w as usize] = v;
                heap.push(Reverse((OrdF32(nd), w)));
            }
        }
    }
    (dist, pred)
}

/// A totally ordered `f32` for the priority queue (distances are finite).
#[derive(Debug, Clone, Copy, PartialEq)]
struct OrdF32(f32);

impl Eq for OrdF32 {}

impl PartialOrd for OrdF32 {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for OrdF32 {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.0.total_cmp(&other.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_clusters_are_bridged_by_their_closest_pair() {
        let pts = vec![
            Vec3::ZERO,
            Vec3::new(0.1, 0.0, 0.0),
            Vec3::new(0.2, 0.0, 0.0),
            Vec3::new(1.2, 0.0, 0.0),
            Vec3::new(1.3, 0.0, 0.0),
        ];
        let edges = vec![(0, 1, 0.1), (1, 2, 0.1), (3, 4, 0.1)];
        let (labels, sizes) = components(pts.len(), &edges);
        assert_eq!(sizes, vec![3, 2]);
        let bridges = bridge_components(&pts, &labels, &sizes, 0.0);
        assert_eq!(bridges.len(), 1);
        assert_eq!((bridges[0].edge.0, bridges[0].edge.1), (2, 3));
        assert!((bridges[0].edge.2 - 1.0).abs() < 1e-5);
    }

    #[test]
    fn a_component_joins_through_the_one_that_joined_before_it() {
        // A (the largest) at x 0–0.3, B at 1.3–1.4, C at 2.4–2.5: C is 2.1 m
        // from A but 1.0 m from B, so it joins B once B has joined.
        let xs = [0.0, 0.1, 0.2, 0.3, 1.3, 1.4, 2.4, 2.5];
        let pts: Vec<Vec3> = xs.iter().map(|&x| Vec3::new(x, 0.0, 0.0)).collect();
        let edges = vec![
            (0, 1, 0.1),
            (1, 2, 0.1),
            (2, 3, 0.1),
            (4, 5, 0.1),
            (6, 7, 0.1),
        ];
        let (labels, sizes) = components(pts.len(), &edges);
        let bridges = bridge_components(&pts, &labels, &sizes, 0.0);
        let joined: Vec<(u32, u32)> = bridges.iter().map(|b| (b.edge.0, b.edge.1)).collect();
        assert_eq!(joined, vec![(3, 4), (5, 6)]);
        assert!((bridges[1].edge.2 - 1.0).abs() < 1e-5);
    }

    #[test]
    fn shortest_paths_follow_the_cheapest_route() {
        let g = Graph::from_edges(4, &[(0, 1, 1.0), (1, 2, 1.0), (0, 2, 3.0), (2, 3, 1.0)]);
        let (dist, pred) = shortest_path_tree(&g, &[0]);
        assert_eq!(dist, vec![0.0, 1.0, 2.0, 3.0]);
        assert_eq!(pred, vec![u32::MAX, 0, 1, 2]);
    }
}
