//! Nearest-neighbour queries over 3D points: the one kd-tree of the crate.
//!
//! Every stage that needs neighbours (clean-up, the dense and airborne graphs,
//! evaluation) goes through [`PointIndex`], so there is one place that knows
//! kiddo's API and its corner cases. It wraps kiddo's `ImmutableKdTree`,
//! which is balanced at build time and, unlike the mutable tree, accepts any
//! number of points with equal coordinates: duplicate-heavy or hostile clouds
//! cannot make it panic.

mod cells;

use std::num::NonZero;

use glam::Vec3;
use kiddo::SquaredEuclidean;
use kiddo::immutable::float::kdtree::ImmutableKdTree;

use cells::CellGrid;

/// Leaf size of the kd-tree; 32 is kiddo's recommended default for 3D.
const BUCKET: usize = 32;

/// Most points [`PointIndex::median_spacing`] samples.
const SPACING_SAMPLES: usize = 2000;

/// Fewest points for which [`PointIndex::each_nearest_k_within`] sorts the
/// cloud into cells; smaller clouds query the kd-tree point by point.
const GRID_MIN_POINTS: usize = 256;

/// Points whose `k`-th neighbour distance sizes the grid's cells.
const GRID_SAMPLES: usize = 64;

/// Cell edge over the sampled `k`-th neighbour distance. Larger cells hand
/// fewer points on to the kd-tree but give each point more candidates; on
/// tree1 (k = 10) 1.0, 1.25, 1.5 and 2 left 16, 9, 5 and 0.6 % of the points
/// unsure, and 1.5 was the fastest.
const GRID_CELL_REACHES: f32 = 1.5;

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

    /// For every point of `points`, which must be the indexed slice, its `k`
    /// nearest other points within `radius`, closest first (equal distances
    /// by index): `visit(i, neighbours)` is called once per point, in no
    /// particular order. The answers are those of [`Self::nearest_k_within`]
    /// without the point itself, found cell by cell (a grid of cubic cells,
    /// module `spatial::cells`) where the cloud is large enough for a grid to
    /// pay.
    ///
    /// ```
    /// use glam::Vec3;
    /// use silva::spatial::PointIndex;
    ///
    /// let pts: Vec<Vec3> = (0..1000).map(|i| Vec3::new(0.01 * i as f32, 0.0, 0.0)).collect();
    /// let index = PointIndex::new(&pts);
    /// let mut firsts = vec![usize::MAX; pts.len()];
    /// index.each_nearest_k_within(&pts, 2, 0.05, |i, near| firsts[i] = near[0].index);
    /// assert_eq!((firsts[0], firsts[1], firsts[999]), (1, 0, 998));
    /// ```
    pub fn each_nearest_k_within(
        &self,
        points: &[Vec3],
        k: usize,
        radius: f32,
        mut visit: impl FnMut(usize, &[Neighbour]),
    ) {
        let grid = (points.len() >= GRID_MIN_POINTS && k > 0)
            .then(|| self.cell_size(points, k, radius))
            .and_then(|cell_m| CellGrid::new(points, cell_m));
        let mut unsure = Vec::new();
        if let Some(grid) = grid {
            let mut scratch = cells::Scratch::default();
            for cell in grid.cells() {
                grid.nearest_k_within(&cell, (k, radius), &mut scratch, &mut visit, |i| {
                    unsure.push(i)
                });
            }
        } else {
            unsure.extend(0..points.len());
        }
        for i in unsure {
            let near: Vec<Neighbour> = self
                .nearest_k_within(points[i], k + 1, radius)
                .into_iter()
                .filter(|n| n.index != i)
                .take(k)
                .collect();
            visit(i, &near);
        }
    }

    /// The cell edge for [`Self::each_nearest_k_within`]: the distance to
    /// the `k`-th neighbour at the upper quartile of a sample of the points,
    /// at most `radius` (where every answer is certain).
    fn cell_size(&self, points: &[Vec3], k: usize, radius: f32) -> f32 {
        let step = (points.len() / GRID_SAMPLES).max(1);
        let mut reach: Vec<f32> = points
            .iter()
            .step_by(step)
            .map(|&p| {
                let near = self.nearest_k_within(p, k + 1, radius);
                near.get(k).map_or(radius, |n| n.distance_sq.sqrt())
            })
            .collect();
        let upper = reach.len() * 3 / 4;
        let quartile = *reach.select_nth_unstable_by(upper, f32::total_cmp).1;
        (GRID_CELL_REACHES * quartile).min(radius)
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

    /// Each point's `k` nearest others within `radius` by brute force,
    /// closest first and equal distances by index.
    fn brute_force(points: &[Vec3], k: usize, radius: f32) -> Vec<Vec<Neighbour>> {
        let within = |i: usize| {
            let mut near: Vec<Neighbour> = (0..points.len())
                .filter(|&j| j != i)
                .map(|j| {
                    let d = points[j] - points[i];
                    let distance_sq = d.x * d.x + d.y * d.y + d.z * d.z;
                    Neighbour {
                        index: j,
                        distance_sq,
                    }
                })
                .filter(|n| n.distance_sq <= radius * radius)
                .collect();
            near.sort_by(|a, b| {
                (a.distance_sq, a.index)
                    .partial_cmp(&(b.distance_sq, b.index))
                    .expect("finite distances")
            });
            near.truncate(k);
            near
        };
        (0..points.len()).map(within).collect()
    }

    /// Whether `found` is a right answer where `truth` is the brute force's:
    /// the same distances, and the same points except among those tied at
    /// the last distance (the kd-tree keeps any of them).
    fn same_answer(found: &[Neighbour], truth: &[Neighbour]) -> bool {
        let distances = |l: &[Neighbour]| l.iter().map(|n| n.distance_sq).collect::<Vec<_>>();
        let last = truth.last().map_or(0.0, |n| n.distance_sq);
        let inside = |l: &[Neighbour]| {
            let mut ids: Vec<usize> = l
                .iter()
                .filter(|n| n.distance_sq < last)
                .map(|n| n.index)
                .collect();
            ids.sort_unstable();
            ids
        };
        distances(found) == distances(truth) && inside(found) == inside(truth)
    }

    fn answers(points: &[Vec3], k: usize, radius: f32) -> Vec<Option<Vec<Neighbour>>> {
        let index = PointIndex::new(points);
        let mut answers = vec![None; points.len()];
        index.each_nearest_k_within(points, k, radius, |i, near| {
            assert!(
                answers[i].replace(near.to_vec()).is_none(),
                "point {i} answered twice"
            );
        });
        answers
    }

    proptest::proptest! {
        /// Clumps of bark-like points, some duplicated, with outliers:
        /// every point is answered once, as the brute force answers it.
        #[test]
        fn every_point_gets_its_nearest_neighbours(
            clumps in proptest::collection::vec(
                ((-5.0f32..5.0, -5.0f32..5.0, 0.0f32..10.0), 0.01f32..0.5, 20usize..200),
                1..5,
            ),
            seed in 0u64..1000,
            k in 1usize..14,
            radius in 0.005f32..1.0,
            duplicates in 0usize..40,
        ) {
            use rand::{Rng, SeedableRng};
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let mut points: Vec<Vec3> = Vec::new();
            for ((x, y, z), spread, n) in clumps {
                let centre = Vec3::new(x, y, z);
                for _ in 0..n {
                    let offset = Vec3::new(rng.random(), rng.random(), rng.random()) - 0.5;
                    points.push(centre + offset * spread);
                }
            }
            for _ in 0..duplicates {
                let p = points[rng.random_range(0..points.len())];
                points.push(p);
            }
            let truth = brute_force(&points, k, radius);
            for (i, found) in answers(&points, k, radius).into_iter().enumerate() {
                let found = found.expect("every point is answered");
                proptest::prop_assert!(same_answer(&found, &truth[i]), "point {}: {:?} vs {:?}", i, found, truth[i]);
            }
        }
    }

    #[test]
    fn points_on_the_cell_faces_get_their_nearest_neighbours() {
        // A lattice: every distance is tied many times over, and points lie
        // on the faces of cells whatever their size.
        let points: Vec<Vec3> = (0..8 * 8 * 8)
            .map(|i| Vec3::new((i % 8) as f32, (i / 8 % 8) as f32, (i / 64) as f32) * 0.05)
            .collect();
        for (k, radius) in [(6, 0.06), (10, 0.2), (26, 0.09), (3, 0.01)] {
            let truth = brute_force(&points, k, radius);
            for (i, found) in answers(&points, k, radius).into_iter().enumerate() {
                let found = found.expect("every point is answered");
                assert!(
                    same_answer(&found, &truth[i]),
                    "k {k}, point {i}: {found:?}"
                );
            }
        }
    }

    #[test]
    fn degenerate_clouds_are_answered_point_by_point() {
        let same = vec![Vec3::splat(1.0); 300];
        let answered = answers(&same, 4, 0.1);
        assert!(
            answered
                .iter()
                .all(|a| a.as_ref().is_some_and(|n| n.len() == 4))
        );
        let far = [Vec3::ZERO, Vec3::splat(1e30)].repeat(200);
        let answered = answers(&far, 2, 1.0);
        assert!(
            answered
                .iter()
                .all(|a| a.as_ref().is_some_and(|n| n.len() == 2))
        );
        assert!(answers(&[], 3, 1.0).is_empty());
    }
}
