//! A plot's ground as a plane in 3D: it shows a tilted cloud that the
//! terrain grid cannot.
//!
//! The terrain fit of [`super::ground`] works on a grid of lowest points
//! (2.5D), so it finds ground that slopes up to about 45°. A plot scan
//! turned by more (a cloud exported with another axis up, or a scanner
//! set-up that was not levelled) keeps its ground disc, but across a grid
//! cell the disc then rises more than the fit's tolerance, and no ground is
//! found: the tree came out skewed without a word (`silva synth --scan tls
//! --ground-radius 4`, oak, birch, poplar and pine, seeds 1 and 5, turned
//! 60° about x or y: 7 of the 16 clouds got no note at all). Turned by 90°,
//! the side checks of `upright` reject the cloud; in between only a 3D
//! view of the ground tells.
//!
//! [`tilted_ground`] looks for the ground as what it is in 3D: a flat,
//! filled surface of many square metres that the rest of the cloud stands
//! on, all on one side of it. A RANSAC plane fit (three points per
//! hypothesis) finds the flat surface that holds the most points; a slice
//! through a crown has points on both sides, a stem is too narrow, and a
//! groundless tree holds no such surface. What stands on the ground touches
//! it with a trunk's foot, not with a crown's face: a wall beside a street
//! tree is met by twigs spread over metres, and is no ground. The plane's
//! normal, pointed to the side the tree stands on, is the cloud's up
//! direction; when it tilts [`TILTED_GROUND_DEG`] or more from +z, the
//! reconstruction notes it.

use glam::{Vec2, Vec3};
use rand::{Rng, SeedableRng};

/// Tilt of a ground plane from horizontal (degrees) from which
/// [`tilted_ground`] reports it: steeper than the terrain grid of
/// [`super::ground`] finds ground, and steeper than the slopes trees are
/// scanned on.
pub(crate) const TILTED_GROUND_DEG: f32 = 45.0;

/// Points of a larger cloud are taken every so many, down to this many: a
/// plane of tens of square metres needs no more.
const MAX_SAMPLE_POINTS: usize = 20_000;

/// Hypotheses are scored on every so many of the sample, down to this many.
const MAX_SCORE_POINTS: usize = 1_000;

/// RANSAC hypotheses. With ground holding a fifth of the points, 1 in 125
/// triples lies wholly on it, so about 8 of them do.
const HYPOTHESES: usize = 1_000;

/// Half thickness of the plane's band of inliers, in metres: scanner noise
/// of a few millimetres to centimetres and the roughness of grass and
/// litter.
const BAND_M: f32 = 0.1;

/// Side of the square cells, in the plane, in which the inliers' cover is
/// counted (metres).
const CELL_M: f32 = 0.5;

/// Fewest points in a cell for it to count as covered.
const CELL_MIN_POINTS: u32 = 2;

/// Least covered area for a surface to be ground (m²): as the terrain
/// grid's 20 open 1 m cells.
const MIN_AREA_M2: f32 = 20.0;

/// Least share of the inliers' bounding rectangle (in the plane's principal
/// axes) that its covered cells fill: ground is a filled patch (a disc
/// fills π/4 of it), a plane through scattered twigs is not.
const MIN_FILL: f32 = 0.4;

/// Least share of the points off the band that lie on the surface's side
/// the tree stands on: a slice through a crown has them on both sides.
const MIN_ONE_SIDE_SHARE: f32 = 0.95;

/// Points count for a side ([`MIN_ONE_SIDE_SHARE`]) only this far (metres)
/// off the plane: an airborne clip's ground returns scatter with a few
/// centimetres of noise, and those past the band are no tree. Synthetic
/// AHN-like clips (`silva synth --scan als`, 5 cm noise) turned 60° had 331
/// such points below their ground against 1,809 above it when every point
/// past the band counted.
const SIDE_MARGIN_M: f32 = 0.3;

/// Height above the surface (metres) up to which the points off its band
/// are the foot of what stands on it…
const FOOT_M: f32 = 1.5;

