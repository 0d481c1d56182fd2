//! Clean-up passes run before reconstruction: near-duplicate removal,
//! statistical outlier removal, the removal of returns classified as noise,
//! of stray returns far from the rest and of small isolated groups above or
//! below it, and voxel downsampling.
//!
//! AdTree (Du et al. 2019, §3.1) removes points closer than 0.001 × the
//! bounding-box diagonal before building its Delaunay graph, because
//! coincident points make the triangulation and the minimum spanning tree
//! degenerate. Statistical outlier removal drops isolated returns (birds,
//! dust, multipath) whose mean distance to their k nearest neighbours is far
//! above the cloud's average. [`remove_classified_noise`] drops what the
//! producer labelled noise; [`remove_stray_returns`] the returns with no
//! other within tens of metres, and [`remove_isolated_groups`] a handful
//! alone a few metres above or below the tree (a bird over the crown,
//! multipath under the ground), which would otherwise set the tree's height
//! or base. Voxel downsampling caps density so that dense terrestrial scans
//! cost the same as airborne ones downstream.
//!
//! All passes keep real points (never synthesise averages), so attributes
//! travel with them, and they keep the input order of the survivors. Neighbour
//! queries go through [`PointIndex`], the crate's one kd-tree.

use foldhash::{HashMap, HashMapExt};

use glam::{I64Vec3, Vec3};

use super::PointCloud;
use crate::spatial::PointIndex;

/// AdTree's default for [`remove_near_duplicates`]: 0.001 of the diagonal.
pub const ADTREE_DUPLICATE_FRACTION: f32 = 0.001;

/// Removes points closer than `fraction_of_diagonal` × the bounding-box
/// diagonal to an earlier kept point (AdTree uses 0.001). Of each group of
/// near-duplicates the first in input order survives; exact copies are
/// always duplicates. A negative or non-finite fraction is a no-op.
///
/// ```
/// use glam::{DVec3, Vec3};
/// use silva::cloud::PointCloud;
/// use silva::cloud::clean::remove_near_duplicates;
///
/// let pts = vec![Vec3::ZERO, Vec3::new(0.0, 0.0, 0.0005), Vec3::new(0.0, 0.0, 1.0)];
/// let cloud = PointCloud::from_points(DVec3::ZERO, pts);
/// let clean = remove_near_duplicates(&cloud, 0.001);
/// assert_eq!(clean.points, vec![Vec3::ZERO, Vec3::new(0.0, 0.0, 1.0)]);
/// ```
pub fn remove_near_duplicates(cloud: &PointCloud, fraction_of_diagonal: f32) -> PointCloud {
    let Some((lo, hi)) = cloud.bounds() else {
        return cloud.clone();
    };
    let radius = fraction_of_diagonal * (hi - lo).length();
    // A zero radius (all points equal) still removes exact duplicates.
    if !(radius >= 0.0 && radius.is_finite()) {
        return cloud.clone();
    }
    let index = PointIndex::new(&cloud.points);
    let mut removed = vec![false; cloud.len()];
    for (i, &p) in cloud.points.iter().enumerate() {
        if removed[i] {
            continue;
        }
        // Kept points are `radius` apart, so each point is reported by a
        // bounded number of queries, even in duplicate-heavy clouds.
        for n in index.within(p, radius) {
            if n.index > i {
                removed[n.index] = true;
            }
        }
    }
    cloud.retain_indices(|i| !removed[i])
}

/// Removes points whose mean distance to their `k` nearest neighbours
/// exceeds the mean of that statistic over the cloud by more than
/// `std_ratio` standard deviations (the usual choice is k = 16, ratio 2).
///
/// ```
/// use glam::{DVec3, Vec3};
/// use silva::cloud::PointCloud;
/// use silva::cloud::clean::remove_statistical_outliers;
///
/// let mut pts: Vec<Vec3> = (0..100)
///     .map(|i| Vec3::new((i % 10) as f32 * 0.1, (i / 10) as f32 * 0.1, 0.0))
///     .collect();
/// pts.push(Vec3::new(0.5, 0.5, 30.0)); // a bird
/// let cloud = PointCloud::from_points(DVec3::ZERO, pts);
/// let clean = remove_statistical_outliers(&cloud, 8, 2.0);
/// assert_eq!(clean.len(), 100);
/// assert!(clean.points.iter().all(|p| p.z == 0.0));
/// ```
pub fn remove_statistical_outliers(cloud: &PointCloud, k: usize, std_ratio: f32) -> PointCloud {
    if k == 0 || cloud.len() <= k || !std_ratio.is_finite() {
        return cloud.clone();
    }
    let index = PointIndex::new(&cloud.points);
    let mean_dist: Vec<f64> = cloud
        .points
        .iter()
        .enumerate()
        .map(|(i, &p)| mean_neighbour_distance(&index, i, p, k))
        .collect();
    let n = mean_dist.len() as f64;
    let mean = mean_dist.iter().sum::<f64>() / n;
    let var = mean_dist.iter().map(|d| (d - mean).powi(2)).sum::<f64>() / n;
    let threshold = mean + f64::from(std_ratio) * var.sqrt();
    cloud.retain_indices(|i| mean_dist[i] <= threshold)
}

