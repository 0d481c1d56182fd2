//! Parts of a cloud that lie apart: a clip that holds two trees, or a tree
//! and a piece of its neighbour's crown.
//!
//! The dense pipeline finds them in its neighbour graph (it must connect
//! the graph anyway); the airborne pipeline asks [`detached_part`] before
//! it builds anything, since its trunk (Eq. 3/4) and its graph would
//! otherwise join the parts into one tree.

use foldhash::{HashMap, HashMapExt};
use glam::{I64Vec3, Vec3};

use super::dense::UnionFind;
use super::z_range;
use crate::spatial::PointIndex;

/// A part of a cloud that lies apart from the rest of it.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Detached {
    /// Points in the part.
    pub(crate) points: usize,
    /// Lowest and highest z of the part.
    pub(crate) part_z: (f32, f32),
    /// Lowest and highest z of the rest.
    pub(crate) rest_z: (f32, f32),
    /// Whether each point of the cloud lies in the part.
    members: Vec<bool>,
}

impl Detached {
    /// True when the part's heights overlap the rest's: it stands beside
    /// the rest (a second tree), not wholly above it (a crown over ground
    /// that was not found, a sparse crown's top) or below it.
    pub(crate) fn beside(&self) -> bool {
        self.part_z.0 < self.rest_z.1 && self.part_z.1 > self.rest_z.0
    }

    /// Distance from the part to the nearest point outside it, in metres,
    /// `points` being the cloud the part was found in: exact, through a
    /// kd-tree over the rest (so a caller measures it only when the part's
    /// size and heights make it matter).
    pub(crate) fn gap_m(&self, points: &[Vec3]) -> f32 {
        let (inside, outside) = self.split(points);
        let index = PointIndex::new(&outside);
        inside
            .iter()
            .filter_map(|&p| index.nearest(p))
            .map(|n| n.distance_sq)
            .fold(f32::INFINITY, f32::min)
            .sqrt()
    }

    /// The points of the part, and the rest.
    fn split(&self, points: &[Vec3]) -> (Vec<Vec3>, Vec<Vec3>) {
        let (inside, outside): (Vec<_>, Vec<_>) =
            points.iter().zip(&self.members).partition(|(_, m)| **m);
        let plain = |v: Vec<(&Vec3, &bool)>| v.into_iter().map(|(p, _)| *p).collect();
        (plain(inside), plain(outside))
    }
}

/// The largest part of `points` but one, when the points fall apart into
/// parts that lie at least `gap_m` from each other; `None` when they do
/// not (or `gap_m` is not a positive length).
///
/// Points are put into cubes of edge `gap_m`, and cubes that touch (by a
/// face, an edge or a corner) join: two points nearer than `gap_m` lie in
/// the same or touching cubes, so a part found this way is at least `gap_m`
/// from every other ([`Detached::gap_m`] measures how far). Parts nearer
/// than about 3.5 × `gap_m` (the diagonal of two cubes) may count as one.
/// One pass over the occupied cubes: no pair of points is compared.
pub(crate) fn detached_part(points: &[Vec3], gap_m: f32) -> Option<Detached> {
    if !(gap_m > 0.0 && gap_m.is_finite()) {
        return None;
    }
    let (cell_of, mut cubes) = touching_cubes(points, gap_m);
    let part_of: Vec<u32> = cell_of.iter().map(|&c| cubes.find(c)).collect();
    let mut sizes: HashMap<u32, usize> = HashMap::new();
    part_of
        .iter()
        .for_each(|&p| *sizes.entry(p).or_default() += 1);
    let mut by_size: Vec<(usize, u32)> = sizes.into_iter().map(|(p, n)| (n, p)).collect();
    by_size.sort_unstable_by(|a, b| b.cmp(a));
    let &(points_in_part, part) = by_size.get(1)?;
    let members: Vec<bool> = part_of.iter().map(|&p| p == part).collect();
    let side = |inside: bool| {
        points
            .iter()
            .zip(&members)
            .filter(move |(_, m)| **m == inside)
    };
    Some(Detached {
        points: points_in_part,
        part_z: z_range(side(true).map(|(p, _)| p)),
        rest_z: z_range(side(false).map(|(p, _)| p)),
        members,
    })
}