/// …of which there must be this many…
const MIN_FOOT_POINTS: usize = 5;

/// …half of them within this distance (metres) of their median along the
/// surface: a trunk's foot, flared, is up to a metre or so across; twigs
/// touching a wall spread over the crown's face. A median, because a
/// broad oak's drooping limb may dip to a metre above the ground 7 m out
/// (seed 7 of `silva synth --species oak --ground-radius 4`: its 50 points
/// there made the foot's RMS spread 2.1 m, its median one 0.4 m).
const MAX_FOOT_SPREAD_M: f32 = 1.0;

/// A flat, filled surface that the rest of a cloud stands on, as
/// [`tilted_ground`] finds it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct GroundPlane {
    /// Unit normal, pointing to the side the rest of the cloud lies on.
    pub up: Vec3,
    /// Angle between [`GroundPlane::up`] and +z, in degrees.
    pub tilt_deg: f32,
    /// Covered area of the surface, in square metres.
    pub area_m2: f32,
}

impl GroundPlane {
    /// The note that tells a user the cloud looks tilted, and how to level
    /// it ([`super::ground::levelling_words`]).
    pub(crate) fn note(&self) -> String {
        format!(
            "the cloud looks tilted by {:.0}°: a flat surface covering {:.0} m², with the \
             tree standing on it as on ground, faces {} rather than up (silva assumes the z \
             axis points up; ground that steep is rare); {} to level it, or height, trunk \
             base and lean are measured askew",
            self.tilt_deg,
            self.area_m2,
            self.facing(),
            super::ground::levelling_words(self.up)
        )
    }

    /// The plane's up direction as notes show it: "(0.87, 0.00, 0.50)".
    pub(crate) fn facing(&self) -> String {
        let up = super::ground::as_shown(self.up);
        format!("({:.2}, {:.2}, {:.2})", up.x, up.y, up.z)
    }
}

/// The ground plane of `points` when it tilts [`TILTED_GROUND_DEG`] or more
/// from horizontal (module docs); `None` when there is no ground surface or
/// it lies flatter. A 5 m disc of ground with a trunk on it, turned 60°
/// about x, gives a plane tilted 60° whose `up` is +z turned with it (see
/// the tests).
pub(crate) fn tilted_ground(points: &[Vec3]) -> Option<GroundPlane> {
    let plane = ground_plane(points, true)?;
    (plane.tilt_deg >= TILTED_GROUND_DEG).then_some(plane)
}

/// The flat surface of `points` holding the most of them, when it is
/// large, filled, and the rest stand on one side of it, however it tilts;
/// with `foot`, only when they stand on it with a trunk's foot
/// ([`stands_on_a_foot`]). An airborne clip shows no foot: its scanner
/// hardly hits the lowest metre of a trunk.
pub(crate) fn ground_plane(points: &[Vec3], foot: bool) -> Option<GroundPlane> {
    let sample: Vec<Vec3> = every_nth(points, MAX_SAMPLE_POINTS)
        .filter(|p| p.is_finite())
        .collect();
    if sample.len() < 3 {
        return None;
    }
    let (point, normal) = best_hypothesis(&sample)?;
    let (point, normal) = refit(&sample, point, normal)?;
    let (mut above, mut below) = (0usize, 0usize);
    let mut inliers = Vec::new();
    for &p in &sample {
        let d = (p - point).dot(normal);
        if d.abs() <= BAND_M {
            inliers.push(p);
        } else if d > SIDE_MARGIN_M {
            above += 1;
        } else if d < -SIDE_MARGIN_M {
            below += 1;
        }
    }
    // With nothing off the band (`off` counted as 1), neither side holds
    // a tree.
    let off = (above + below).max(1) as f32;
    let up = if above as f32 >= MIN_ONE_SIDE_SHARE * off {
        normal
    } else if below as f32 >= MIN_ONE_SIDE_SHARE * off {
        -normal
    } else {
        return None;
    };
    if foot && !stands_on_a_foot(&sample, point, up) {
        return None;
    }
    let area_m2 = filled_area(&inliers, up)?;
    let tilt_deg = up.dot(Vec3::Z).clamp(-1.0, 1.0).acos().to_degrees();
    Some(GroundPlane {
        up,
        tilt_deg,
        area_m2,
    })
}

