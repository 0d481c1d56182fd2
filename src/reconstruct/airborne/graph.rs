//! The candidate graph: Hu et al. §5.2, Algorithm 1 (GraphGenerate(r_p, k)).
//!
//! Every candidate point is connected to all points within r_p (fixed-radius
//! nearest neighbours); a point with fewer than k such neighbours is also
//! connected to its k nearest points, however far. Sparse, unevenly sampled
//! airborne crowns thus give a connected graph without the many spurious
//! edges a large r_p would add. Edges are undirected; their weight is the
//! Euclidean length, which Algorithm 2 reads from the points themselves.

use glam::Vec3;

use crate::spatial::PointIndex;

/// Most fixed-radius neighbours kept per point, nearest first. Hu et al.'s
/// sparse clouds have a few dozen within r_p; the cap bounds memory when a
/// dense cloud is fed to the airborne pipeline, where the nearest 128
/// already span every direction Algorithm 2 can pick from.
const MAX_FRNN_NEIGHBOURS: usize = 128;

/// Adjacency lists of the Algorithm 1 graph over `points` (sorted, no self
/// loops, symmetric).
pub(super) fn graph(points: &[Vec3], radius_m: f32, k: usize) -> Vec<Vec<u32>> {
    let index = PointIndex::new(points);
    let mut adjacency: Vec<Vec<u32>> = points
        .iter()
        .enumerate()
        .map(|(i, &p)| {
            // The lists are sorted by index below, so the nearest-first order
            // is only needed (and paid for) when the cap applies.
            let mut near = index.within(p, radius_m);
            if near.len() > MAX_FRNN_NEIGHBOURS + 1 {
                near = index.nearest_k_within(p, MAX_FRNN_NEIGHBOURS + 1, radius_m);
            }
            near.into_iter()
                .filter(|n| n.index != i)
                .map(|n| n.index as u32)
                .collect()
        })
        .collect();
    // Second pass of Algorithm 1: kNN for points short of k neighbours.
    for (i, &p) in points.iter().enumerate() {
        if adjacency[i].len() < k {
            let knn = index.nearest_k(p, k + 1);
            adjacency[i].extend(knn.iter().filter(|n| n.index != i).map(|n| n.index as u32));
        }
    }
    // Edges are undirected: add every edge's reverse (the FRNN cap and the
    // kNN pass are not symmetric on their own).
    let reverse: Vec<(u32, u32)> = adjacency
        .iter()
        .enumerate()
        .flat_map(|(i, list)| list.iter().map(move |&j| (j, i as u32)))
        .collect();
    for (j, i) in reverse {
        adjacency[j as usize].push(i);
    }
    for list in &mut adjacency {
        list.sort_unstable();
        list.dedup();
    }
    adjacency
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn knn_connects_points_beyond_the_radius() {
        let pts = [
            Vec3::ZERO,
            Vec3::new(0.5, 0.0, 0.0),
            Vec3::new(5.0, 0.0, 0.0),
        ];
        let g = graph(&pts, 1.0, 2);
        assert_eq!(g[0], vec![1, 2]);
        assert_eq!(g[2], vec![0, 1]);
        assert!(
            g.iter()
                .enumerate()
                .all(|(i, l)| l.iter().all(|&j| g[j as usize].contains(&(i as u32))))
        );
        assert_eq!(graph(&pts, 1.0, 0)[2], Vec::<u32>::new());
    }
}
