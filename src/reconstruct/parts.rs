//! Parts of a cloud that lie apart: a clip that holds two trees, or a tree
//! and a piece of its neighbour's crown.
//!
//! The dense pipeline finds them in its neighbour graph (it must connect
//! the graph anyway); the airborne pipeline asks [`detached_part`] before
//! it builds anything, since its trunk (Eq. 3/4) and its graph would
//! otherwise join the parts into one tree.
//!
//! Two trees whose crowns touch are one part. A dense scan still sees them
//! stand on two stems: [`standing_stems`] finds the stems at the foot of
//! the cloud.

use foldhash::{HashMap, HashMapExt};
use glam::{I64Vec3, Vec2, Vec3};

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

/// Height of the band at the foot of a cloud in which [`standing_stems`]
/// looks for stems, in metres: breast height, under the crowns of most
/// trees (an inventory measures each stem's DBH there).
pub(crate) const STEM_BAND_M: f32 = 1.3;

/// Points of the foot band nearer than this (metres) belong to one stem.
const STEM_LINK_M: f32 = 0.25;

/// A stem rises through at least this share of [`STEM_BAND_M`]: a twig
/// hanging into the band, or a stone or stump, does not.
const STEM_RISE_SHARE: f32 = 0.7;

/// A stem leans at most this far from vertical in the band, in degrees
/// (the drift of its upper half's centroid from its lower half's): a limb
/// whose far end rests on the ground slants through the band (one of a
/// synthetic oak's, over a 20° slope, at 50°), a stem stands. Trunks
/// leaning more are flagged by the upright check in any case.
const MAX_STEM_LEAN_DEG: f32 = 30.0;

/// A stem holds at least this many points of the band.
const MIN_STEM_POINTS: usize = 20;

/// A stem holds at least this share of the band points of the largest
/// stem: a sapling or a fallen twig beside a trunk does not count.
const MIN_STEM_SHARE: f32 = 0.1;

/// Stems at least this far apart (metres, centre to centre) are two trees
/// ([`stems_apart`]); nearer ones can be one tree forked at the ground, or
/// a coppice stool.
pub(crate) const MIN_STEMS_APART_M: f32 = 1.0;

/// A stem standing on the ground, as [`standing_stems`] finds it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Stem {
    /// Horizontal centroid of the stem's points in the foot band.
    pub(crate) centre: Vec2,
    /// Points of the stem in the foot band.
    pub(crate) points: usize,
}

/// The stems a dense cloud stands on, largest first: the parts of the
/// points of the foot band (heights from `lowest` up to [`STEM_BAND_M`]
/// above it; `heights[i]` is point `i`'s height, above the terrain where
/// there is one) that lie at least [`STEM_LINK_M`] apart horizontally, and
/// are shaped like a stem:
/// - they rise through [`STEM_RISE_SHARE`] of the band,
/// - they are no wider than a trunk (twice [`MAX_TRUNK_RADIUS_M`]),
/// - they lean at most [`MAX_STEM_LEAN_DEG`] from vertical,
/// - they hold [`MIN_STEM_POINTS`] points, and [`MIN_STEM_SHARE`] of the
///   largest stem's.
///
/// A tree stands on one stem (or on several within a metre or so, when it
/// forks at the ground); two trees whose crowns touch stand on two stems
/// metres apart. The parts are found as in [`detached_part`], with cubes
/// one layer high.
///
/// [`MAX_TRUNK_RADIUS_M`]: super::radii::MAX_TRUNK_RADIUS_M
pub(crate) fn standing_stems(points: &[Vec3], heights: &[f32], lowest: f32) -> Vec<Stem> {
    let band: Vec<(Vec3, f32)> = points
        .iter()
        .zip(heights)
        .filter(|&(_, &h)| (lowest..=lowest + STEM_BAND_M).contains(&h))
        .map(|(p, &h)| (p.truncate().extend(0.0), h - lowest))
        .collect();
    let flat: Vec<Vec3> = band.iter().map(|&(p, _)| p).collect();
    let (cell_of, mut cells) = touching_cubes(&flat, STEM_LINK_M);
    let mut parts: HashMap<u32, FootPart> = HashMap::new();
    for (&(p, h), &cell) in band.iter().zip(&cell_of) {
        parts
            .entry(cells.find(cell))
            .or_insert_with(FootPart::new)
            .add(p.truncate(), h);
    }
    let mut stems: Vec<Stem> = parts.values().filter_map(FootPart::stem).collect();
    stems.sort_unstable_by_key(|s| std::cmp::Reverse(s.points));
    let largest = stems.first().map_or(0, |s| s.points);
    stems.retain(|s| s.points as f32 >= MIN_STEM_SHARE * largest as f32);
    stems
}

/// The [`standing_stems`] that stand at least [`MIN_STEMS_APART_M`] from
/// every larger one, largest first: one stem per tree.
pub(crate) fn stems_apart(points: &[Vec3], heights: &[f32], lowest: f32) -> Vec<Stem> {
    let mut apart: Vec<Stem> = Vec::new();
    for stem in standing_stems(points, heights, lowest) {
        if apart
            .iter()
            .all(|a| a.centre.distance(stem.centre) >= MIN_STEMS_APART_M)
        {
            apart.push(stem);
        }
    }
    apart
}