/// Mean distance from point `i` to its `k` nearest other points.
fn mean_neighbour_distance(index: &PointIndex, i: usize, p: Vec3, k: usize) -> f64 {
    let near = index.nearest_k(p, k + 1);
    // Skip the point itself; with exact duplicates it need not come first,
    // and any one zero-distance entry stands for it equally well.
    let self_pos = near
        .iter()
        .position(|n| n.index == i)
        .unwrap_or(near.len() - 1);
    let sum: f64 = near
        .iter()
        .enumerate()
        .filter(|&(j, _)| j != self_pos)
        .map(|(_, n)| f64::from(n.distance_sq).sqrt())
        .sum();
    sum / k as f64
}

/// The cloud without the points its producer classified as noise
/// ([`super::CLASSES_NOISE`]: LAS classes 7 and 18) and how many those
/// were, or `None` when the cloud has none (or no classification).
///
/// ```
/// use glam::{DVec3, Vec3};
/// use silva::cloud::PointCloud;
/// use silva::cloud::clean::remove_classified_noise;
///
/// let mut cloud = PointCloud::from_points(DVec3::ZERO, vec![Vec3::ZERO, Vec3::Z, Vec3::X]);
/// cloud.classification = Some(vec![1, 7, 2]);
/// let (kept, noise) = remove_classified_noise(&cloud).unwrap();
/// assert_eq!((kept.len(), noise), (2, 1));
/// assert_eq!(kept.classification, Some(vec![1, 2]));
/// ```
pub fn remove_classified_noise(cloud: &PointCloud) -> Option<(PointCloud, usize)> {
    let classes = cloud.classification.as_ref()?;
    let noise = classes
        .iter()
        .filter(|c| super::CLASSES_NOISE.contains(c))
        .count();
    (noise > 0).then(|| {
        let kept = cloud.retain_indices(|i| !super::CLASSES_NOISE.contains(&classes[i]));
        (kept, noise)
    })
}

/// Returns dropped by [`remove_stray_returns`] or [`remove_isolated_groups`],
/// by where they lay.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Strays {
    /// Above the kept points, across a gap in height.
    pub above: usize,
    /// Below the kept points, across a gap in height.
    pub below: usize,
    /// Beside the kept points, across a horizontal gap.
    pub beside: usize,
}

impl Strays {
    /// The returns of two passes together.
    pub fn merged(self, other: Strays) -> Strays {
        Strays {
            above: self.above + other.above,
            below: self.below + other.below,
            beside: self.beside + other.beside,
        }
    }

    /// All dropped returns.
    pub fn total(&self) -> usize {
        self.above + self.below + self.beside
    }
}

/// Drops a handful of returns isolated from the rest of the cloud: birds,
/// atmospheric noise, corrupt records far above, below or beside a tree.
///
/// This is the radius outlier test (a return with no neighbour within
/// `gap_m` is noise; "distant singular points or small clusters were
/// disallowed", multi-temporal-tree-growth §3.1.3; clusters of "only 1–3
/// points" are noise, airborne-lidar-tree-modeling §6.2) in a form that
/// costs one pass per axis on ordinary clouds: a gap wider than `gap_m`
/// between consecutive coordinates along z, x or y splits the cloud into
/// slabs whose points are all more than `gap_m` apart. The most populous
/// slab is the tree; the others go when they hold at most `max_share` of
/// the points (at least one point) in all. Gaps are looked for along z,
/// x, y and again until none is left; an axis along which the points span
/// no more than `gap_m` is skipped without sorting.
///
/// `None` when nothing was dropped, so that callers keep the cloud as it
/// is. The points must be finite.
///
/// ```
/// use glam::{DVec3, Vec3};
/// use silva::cloud::PointCloud;
/// use silva::cloud::clean::remove_stray_returns;
///
/// let mut pts: Vec<Vec3> = (0..200).map(|i| Vec3::new(0.0, 0.01 * i as f32, 0.05 * i as f32)).collect();
/// pts.push(Vec3::new(0.0, 0.0, 300.0)); // a bird
/// let cloud = PointCloud::from_points(DVec3::ZERO, pts);
/// let (clean, strays) = remove_stray_returns(&cloud, 30.0, 0.01).unwrap();
/// assert_eq!((clean.len(), strays.above), (200, 1));
/// ```
pub fn remove_stray_returns(
    cloud: &PointCloud,
    gap_m: f32,
    max_share: f32,
) -> Option<(PointCloud, Strays)> {
    let limit = ((cloud.len() as f32 * max_share) as usize).max(1);
    let mut kept = vec![true; cloud.len()];
    let mut strays = Strays::default();
    let mut changed = true;
    while changed {
        changed = false;
        for axis in [2, 0, 1] {
            let value = |i: usize| cloud.points[i][axis];
            let Some((lo, hi)) = main_slab(cloud.len(), &kept, value, gap_m) else {
                continue;
            };
            let outside: Vec<usize> = (0..cloud.len())
                .filter(|&i| kept[i] && !(lo..=hi).contains(&value(i)))
                .collect();
            let below = outside.iter().filter(|&&i| value(i) < lo).count();
            let above = outside.len() - below;
            if outside.is_empty() || strays.total() + outside.len() > limit {
                continue;
            }
            outside.iter().for_each(|&i| kept[i] = false);
            if axis == 2 {
                strays.below += below;
                strays.above += above;
            } else {
                strays.beside += below + above;
            }
            changed = true;
        }
    }
    (strays.total() > 0).then(|| (cloud.retain_indices(|i| kept[i]), strays))
}