/// True when the points up to [`FOOT_M`] above the surface through `point`
/// (normal `up`), off its band, are a foot: at least [`MIN_FOOT_POINTS`] of
/// them, half within [`MAX_FOOT_SPREAD_M`] of their median position.
fn stands_on_a_foot(sample: &[Vec3], point: Vec3, up: Vec3) -> bool {
    let foot: Vec<Vec3> = sample
        .iter()
        .copied()
        .filter(|p| (BAND_M..=FOOT_M).contains(&(*p - point).dot(up)))
        .map(|p| p - up * (p - point).dot(up))
        .collect();
    if foot.len() < MIN_FOOT_POINTS {
        return false;
    }
    let median_of = |axis: fn(&Vec3) -> f32| {
        let mut v: Vec<f32> = foot.iter().map(axis).collect();
        super::radii::median(&mut v)
    };
    let centre = Vec3::new(median_of(|p| p.x), median_of(|p| p.y), median_of(|p| p.z));
    let mut distances: Vec<f32> = foot.iter().map(|p| p.distance(centre)).collect();
    super::radii::median(&mut distances) <= MAX_FOOT_SPREAD_M
}

/// Every n-th point, so that at most about `max` are taken.
fn every_nth(points: &[Vec3], max: usize) -> impl Iterator<Item = Vec3> + '_ {
    let step = points.len().div_ceil(max).max(1);
    points.iter().copied().step_by(step)
}

/// The plane (a point on it and its unit normal) through three sample
/// points that holds the most of the scoring points within [`BAND_M`].
fn best_hypothesis(sample: &[Vec3]) -> Option<(Vec3, Vec3)> {
    let scoring = Columns::new(every_nth(sample, MAX_SCORE_POINTS));
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0x9e0_d15c);
    let mut best: Option<((Vec3, Vec3), usize)> = None;
    for _ in 0..HYPOTHESES {
        let [a, b, c] = [0, 1, 2].map(|_| sample[rng.random_range(0..sample.len())]);
        let normal = (b - a).cross(c - a);
        // Triples closer than half a metre or nearly in a line say
        // nothing about a surface of square metres.
        if normal.length() < 0.25 {
            continue;
        }
        let normal = normal.normalize();
        let score = scoring.in_band(a, normal);
        if best.is_none_or(|(_, s)| score > s) {
            best = Some(((a, normal), score));
        }
    }
    best.map(|(plane, _)| plane)
}

/// Points as three columns of coordinates: scoring a hypothesis then runs
/// over plain `f32` slices, which the compiler vectorises. The scoring was
/// the largest step of an airborne clip's reconstruction (15 % of `tiny`'s
/// time, 1,000 hypotheses over up to 1,000 points).
struct Columns {
    x: Vec<f32>,
    y: Vec<f32>,
    z: Vec<f32>,
}

impl Columns {
    fn new(points: impl Iterator<Item = Vec3>) -> Self {
        let mut columns = Self {
            x: Vec::new(),
            y: Vec::new(),
            z: Vec::new(),
        };
        for p in points {
            columns.x.push(p.x);
            columns.y.push(p.y);
            columns.z.push(p.z);
        }
        columns
    }

    /// How many points lie within [`BAND_M`] of the plane through `a` with
    /// unit `normal`. The arithmetic is `(p - a).dot(normal)`'s, term by
    /// term in the same order, so the count is the same to the last point.
    fn in_band(&self, a: Vec3, normal: Vec3) -> usize {
        let n = self.x.len();
        let (x, y, z) = (&self.x[..n], &self.y[..n], &self.z[..n]);
        let mut count = 0u32;
        for i in 0..n {
            let d = (x[i] - a.x) * normal.x + (y[i] - a.y) * normal.y + (z[i] - a.z) * normal.z;
            count += u32::from(d.abs() <= BAND_M);
        }
        count as usize
    }
}