/// What [`standing_stems`] gathers of one part of the foot band: its
/// points, their horizontal sum and bounding box, and their height range;
/// and the sums of position and height of the points in the lower and the
/// upper half of the band.
#[derive(Debug)]
struct FootPart {
    points: usize,
    sum: Vec2,
    halves: [(usize, Vec3); 2],
    min_xy: Vec2,
    max_xy: Vec2,
    min_h: f32,
    max_h: f32,
}

impl FootPart {
    fn new() -> Self {
        FootPart {
            points: 0,
            sum: Vec2::ZERO,
            halves: [(0, Vec3::ZERO); 2],
            min_xy: Vec2::INFINITY,
            max_xy: Vec2::NEG_INFINITY,
            min_h: f32::INFINITY,
            max_h: f32::NEG_INFINITY,
        }
    }

    fn add(&mut self, xy: Vec2, height: f32) {
        self.points += 1;
        self.sum += xy;
        let half = &mut self.halves[usize::from(height >= 0.5 * STEM_BAND_M)];
        half.0 += 1;
        half.1 += xy.extend(height);
        self.min_xy = self.min_xy.min(xy);
        self.max_xy = self.max_xy.max(xy);
        self.min_h = self.min_h.min(height);
        self.max_h = self.max_h.max(height);
    }

    /// The part as a stem, if it is shaped like one.
    fn stem(&self) -> Option<Stem> {
        let width = (self.max_xy - self.min_xy).max_element();
        let is_stem = self.points >= MIN_STEM_POINTS
            && self.max_h - self.min_h >= STEM_RISE_SHARE * STEM_BAND_M
            && width <= 2.0 * super::radii::MAX_TRUNK_RADIUS_M
            && self.lean_deg() <= MAX_STEM_LEAN_DEG;
        is_stem.then(|| Stem {
            centre: self.sum / self.points as f32,
            points: self.points,
        })
    }

    /// The angle from vertical of the line from the lower half's centroid
    /// to the upper half's, in degrees; 90 when a half is empty.
    fn lean_deg(&self) -> f32 {
        let [(n_low, low), (n_high, high)] = self.halves;
        if n_low == 0 || n_high == 0 {
            return 90.0;
        }
        let rise = high / n_high as f32 - low / n_low as f32;
        rise.truncate().length().atan2(rise.z).to_degrees()
    }
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

    /// Points on the bark of a vertical stem of `radius` standing at
    /// `foot`, `height` m tall, one per 5 cm of girth and of height.
    fn stem(foot: Vec2, radius: f32, height: f32) -> Vec<Vec3> {
        let around = (std::f32::consts::TAU * radius / 0.05).ceil() as usize;
        let up = (height / 0.05) as usize;
        (0..around * up)
            .map(|i| {
                let angle = std::f32::consts::TAU * (i % around) as f32 / around as f32;
                let z = 0.05 * (i / around) as f32;
                (foot + radius * Vec2::from_angle(angle)).extend(z)
            })
            .collect()
    }

    /// `standing_stems` with heights above a level ground at z = 0.
    fn stems_of(points: &[Vec3]) -> Vec<Stem> {
        let heights: Vec<f32> = points.iter().map(|p| p.z).collect();
        standing_stems(points, &heights, 0.0)
    }

    #[test]
    fn two_trunks_are_two_stems_largest_first() {
        let mut pts = stem(Vec2::ZERO, 0.3, 4.0);
        pts.extend(stem(Vec2::new(5.0, 1.0), 0.15, 4.0));
        // Their crowns touch: a bridge of points joins them at 3 m.
        pts.extend((0..100).map(|i| Vec3::new(0.05 * i as f32, 0.01 * i as f32, 3.0)));
        let stems = stems_of(&pts);
        assert_eq!(stems.len(), 2, "{stems:?}");
        assert!(stems[0].points > stems[1].points);
        assert!(stems[0].centre.length() < 0.01, "{stems:?}");
        assert!(
            stems[1].centre.distance(Vec2::new(5.0, 1.0)) < 0.01,
            "{stems:?}"
        );
    }

    #[test]
    fn a_limb_on_the_ground_a_sapling_or_a_stone_is_no_stem() {
        let mut pts = stem(Vec2::ZERO, 0.3, 4.0);
        // A limb from the trunk at 3 m down to the ground 3 m away, at 45°.
        pts.extend((0..300).map(|i| {
            let t = i as f32 / 300.0;
            Vec3::new(0.5 + 2.5 * t, 0.02 * (i % 5) as f32, 3.0 * (1.0 - t))
        }));
        // A sapling with a tenth of the trunk's points in the band.
        pts.extend(stem(Vec2::new(-3.0, 0.0), 0.02, 1.5));
        // A stone: 40 points, 0.3 m high.
        pts.extend((0..40).map(|i| Vec3::new(2.0, -2.0 + 0.01 * i as f32, 0.3 * (i % 2) as f32)));
        let stems = stems_of(&pts);
        assert_eq!(stems.len(), 1, "{stems:?}");
        assert_eq!(stems_of(&[]), vec![]);
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