/// The coordinate range of the most populous slab of the kept points
/// between gaps wider than `gap_m` along one axis; `None` without such gaps.
fn main_slab(
    len: usize,
    kept: &[bool],
    value: impl Fn(usize) -> f32,
    gap_m: f32,
) -> Option<(f32, f32)> {
    let values = || (0..len).filter(|&i| kept[i]).map(&value);
    let (min, max) = values().fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), v| {
        (lo.min(v), hi.max(v))
    });
    if max - min <= gap_m {
        return None;
    }
    let mut sorted: Vec<f32> = values().collect();
    sorted.sort_unstable_by(f32::total_cmp);
    let slabs = sorted.chunk_by(|a, b| b - a <= gap_m);
    let main = slabs.max_by_key(|slab| slab.len())?;
    (main.len() < sorted.len()).then(|| (main[0], main[main.len() - 1]))
}

/// The test of [`remove_isolated_groups`].
#[derive(Debug, Clone, PartialEq)]
pub struct IsolatedGroups {
    /// The shortest gap, in metres, that isolates a group.
    pub min_gap_m: f32,
    /// The gap in median point spacings, when that is longer.
    pub gap_spacings: f32,
    /// The most points a group holds.
    pub max_group: usize,
    /// The largest share of the points that may go.
    pub max_share: f32,
}

/// Drops small groups of returns that no other return comes near: a bird
/// or two above a crown, multipath returns under the ground. These lie a
/// few metres to tens of metres off, nearer than [`remove_stray_returns`]'
/// gap, yet one of them sets the tree's height or its lowest point (three
/// returns 20–40 m above a 10.9 m AHN tree made it 52.7 m tall; two returns
/// 5–10 m under a terrestrial scan made it look upside down).
///
/// A *group* is a set of at most [`IsolatedGroups::max_group`] points with
/// no other point within the gap of any of them (single linkage, exactly):
/// [`IsolatedGroups::min_gap_m`], or [`IsolatedGroups::gap_spacings`] times
/// the cloud's median point spacing if that is longer, since the sparser
/// the scan, the farther apart its hits on one tree lie. The
/// groups that lie wholly above or wholly below all the other points go:
/// those set a tree's height and its base. A group within the others'
/// height range stays: in a sparse airborne clip it is a piece of the crown
/// whose links to the rest were not hit (at 2 points/m², 19 of 40
/// synthetic clips hold such pieces more than 3 m from the rest), and a
/// stray beside a tree moves no more than its crown's width. Nothing goes
/// when the groups to drop hold more than [`IsolatedGroups::max_share`] of
/// the points (and more than one group's worth) in all: that many are a
/// second object or a noisy scan, not a few strays; nor when nothing else
/// would stay.
///
/// Cost: one pass over cubes whose diagonal is the gap. A cube holding more
/// than `max_group` points cannot hold a group (its points are all within
/// the gap of each other): when every cube is fuller, that is all. Else a
/// kd-tree over the points gives their spacing, and the points of sparse
/// cubes are grown into groups; each growth stops after `max_group + 1`
/// points.
///
/// `None` when nothing was dropped. The points must be finite.
///
/// ```
/// use glam::{DVec3, Vec3};
/// use silva::cloud::PointCloud;
/// use silva::cloud::clean::{IsolatedGroups, remove_isolated_groups};
///
/// let mut pts: Vec<Vec3> = (0..200).map(|i| Vec3::new(0.0, 0.01 * i as f32, 0.05 * i as f32)).collect();
/// pts.push(Vec3::new(1.0, 0.0, 25.0)); // a bird 15 m above the top
/// pts.push(Vec3::new(0.0, 0.5, -6.0)); // multipath 6 m under the base
/// let cloud = PointCloud::from_points(DVec3::ZERO, pts);
/// let rule = IsolatedGroups { min_gap_m: 3.0, gap_spacings: 20.0, max_group: 8, max_share: 0.01 };
/// let (clean, strays) = remove_isolated_groups(&cloud, &rule).unwrap();
/// assert_eq!((clean.len(), strays.above, strays.below), (200, 1, 1));
/// ```
pub fn remove_isolated_groups(
    cloud: &PointCloud,
    rule: &IsolatedGroups,
) -> Option<(PointCloud, Strays)> {
    remove_isolated_groups_measured(cloud, rule).0
}