/// The least-squares plane (centroid and the direction of least spread,
/// [`super::least_spread_axis`]) of the sample points within [`BAND_M`] of a
/// hypothesis, twice over.
fn refit(sample: &[Vec3], mut point: Vec3, mut normal: Vec3) -> Option<(Vec3, Vec3)> {
    for _ in 0..2 {
        let band: Vec<Vec3> = sample
            .iter()
            .copied()
            .filter(|p| (*p - point).dot(normal).abs() <= BAND_M)
            .collect();
        if band.len() < 3 {
            return None;
        }
        let fitted = super::least_spread_axis(&band)?;
        point = band.iter().copied().sum::<Vec3>() / band.len() as f32;
        normal = if fitted.dot(normal) < 0.0 {
            -fitted
        } else {
            fitted
        };
    }
    Some((point, normal))
}

/// The area (m²) covered by `inliers` in cells of [`CELL_M`] in their plane
/// (normal `up`), when it reaches [`MIN_AREA_M2`] and fills [`MIN_FILL`] of
/// its bounding rectangle along the plane's principal axes.
fn filled_area(inliers: &[Vec3], up: Vec3) -> Option<f32> {
    if inliers.len() < 3 {
        return None;
    }
    let centroid = inliers.iter().copied().sum::<Vec3>() / inliers.len() as f32;
    let flat: Vec<Vec2> = {
        let (u, v) = up.any_orthonormal_pair();
        inliers
            .iter()
            .map(|p| Vec2::new((*p - centroid).dot(u), (*p - centroid).dot(v)))
            .collect()
    };
    let (u, v) = principal_axes(&flat);
    let mut cells = foldhash::HashMap::<(i32, i32), u32>::default();
    let (mut lo, mut hi) = (Vec2::splat(f32::MAX), Vec2::splat(f32::MIN));
    for p in &flat {
        let q = Vec2::new(p.dot(u), p.dot(v));
        let cell = ((q.x / CELL_M).floor() as i32, (q.y / CELL_M).floor() as i32);
        *cells.entry(cell).or_default() += 1;
        (lo, hi) = (lo.min(q), hi.max(q));
    }
    let cell_area = CELL_M * CELL_M;
    let area = cells.values().filter(|&&n| n >= CELL_MIN_POINTS).count() as f32 * cell_area;
    let extent = hi - lo + Vec2::splat(CELL_M);
    (area >= MIN_AREA_M2 && area >= MIN_FILL * extent.x * extent.y).then_some(area)
}

