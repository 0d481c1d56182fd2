//! Nearest-neighbour queries over 3D points: the one kd-tree of the crate.
//!
//! Every stage that needs neighbours (clean-up, the dense and airborne graphs,
//! evaluation) goes through [`PointIndex`], so there is one place that knows
//! kiddo's API and its corner cases. It wraps kiddo's `ImmutableKdTree`,
//! which is balanced at build time and, unlike the mutable tree, accepts any
//! number of points with equal coordinates: duplicate-heavy or hostile clouds
//! cannot make it panic.

use std::num::NonZero;

use glam::Vec3;
use kiddo::SquaredEuclidean;
use kiddo::immutable::float::kdtree::ImmutableKdTree;

/// Leaf size of the kd-tree; 32 is kiddo's recommended default for 3D.
const BUCKET: usize = 32;

/// Most points [`PointIndex::median_spacing`] samples.
const SPACING_SAMPLES: usize = 2000;

/// A neighbour found by a query: the point's index in the indexed slice and
/// its squared distance to the query point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Neighbour {
    /// Index into the slice the index was built from.
    pub index: usize,
    /// Squared Euclidean distance in m².
    pub distance_sq: f32,
}

/// A static kd-tree over a slice of points (indices refer to that slice).
///
/// ```
/// use glam::Vec3;
/// use silva::spatial::PointIndex;
///
/// let pts = [Vec3::ZERO, Vec3::X, Vec3::new(5.0, 0.0, 0.0)];
/// let index = PointIndex::new(&pts);
/// let near = index.nearest_k(Vec3::new(0.9, 0.0, 0.0), 2);
/// assert_eq!(near[0].index, 1);
/// assert_eq!(index.within(Vec3::ZERO, 1.5).len(), 2);
/// ```
pub struct PointIndex {
    tree: Option<ImmutableKdTree<f32, u32, 3, BUCKET>>,
    len: usize,
}

impl PointIndex {
    /// Builds the index. Points must be finite (readers guarantee it).
    pub fn new(points: &[Vec3]) -> Self {
        let coords: Vec<[f32; 3]> = points.iter().map(|p| p.to_array()).collect();
        let tree = (!coords.is_empty()).then(|| ImmutableKdTree::new_from_slice(&coords));
        Self {
            tree,
            len: points.len(),
        }
    }

    /// Number of indexed points.
    pub fn len(&self) -> usize {
        self.len
    }

    /// True when no point is indexed.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The nearest indexed point, or `None` for an empty index.
    pub fn nearest(&self, query: Vec3) -> Option<Neighbour> {
        let tree = self.tree.as_ref()?;
        let n = tree.nearest_one::<SquaredEuclidean>(&query.to_array());
        Some(to_neighbour(n))
    }

    /// The `k` nearest points, closest first (fewer if the index is smaller).
    /// The query point itself is included when it is indexed.
    pub fn nearest_k(&self, query: Vec3, k: usize) -> Vec<Neighbour> {
        let (Some(tree), Some(k)) = (self.tree.as_ref(), NonZero::new(k)) else {
            return Vec::new();
        };
        tree.nearest_n::<SquaredEuclidean>(&query.to_array(), k)
            .into_iter()
            .map(to_neighbour)
            .collect()
    }

    /// All points within `radius` (inclusive), in no particular order.
    pub fn within(&self, query: Vec3, radius: f32) -> Vec<Neighbour> {
        let Some(tree) = self.tree.as_ref() else {
            return Vec::new();
        };
        tree.within_unsorted::<SquaredEuclidean>(&query.to_array(), radius * radius)
            .into_iter()
            .map(to_neighbour)
            .collect()
    }

    /// At most `k` points within `radius`, closest first (equal distances by
    /// index, so the order does not depend on the tree's layout).
    pub fn nearest_k_within(&self, query: Vec3, k: usize, radius: f32) -> Vec<Neighbour> {
        let (Some(tree), Some(k)) = (self.tree.as_ref(), NonZero::new(k)) else {
            return Vec::new();
        };
        // kiddo keeps a bounded heap when asked for unsorted results and a
        // sorted vector (an insertion per candidate) otherwise; the heap and
        // one sort of the `k` results are a quarter faster for the dense
        // graph's k = 11.
        let mut found: Vec<Neighbour> = tree
            .nearest_n_within::<SquaredEuclidean>(&query.to_array(), radius * radius, k, false)
            .into_iter()
            .map(to_neighbour)
            .collect();
        found.sort_unstable_by(|a, b| {
            a.distance_sq
                .total_cmp(&b.distance_sq)
                .then(a.index.cmp(&b.index))
        });
        found
    }

    /// Median distance from up to 2,000 evenly picked `points` to their
    /// nearest other point; `points` must be the indexed slice. `None` when
    /// fewer than two points are indexed.
    ///
    /// ```
    /// use glam::Vec3;
    /// use silva::spatial::PointIndex;
    ///
    /// let pts: Vec<Vec3> = (0..10).map(|i| Vec3::new(0.02 * i as f32, 0.0, 0.0)).collect();
    /// let spacing = PointIndex::new(&pts).median_spacing(&pts).unwrap();
    /// assert!((spacing - 0.02).abs() < 1e-6);
    /// ```
    pub fn median_spacing(&self, points: &[Vec3]) -> Option<f32> {
        let step = (points.len() / SPACING_SAMPLES).max(1);
        let mut nearest: Vec<f32> = points
            .iter()
            .step_by(step)
            .filter_map(|&p| self.nearest_k(p, 2).get(1).map(|n| n.distance_sq.sqrt()))
            .collect();
        let mid = nearest.len() / 2;
        (!nearest.is_empty()).then(|| *nearest.select_nth_unstable_by(mid, f32::total_cmp).1)
    }
}

fn to_neighbour(n: kiddo::NearestNeighbour<f32, u32>) -> Neighbour {
    Neighbour {
        index: n.item as usize,
        distance_sq: n.distance,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bounded_neighbours_come_closest_first_and_ties_by_index() {
        let pts = [
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(0.0, 0.5, 0.0),
        ];
        let index = PointIndex::new(&pts);
        let near: Vec<usize> = index
            .nearest_k_within(Vec3::ZERO, 4, 1.5)
            .iter()
            .map(|n| n.index)
            .collect();
        assert_eq!(near, vec![4, 0, 2, 3]);
        assert_eq!(index.nearest_k_within(Vec3::ZERO, 2, 0.6).len(), 1);
    }
}