/// [`remove_isolated_groups`], and the median spacing of `cloud`'s points
/// ([`PointIndex::median_spacing`]) when the search measured it: a caller
/// that needs the spacing of the same points later need not build a second
/// kd-tree for it (on an airborne clip, the two cost a fifth of the
/// reconstruction).
pub fn remove_isolated_groups_measured(
    cloud: &PointCloud,
    rule: &IsolatedGroups,
) -> (Option<(PointCloud, Strays)>, Option<f32>) {
    let Some(search) = SparseCubes::new(&cloud.points, rule) else {
        return (None, None);
    };
    (dropped_groups(cloud, rule, &search), search.spacing_m)
}

/// The isolated groups that [`remove_isolated_groups`] drops, and the
/// cloud without them; `None` when none go.
fn dropped_groups(
    cloud: &PointCloud,
    rule: &IsolatedGroups,
    search: &SparseCubes,
) -> Option<(PointCloud, Strays)> {
    let groups = search.isolated_groups();
    let mut in_group = vec![false; cloud.len()];
    groups.iter().flatten().for_each(|&i| in_group[i] = true);
    let others = cloud.points.iter().zip(&in_group).filter(|(_, g)| !**g);
    let (low, high) = z_bounds(others.map(|(p, _)| p));
    let mut strays = Strays::default();
    let mut stray = vec![false; cloud.len()];
    for group in &groups {
        let (lo, hi) = z_bounds(group.iter().map(|&i| &cloud.points[i]));
        match () {
            _ if lo > high => strays.above += group.len(),
            _ if hi < low => strays.below += group.len(),
            _ => continue,
        }
        group.iter().for_each(|&i| stray[i] = true);
    }
    let dropped = strays.total();
    let limit = ((cloud.len() as f32 * rule.max_share) as usize).max(rule.max_group);
    if dropped == 0 || dropped > limit || dropped == cloud.len() {
        return None;
    }
    Some((cloud.retain_indices(|i| !stray[i]), strays))
}

/// Lowest and highest z of the points (infinities when there are none).
fn z_bounds<'a>(points: impl Iterator<Item = &'a Vec3>) -> (f32, f32) {
    points.fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), p| {
        (lo.min(p.z), hi.max(p.z))
    })
}

/// The search of [`remove_isolated_groups`]: a kd-tree over the points,
/// the gap, and which points lie in cubes sparse enough to hold a group.
struct SparseCubes<'a> {
    points: &'a [Vec3],
    gap_m: f32,
    max_group: usize,
    /// Whether each point's cube holds at most `max_group` points.
    in_sparse_cube: Vec<bool>,
    index: PointIndex,
    /// The points' median spacing, as the index measured it.
    spacing_m: Option<f32>,
}

impl<'a> SparseCubes<'a> {
    /// `None` when no group can lie above or below the rest. The kd-tree is
    /// built only when the highest or the lowest point sits in a sparse cube.
    fn new(points: &'a [Vec3], rule: &IsolatedGroups) -> Option<Self> {
        // A group wholly above the rest would put the highest point in it,
        // and one below the lowest: when both points sit in full cubes,
        // there is none (a longer gap only fills the cubes more).
        let sparse = sparse_cubes(points, rule.min_gap_m, rule.max_group)?;
        let by_z = |a: &(usize, &Vec3), b: &(usize, &Vec3)| a.1.z.total_cmp(&b.1.z);
        let extreme = |p: Option<(usize, &Vec3)>| p.is_some_and(|(i, _)| sparse[i]);
        let top = points.iter().enumerate().max_by(by_z);
        let bottom = points.iter().enumerate().min_by(by_z);
        if !extreme(top) && !extreme(bottom) {
            return None;
        }
        let index = PointIndex::new(points);
        let spacing_m = index.median_spacing(points);
        let gap_m = rule
            .min_gap_m
            .max(rule.gap_spacings * spacing_m.unwrap_or(0.0));
        Some(Self {
            points,
            gap_m,
            max_group: rule.max_group,
            in_sparse_cube: if gap_m > rule.min_gap_m {
                sparse_cubes(points, gap_m, rule.max_group)?
            } else {
                sparse
            },
            index,
            spacing_m,
        })
    }

    /// Every group, as point indices.
    fn isolated_groups(&self) -> Vec<Vec<usize>> {
        // Points known to belong to a part of more than `max_group` points.
        let mut large = vec![false; self.points.len()];
        let mut grouped = vec![false; self.points.len()];
        let mut groups = Vec::new();
        for seed in 0..self.points.len() {
            if !self.in_sparse_cube[seed] || large[seed] || grouped[seed] {
                continue;
            }
            if let Some(group) = self.grow(seed, &mut large) {
                group.iter().for_each(|&i| grouped[i] = true);
                groups.push(group);
            }
        }
        groups
    }