/// The principal axes of centred 2D points: the major one, then the one
/// across it.
fn principal_axes(flat: &[Vec2]) -> (Vec2, Vec2) {
    let (mut xx, mut xy, mut yy) = (0.0f64, 0.0f64, 0.0f64);
    for p in flat {
        let (x, y) = (f64::from(p.x), f64::from(p.y));
        (xx, xy, yy) = (xx + x * x, xy + x * y, yy + y * y);
    }
    let angle = 0.5 * (2.0 * xy).atan2(xx - yy);
    let major = Vec2::new(angle.cos() as f32, angle.sin() as f32);
    (major, major.perp())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A disc of ground (radius 5 m, points every 10 cm) with a trunk of
    /// radius 0.3 m and 8 m standing on it, in the upright frame.
    fn plot() -> Vec<Vec3> {
        let mut points = Vec::new();
        for i in -50..=50 {
            for j in -50..=50 {
                let p = Vec3::new(i as f32 * 0.1, j as f32 * 0.1, 0.0);
                if p.length() <= 5.0 {
                    points.push(p);
                }
            }
        }
        for k in 0..160 {
            for a in 0..24 {
                let t = a as f32 * std::f32::consts::TAU / 24.0;
                points.push(Vec3::new(
                    0.3 * t.cos(),
                    0.3 * t.sin(),
                    0.05 * k as f32 + 0.2,
                ));
            }
        }
        points
    }

    fn turned(points: &[Vec3], axis: Vec3, deg: f32) -> Vec<Vec3> {
        let q = glam::Quat::from_axis_angle(axis.normalize(), deg.to_radians());
        points.iter().map(|&p| q * p).collect()
    }

    #[test]
    fn a_plot_turned_sixty_degrees_shows_its_tilt_and_its_up_direction() {
        let plot = turned(&plot(), Vec3::X, 60.0);
        let plane = tilted_ground(&plot).expect("the ground is found tilted");
        assert!((plane.tilt_deg - 60.0).abs() < 1.0, "{plane:?}");
        let up = glam::Quat::from_axis_angle(Vec3::X, 60f32.to_radians()) * Vec3::Z;
        assert!(plane.up.dot(up) > 0.999, "{plane:?}");
        assert!(plane.area_m2 > 60.0, "{plane:?}");
        assert!(plane.note().contains("tilted by 60°"), "{}", plane.note());
        assert!(
            plane
                .note()
                .contains("by 60° about the axis (-1.00, 0.00, 0.00)"),
            "{}",
            plane.note()
        );
    }

    #[test]
    fn an_upright_or_gently_turned_plot_is_not_reported() {
        assert_eq!(tilted_ground(&plot()), None);
        let plane =
            ground_plane(&turned(&plot(), Vec3::Y, 30.0), true).expect("the ground is found");
        assert!((plane.tilt_deg - 30.0).abs() < 1.0, "{plane:?}");
        assert_eq!(tilted_ground(&turned(&plot(), Vec3::Y, 30.0)), None);
    }

    #[test]
    fn a_tree_without_ground_holds_no_ground_plane() {
        let trunk: Vec<Vec3> = plot().into_iter().filter(|p| p.z > 0.1).collect();
        assert_eq!(ground_plane(&trunk, true), None);
        assert_eq!(ground_plane(&turned(&trunk, Vec3::X, 60.0), true), None);
    }

    /// A wall 10 m wide and 8 m high beside a tree (a trunk under a ball
    /// of crown 2.5 m across whose side comes within 0.5 m of the wall),
    /// as a street tree's clip may hold without its ground.
    #[test]
    fn a_wall_beside_a_tree_is_no_ground() {
        let mut points = Vec::new();
        for i in -50..=50 {
            for k in 0..=80 {
                points.push(Vec3::new(0.0, i as f32 * 0.1, k as f32 * 0.1));
            }
        }
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        for _ in 0..20_000 {
            let d = Vec3::new(
                rng.random_range(-1.0f32..1.0),
                rng.random_range(-1.0f32..1.0),
                rng.random_range(-1.0f32..1.0),
            );
            if (0.2..=1.0).contains(&d.length()) {
                points.push(Vec3::new(3.0, 0.0, 6.0) + 2.5 * d);
            }
        }
        for k in 0..60 {
            for a in 0..24 {
                let t = a as f32 * std::f32::consts::TAU / 24.0;
                points.push(Vec3::new(
                    3.0 + 0.3 * t.cos(),
                    0.3 * t.sin(),
                    0.05 * k as f32,
                ));
            }
        }
        assert_eq!(ground_plane(&points, true), None);
    }

    #[test]
    fn a_slice_with_points_on_both_sides_is_no_ground() {
        // The same disc with as much above it as below: a slice through
        // something, not the ground under it.
        let mut points = plot();
        points.extend(plot().iter().map(|p| Vec3::new(p.x, p.y, -p.z)));
        assert_eq!(ground_plane(&turned(&points, Vec3::X, 60.0), true), None);
    }

    #[test]
    fn degenerate_clouds_hold_no_plane() {
        assert_eq!(ground_plane(&[], true), None);
        assert_eq!(ground_plane(&[Vec3::ZERO; 10], true), None);
        assert_eq!(ground_plane(&[Vec3::NAN; 10], true), None);
        let line: Vec<Vec3> = (0..100).map(|i| Vec3::X * i as f32).collect();
        assert_eq!(ground_plane(&line, true), None);
    }
}