/// Each point's cube (of edge `edge_m`) as a dense index, and the cubes
/// joined where they touch.
fn touching_cubes(points: &[Vec3], edge_m: f32) -> (Vec<u32>, UnionFind) {
    let mut cubes: HashMap<I64Vec3, u32> = HashMap::new();
    let cell_of: Vec<u32> = points
        .iter()
        .map(|p| {
            let next = cubes.len() as u32;
            *cubes
                .entry((*p / edge_m).floor().as_i64vec3())
                .or_insert(next)
        })
        .collect();
    let mut sets = UnionFind::new(cubes.len());
    for (&at, &i) in &cubes {
        for step in TOUCHING {
            if let Some(&j) = cubes.get(&(at + step)) {
                sets.union(i, j);
            }
        }
    }
    (cell_of, sets)
}

/// Half of the 26 cubes that touch a cube: the other half sees this one.
const TOUCHING: [I64Vec3; 13] = [
    I64Vec3::new(1, -1, -1),
    I64Vec3::new(1, -1, 0),
    I64Vec3::new(1, -1, 1),
    I64Vec3::new(1, 0, -1),
    I64Vec3::new(1, 0, 0),
    I64Vec3::new(1, 0, 1),
    I64Vec3::new(1, 1, -1),
    I64Vec3::new(1, 1, 0),
    I64Vec3::new(1, 1, 1),
    I64Vec3::new(0, 1, -1),
    I64Vec3::new(0, 1, 0),
    I64Vec3::new(0, 1, 1),
    I64Vec3::new(0, 0, 1),
];

#[cfg(test)]
mod tests {
    use super::*;

    /// A ball of `n` points of radius about 1 m around `centre`.
    fn ball(centre: Vec3, n: usize) -> Vec<Vec3> {
        (0..n)
            .map(|i| {
                let t = i as f32;
                let dir = Vec3::new((t * 0.7).sin(), (t * 1.3).cos(), (t * 0.37).sin());
                centre + dir.normalize_or(Vec3::Z) * ((t * 0.11).sin().abs())
            })
            .collect()
    }

    #[test]
    fn two_crowns_far_apart_are_two_parts_with_their_gap() {
        let mut pts = ball(Vec3::ZERO, 600);
        pts.extend(ball(Vec3::new(20.0, 0.0, 0.0), 300));
        let part = detached_part(&pts, 3.0).expect("two parts");
        assert_eq!(part.points, 300);
        assert!(part.beside(), "{part:?}");
        let gap_m = part.gap_m(&pts);
        let inner = |c: Vec3, q: &[Vec3]| q.iter().map(|p| p.distance(c)).fold(0.0, f32::max);
        let reach = inner(Vec3::ZERO, &pts[..600]) + inner(Vec3::new(20.0, 0.0, 0.0), &pts[600..]);
        assert!(gap_m >= 20.0 - reach && gap_m <= 20.0, "{gap_m}");
    }

    #[test]
    fn a_crown_over_its_ground_is_not_beside_it() {
        let mut pts: Vec<Vec3> = (0..400)
            .map(|i| Vec3::new((i % 20) as f32, (i / 20) as f32, 0.0))
            .collect();
        pts.extend(ball(Vec3::new(10.0, 10.0, 12.0), 100));
        let part = detached_part(&pts, 3.0).expect("the crown lies apart");
        assert_eq!(part.points, 100);
        assert!(!part.beside(), "{part:?}");
    }

    #[test]
    fn one_crown_or_parts_nearer_than_the_gap_are_one() {
        assert_eq!(detached_part(&ball(Vec3::ZERO, 500), 3.0), None);
        let mut pts = ball(Vec3::ZERO, 500);
        pts.extend(ball(Vec3::new(3.5, 0.0, 0.0), 500));
        assert_eq!(detached_part(&pts, 3.0), None);
        assert_eq!(detached_part(&pts, 0.0), None);
        assert_eq!(detached_part(&pts, f32::NAN), None);
    }

    #[test]
    fn a_part_found_is_at_least_the_gap_from_the_rest() {
        // A line of points with one wide step: the parts split there only,
        // and only for a gap shorter than the step.
        let mut pts: Vec<Vec3> = (0..50)
            .map(|i| Vec3::new(0.5 * i as f32, 0.0, 0.0))
            .collect();
        pts.extend((0..20).map(|i| Vec3::new(24.5 + 8.5 + 0.5 * i as f32, 0.3, 0.0)));
        let part = detached_part(&pts, 4.0).expect("split at the wide step");
        assert_eq!(part.points, 20);
        assert!((part.gap_m(&pts) - 8.5053).abs() < 1e-3, "{part:?}");
        assert_eq!(
            detached_part(&pts, 9.0),
            None,
            "an 8.5 m step is not 9 m apart"
        );
    }
}