    /// The part of `seed` (all points linked to it through steps of at most
    /// the gap) when it holds at most `max_group` points; `None` as soon as
    /// it is known to hold more, with the points met marked in `large`.
    fn grow(&self, seed: usize, large: &mut [bool]) -> Option<Vec<usize>> {
        let mut group = vec![seed];
        let mut next = 0;
        while let Some(&member) = group.get(next) {
            next += 1;
            // A denser cube's points are all within the gap of each other.
            let mut more = !self.in_sparse_cube[member] || large[member];
            if !more {
                let at = self.points[member];
                for n in self
                    .index
                    .nearest_k_within(at, self.max_group + 1, self.gap_m)
                {
                    if !group.contains(&n.index) {
                        group.push(n.index);
                    }
                }
                more = group.len() > self.max_group;
            }
            if more {
                group.iter().for_each(|&i| large[i] = true);
                return None;
            }
        }
        Some(group)
    }
}

/// For each point, whether its cube holds at most `max_group` points;
/// `None` when no cube does. The cubes' diagonal is just under `gap_m`, so
/// the points of a fuller cube all lie within `gap_m` of each other and
/// belong to no group.
fn sparse_cubes(points: &[Vec3], gap_m: f32, max_group: usize) -> Option<Vec<bool>> {
    let edge = gap_m / 1.732_1;
    let keys: Vec<I64Vec3> = points
        .iter()
        .map(|p| (*p / edge).floor().as_i64vec3())
        .collect();
    let mut count: HashMap<I64Vec3, usize> = HashMap::new();
    keys.iter().for_each(|k| *count.entry(*k).or_default() += 1);
    if !count.values().any(|&n| n <= max_group) {
        return None;
    }
    Some(keys.iter().map(|k| count[k] <= max_group).collect())
}

/// Keeps one point per cubic voxel of edge `voxel_m`: the point nearest the
/// centroid of the voxel's points, so that attributes stay real. Survivors
/// keep their input order. A non-positive or non-finite size is a no-op.
///
/// ```
/// use glam::{DVec3, Vec3};
/// use silva::cloud::PointCloud;
/// use silva::cloud::clean::voxel_downsample;
///
/// let pts = vec![Vec3::new(0.1, 0.1, 0.1), Vec3::new(0.5, 0.5, 0.5), Vec3::new(0.45, 0.5, 0.5), Vec3::new(1.5, 0.2, 0.2)];
/// let cloud = PointCloud::from_points(DVec3::ZERO, pts);
/// let down = voxel_downsample(&cloud, 1.0);
/// assert_eq!(down.points, vec![Vec3::new(0.45, 0.5, 0.5), Vec3::new(1.5, 0.2, 0.2)]);
/// ```
pub fn voxel_downsample(cloud: &PointCloud, voxel_m: f32) -> PointCloud {
    if !(voxel_m > 0.0 && voxel_m.is_finite()) {
        return cloud.clone();
    }
    let points = &cloud.points;
    let mut keep = match packed_keys(points, voxel_m) {
        Some(keys) => closest_per_voxel(points, keys),
        None => closest_per_voxel(points, points.iter().map(|&p| voxel_of(p, voxel_m))),
    };
    keep.sort_unstable();
    cloud.select(&keep)
}

/// For each voxel (`keys`: one per point), the index of its point nearest
/// the centroid of its points.
///
/// Sorting the points by voxel, then by index, puts each voxel's points in
/// one run, in input order: a third of the cost of hashing them (this step
/// runs on every dense reconstruction).
fn closest_per_voxel<K: Ord>(points: &[Vec3], keys: impl Iterator<Item = K>) -> Vec<usize> {
    let mut order: Vec<(K, u32)> = keys.zip(0u32..).collect();
    order.sort_unstable();
    order
        .chunk_by(|a, b| a.0 == b.0)
        .map(|run| closest_to_centroid(points, run.iter().map(|&(_, i)| i as usize)))
        .collect()
}

/// The number of points [`voxel_downsample`] keeps at `voxel_m`, without
/// choosing them: the number of occupied voxels (all points for a
/// non-positive or non-finite size).
///
/// A caller searching for the voxel size that brings a cloud under a
/// budget counts at each trial size and selects once, at the last.
///
/// ```
/// use glam::{DVec3, Vec3};
/// use silva::cloud::PointCloud;
/// use silva::cloud::clean::{occupied_voxels, voxel_downsample};
///
/// let pts = vec![Vec3::new(0.1, 0.1, 0.1), Vec3::new(0.5, 0.5, 0.5), Vec3::new(0.45, 0.5, 0.5), Vec3::new(1.5, 0.2, 0.2)];
/// assert_eq!(occupied_voxels(&pts, 1.0), 2);
/// let cloud = PointCloud::from_points(DVec3::ZERO, pts.clone());
/// assert_eq!(occupied_voxels(&pts, 0.3), voxel_downsample(&cloud, 0.3).len());
/// ```
pub fn occupied_voxels(points: &[Vec3], voxel_m: f32) -> usize {
    if !(voxel_m > 0.0 && voxel_m.is_finite()) {
        return points.len();
    }
    let Some(keys) = packed_keys(points, voxel_m) else {
        return distinct(points.iter().map(|&p| voxel_of(p, voxel_m)).collect());
    };
    // Sorted, not hashed: a hash set of millions of keys takes fewer
    // instructions but misses the cache on every insert, and was slower
    // (5.6 M points: 6.0 s against 3.8 s for the whole reconstruction).
    distinct(keys.collect())
}

/// The points' voxels as one 63-bit key each, which orders as the (z, y, x)
/// voxel indices do, when the cloud spans fewer than 2^21 voxels per axis
/// (a tree at 2 mm spans about 2^14); `None` otherwise. Sorting or hashing
/// one integer is several times cheaper than the index triple.
fn packed_keys(points: &[Vec3], voxel_m: f32) -> Option<impl Iterator<Item = u64> + '_> {
    // `floor` is monotonic, so the corners' voxels bound every finite
    // point's (a NaN point would fall outside them).
    let (min, max, finite) = points.iter().fold(
        (Vec3::INFINITY, Vec3::NEG_INFINITY, true),
        |(lo, hi, finite), &p| (lo.min(p), hi.max(p), finite && p.is_finite()),
    );
    let (lo, hi) = (voxel_of(min, voxel_m), voxel_of(max, voxel_m));
    let offset = |v: i32, from: i32| (i64::from(v) - i64::from(from)) as u64;
    let fits = [(lo.0, hi.0), (lo.1, hi.1), (lo.2, hi.2)]
        .iter()
        .all(|&(a, b)| offset(b, a) < 1 << 21);
    (finite && fits).then(move || {
        points.iter().map(move |&p| {
            let (z, y, x) = voxel_of(p, voxel_m);
            offset(z, lo.0) << 42 | offset(y, lo.1) << 21 | offset(x, lo.2)
        })
    })
}

/// The number of distinct values in `keys`.
fn distinct<K: Ord>(mut keys: Vec<K>) -> usize {
    keys.sort_unstable();
    keys.chunk_by(|a, b| a == b).count()
}

/// The voxel of edge `voxel_m` holding `p`, as (z, y, x) indices. `as`
/// saturates, so far-away or huge coordinates share edge voxels rather than
/// overflow.
fn voxel_of(p: Vec3, voxel_m: f32) -> (i32, i32, i32) {
    let v = (p / voxel_m).floor();
    (v.z as i32, v.y as i32, v.x as i32)
}

/// The index (the first of equals) of the point nearest the centroid of the
/// points at `indices`, which must not be empty.
fn closest_to_centroid(points: &[Vec3], indices: impl Iterator<Item = usize> + Clone) -> usize {
    let (sum, count) = indices
        .clone()
        .fold((Vec3::ZERO, 0u32), |(s, n), i| (s + points[i], n + 1));
    let centroid = sum / count as f32;
    let mut best = (usize::MAX, f32::INFINITY);
    for i in indices {
        let d = points[i].distance_squared(centroid);
        if d < best.1 || best.0 == usize::MAX {
            best = (i, d);
        }
    }
    best.0
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    fn cloud(points: Vec<Vec3>) -> PointCloud {
        let n = points.len();
        let mut c = PointCloud::from_points(DVec3::new(85_000.0, 446_000.0, 0.0), points);
        c.classification = Some((0..n).map(|i| i as u8).collect());
        c
    }

    #[test]
    fn near_duplicates_use_the_bounding_box_diagonal() {
        // Diagonal 10 m: the radius is 1 cm at AdTree's 0.001.
        let c = cloud(vec![
            Vec3::ZERO,
            Vec3::new(0.009, 0.0, 0.0),
            Vec3::new(0.02, 0.0, 0.0),
            Vec3::new(10.0, 0.0, 0.0),
        ]);
        let out = remove_near_duplicates(&c, ADTREE_DUPLICATE_FRACTION);
        assert_eq!(out.classification, Some(vec![0, 2, 3]));
    }

    #[test]
    fn all_identical_points_collapse_to_one() {
        let mut c = cloud(vec![Vec3::ONE; 1000]);
        // A zero diagonal gives a zero radius, which still catches exact copies.
        assert_eq!(remove_near_duplicates(&c, 0.001).len(), 1);
        c.points.push(Vec3::new(2.0, 1.0, 1.0));
        c.classification.as_mut().unwrap().push(7);
        let out = remove_near_duplicates(&c, 0.001);
        assert_eq!(out.classification, Some(vec![0, 7]));
    }

    #[test]
    fn degenerate_parameters_are_no_ops() {
        let c = cloud(vec![Vec3::ZERO, Vec3::X, Vec3::Y]);
        assert_eq!(voxel_downsample(&c, 0.0), c);
        assert_eq!(voxel_downsample(&c, f32::NAN), c);
        assert_eq!(remove_statistical_outliers(&c, 0, 2.0), c);
        assert_eq!(remove_statistical_outliers(&c, 5, 2.0), c);
        assert_eq!(remove_near_duplicates(&c, -1.0), c);
        let empty = PointCloud::default();
        assert!(remove_near_duplicates(&empty, 0.001).is_empty());
        assert!(voxel_downsample(&empty, 1.0).is_empty());
    }

    #[test]
    fn voxel_downsample_keeps_one_point_per_voxel() {
        let pts: Vec<Vec3> = (0..1000)
            .map(|i| Vec3::new((i % 10) as f32, ((i / 10) % 10) as f32, (i / 100) as f32) * 0.1)
            .collect();
        let out = voxel_downsample(&cloud(pts), 0.5);
        assert_eq!(out.len(), 8);
    }

    #[test]
    fn packed_and_triple_voxel_keys_keep_the_same_points() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let mut coordinate = || rng.random_range(-3.0f32..3.0);
        let pts: Vec<Vec3> = (0..5000)
            .map(|_| Vec3::new(coordinate(), coordinate(), coordinate()))
            .collect();
        for voxel_m in [0.002, 0.05, 0.7] {
            let packed = packed_keys(&pts, voxel_m).expect("a 6 m cloud packs");
            let triples = pts.iter().map(|&p| voxel_of(p, voxel_m));
            let kept = closest_per_voxel(&pts, packed);
            assert_eq!(kept, closest_per_voxel(&pts, triples));
            assert_eq!(occupied_voxels(&pts, voxel_m), kept.len());
        }
    }

    #[test]
    fn clouds_too_wide_to_pack_or_not_finite_are_counted_all_the_same() {
        let wide = vec![
            Vec3::ZERO,
            Vec3::new(5_000.0, 0.0, 0.0),
            Vec3::new(0.0004, 0.0, 0.0),
        ];
        assert!(packed_keys(&wide, 0.001).is_none());
        assert_eq!(occupied_voxels(&wide, 0.001), 2);
        let with_nan = vec![Vec3::ZERO, Vec3::NAN, Vec3::new(4.5, 0.0, 0.0)];
        assert!(packed_keys(&with_nan, 1.0).is_none());
        // NaN saturates to voxel (0, 0, 0), as in `voxel_downsample`.
        assert_eq!(occupied_voxels(&with_nan, 1.0), 2);
        assert_eq!(voxel_downsample(&cloud(with_nan), 1.0).len(), 2);
        assert_eq!(occupied_voxels(&wide, f32::NAN), 3);
    }

    #[test]
    fn outliers_among_duplicates() {
        // Exact duplicates give zero distances; the lone far point still goes.
        let mut pts = vec![Vec3::ZERO; 50];
        pts.extend((0..50).map(|i| Vec3::new(i as f32 * 0.01, 0.0, 0.0)));
        pts.push(Vec3::new(0.0, 0.0, 50.0));
        let out = remove_statistical_outliers(&cloud(pts), 6, 1.0);
        assert_eq!(out.len(), 100);
    }

    /// A column of 1000 points 20 m tall, 2 m wide.
    fn column() -> Vec<Vec3> {
        (0..1000)
            .map(|i| {
                let a = i as f32 * 2.4;
                Vec3::new(a.cos(), a.sin(), 0.02 * i as f32)
            })
            .collect()
    }

    #[test]
    fn stray_returns_far_above_below_and_beside_are_dropped_with_their_attributes() {
        let mut pts = column();
        pts.push(Vec3::new(0.0, 0.0, 99_000.0));
        pts.push(Vec3::new(0.0, 0.0, -500.0));
        pts.push(Vec3::new(300.0, 0.0, 5.0));
        pts.push(Vec3::new(0.0, -99_000.0, 5.0));
        let (out, strays) = remove_stray_returns(&cloud(pts), 30.0, 0.01).unwrap();
        let expected = Strays {
            above: 1,
            below: 1,
            beside: 2,
        };
        assert_eq!(strays, expected);
        assert_eq!(out.points, column());
        let classes = out.classification.unwrap();
        assert_eq!(classes, (0..1000).map(|i| i as u8).collect::<Vec<_>>());
    }

    #[test]
    fn only_a_handful_beyond_a_wide_gap_is_dropped() {
        // 40 m of points every metre: wider than the gap, but no gap.
        let mut pts = column();
        pts.extend((0..40).map(|i| Vec3::new(i as f32, 0.0, 0.0)));
        assert_eq!(remove_stray_returns(&cloud(pts.clone()), 30.0, 0.01), None);
        // A point 29 m above the top is near enough.
        pts.push(Vec3::new(0.0, 0.0, 20.0 + 29.0));
        assert_eq!(remove_stray_returns(&cloud(pts), 30.0, 0.01), None);
        // Two equal trees far apart, and a cluster of 2 % beside one tree.
        let mut two = column();
        two.extend(column().iter().map(|p| *p + Vec3::new(99_000.0, 0.0, 0.0)));
        assert_eq!(remove_stray_returns(&cloud(two), 30.0, 0.01), None);
        let mut cluster = column();
        cluster.extend((0..20).map(|i| Vec3::new(100.0, 0.0, i as f32 * 0.1)));
        assert_eq!(
            remove_stray_returns(&cloud(cluster.clone()), 30.0, 0.01),
            None
        );
        let (out, strays) = remove_stray_returns(&cloud(cluster), 30.0, 0.02).unwrap();
        assert_eq!((out.len(), strays.beside), (1000, 20));
    }

    /// A gap of 3 m whatever the spacing, groups of at most `max_group`.
    fn rule(max_group: usize, max_share: f32) -> IsolatedGroups {
        IsolatedGroups {
            min_gap_m: 3.0,
            gap_spacings: 0.0,
            max_group,
            max_share,
        }
    }

    #[test]
    fn groups_a_few_metres_above_and_below_go_and_one_beside_stays() {
        let mut pts = column();
        pts.extend([Vec3::new(0.0, 0.0, 35.0), Vec3::new(1.0, 0.0, 36.0)]); // 15 m above
        pts.push(Vec3::new(0.5, 0.0, -6.0)); // 6 m under the base
        // 8 m beside, within the column's height: a piece of a sparse crown.
        let beside = Vec3::new(9.0, 0.0, 10.0);
        pts.push(beside);
        let (out, strays) = remove_isolated_groups(&cloud(pts), &rule(8, 0.01)).unwrap();
        let expected = Strays {
            above: 2,
            below: 1,
            beside: 0,
        };
        assert_eq!(strays, expected);
        assert_eq!(out.points[..1000], column()[..]);
        assert_eq!(out.points[1000..], [beside]);
        let classes = out.classification.unwrap();
        let expected: Vec<u8> = (0..1000).chain([1003]).map(|i| i as u8).collect();
        assert_eq!(classes, expected);
    }

    /// The spacing handed on is the one a kd-tree over the same points
    /// measures, and it is handed on only when the search built one.
    #[test]
    fn the_search_hands_on_the_spacing_it_measured() {
        let mut pts = column();
        pts.push(Vec3::new(0.0, 0.0, 35.0));
        let (dropped, spacing) =
            remove_isolated_groups_measured(&cloud(pts.clone()), &rule(8, 0.01));
        assert_eq!(dropped.map(|(_, s)| s.above), Some(1));
        let expected = PointIndex::new(&pts).median_spacing(&pts);
        assert!(expected.is_some_and(|s| s > 0.0));
        assert_eq!(spacing, expected);
        // Both ends in full cubes: no kd-tree, no spacing.
        assert_eq!(
            remove_isolated_groups_measured(&cloud(column()), &rule(8, 0.01)),
            (None, None)
        );
    }

    #[test]
    fn a_group_near_the_tree_or_bigger_than_a_handful_is_kept() {
        let dropped = |pts: Vec<Vec3>, max_group| {
            remove_isolated_groups(&cloud(pts), &rule(max_group, 0.01)).map(|(_, s)| s.total())
        };
        // 2.9 m above the top point: within the gap; 3.1 m above: not.
        let top = column()[999];
        for (above, expected) in [(2.9, None), (3.1, Some(1))] {
            let mut pts = column();
            pts.push(top + Vec3::Z * above);
            assert_eq!(dropped(pts, 8), expected, "{above} m above");
        }
        // Nine returns together 10 m above: a piece of something.
        let mut nine = column();
        nine.extend((0..9).map(|i| Vec3::new(0.1 * i as f32, 0.0, 30.0)));
        assert_eq!(dropped(nine.clone(), 8), None);
        assert_eq!(dropped(nine, 9), Some(9));
        // A sparse crown: returns 2.5 m apart in a row, none left alone.
        let mut sparse = column();
        sparse.extend((1..20).map(|i| Vec3::new(1.0 + 2.5 * i as f32, 0.0, 15.0)));
        assert_eq!(dropped(sparse, 8), None);
    }

    #[test]
    fn more_strays_than_the_share_allows_are_all_kept() {
        let dropped = |pts: Vec<Vec3>, share| {
            let out = remove_isolated_groups(&cloud(pts), &rule(1, share));
            out.map(|(c, s)| (c.len(), s.above))
        };
        // Twelve lone returns 10 m apart above the column: 1.2 % of the points.
        let mut many = column();
        many.extend((0..12).map(|i| Vec3::new(10.0 * i as f32, 0.0, 40.0)));
        assert_eq!(dropped(many.clone(), 0.01), None);
        assert_eq!(dropped(many, 0.02), Some((1000, 12)));
        assert_eq!(dropped(Vec::new(), 0.01), None);
        // Nothing goes when nothing would stay.
        let lone = vec![Vec3::ZERO, Vec3::new(10.0, 0.0, 10.0)];
        assert_eq!(dropped(lone, 1.0), None);
    }

    /// Twenty spacings of a sparse cloud make the gap longer than 3 m: hits
    /// 0.3 m apart, a top return 4 m above them stays, one 7 m above goes.
    #[test]
    fn the_gap_grows_with_the_point_spacing() {
        let sparse: Vec<Vec3> = (0..2000)
            .map(|i| Vec3::new(0.3 * (i % 40) as f32, 0.3 * (i / 40) as f32, 0.0))
            .collect();
        for (above, expected) in [(4.0, None), (7.0, Some(1))] {
            let mut pts = sparse.clone();
            pts.push(Vec3::new(6.0, 6.0, above));
            let spacings = IsolatedGroups {
                gap_spacings: 20.0,
                ..rule(8, 0.01)
            };
            let out = remove_isolated_groups(&cloud(pts), &spacings);
            assert_eq!(out.map(|(_, s)| s.above), expected, "{above} m above");
        }
    }
}
