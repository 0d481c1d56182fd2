//! Whether a cloud stands on its trunk or on its crown's top.
//!
//! The test on spreads ([`super::check_upright`]) compares how far
//! the lowest and the highest tenth of the cloud spread sideways, which
//! catches a broad crown turned over but not a conical, columnar or
//! slender one: upside down, the narrow top of a pine or a poplar looks
//! like a trunk. A terrestrial scan shows bark, so the stems themselves
//! tell: a slice through the trunk is a ring of points around one thick
//! axis, a slice just under the crown's top a scatter of twig rings a few
//! centimetres across. So the thickest stem in a slice near each end is
//! measured by a circle fit (the one of the DBH, [`robust_circle`]), and a
//! cloud whose thick stem is at the top is rejected.
//!
//! An airborne clip shows no bark, and one cut without its ground shows no
//! terrain either (the ground test of the airborne pipeline then has nothing
//! to go on). But the scanner looks down: the crown's top is hit all round
//! and more than any other part, the trunk and the crown's underside hardly
//! at all. [`seen_from_below`] flags a clip whose lowest tenth is the one
//! hit all round and most.
//!
//! A clip or a plot scan that holds its ground shows it, turned over, as a
//! flat surface on top: [`check_ground_below`] rejects it, in both
//! pipelines, before their ground leaves. A terrestrial scan too sparse to
//! ring its trunk still shows the trunk best: turned over, its highest
//! tenth gathers like a stem over a lowest tenth spread like a crown's top
//! ([`trunk_on_top`]).
//!
//! A cloud lying on its side (exported with `y` up, as many mesh and game
//! tools do, or turned by 90°) is rejected the same ways, with each
//! horizontal axis tried as up: its ground stands as a wall
//! ([`check_ground_beside`]), or a slice near one of its side ends rings
//! the trunk while none near its bottom does ([`check_trunk_not_beside`]).
//! The error names the axis that looks up. An airborne clip without its
//! ground shows neither, but its crown's top, hit all round and most, now
//! lies at one side: [`seen_from_beside`] notes the side end that looks
//! like the top.
//!
//! Such a clip tilted by 20–60° cannot be told from an upright one, so
//! the airborne pipeline states the assumption in a note on every clip
//! without ground that no test flagged ("upright not checked: … takes +z
//! as up"). One test was measured and not adopted (2026-12-07, a Python prototype): the scanner's
//! side as the direction from the Steiner point of the clip's hull (three
//! times the mean over 400 directions u of max p·u times u, which turns
//! with the cloud) to the points' centroid. On 200 synthetic AHN-like clips
//! without ground (`silva synth --scan als`, each species, seeds 1–25,
//! leaf-off and leaf-on, points below the 1st percentile of z + 0.5 m cut
//! off) it lay a median 9° from +z upright, but 24° at the 90th percentile
//! and 42° at the 99th: crowns are lopsided. Flagging beyond 40° would have
//! flagged 3 of the 200 upright, 43 / 114 / 625 / 780 of 800 turned by
//! 20° / 30° / 45° / 60° (about x and y, both ways), and ahn3_delft cut the
//! same way read 32° upright. The direction in which the hull's points are
//! densest per area seen from it did worse (a median 30° or more upright,
//! on a third of the clips).

use foldhash::{HashMap, HashMapExt};

use glam::{Vec2, Vec3};

use crate::reconstruct::ReconstructError;
use crate::reconstruct::dense::UnionFind;
use crate::reconstruct::ground::{
    BELOW_GROUND_NOISE_M, GROUND_TOLERANCE_M, GroundMethod, GroundSplit, Terrain, fit_terrain,
    levelling_words, terrain_cell_share,
};
use crate::reconstruct::ground_plane::GroundPlane;
use crate::reconstruct::radii::{
    MAX_TRUNK_RADIUS_M, circle_rms, median, robust_circle, sectors_seen,
};

/// Where the two slices of [`check_stands_on_its_trunk`] lie in a dense
/// scan, as shares of the cloud's height from its lowest (and from its
/// highest) point: clear of the ground and the root flare at the bottom and
/// of the very tip at the top, low enough on a 20 m tree (0.4–1.2 m) to
/// cut the trunk below any crown. Reaching deeper, the top slice of a
/// dense crown rings clusters of twigs: at (0.02, 0.14) tree1 upright (a
/// 46 cm "stem" 0.1–0.8 m below its top) and one clean synthetic poplar
/// were rejected as upside down.
pub(crate) const DENSE_SLICES: (f32, f32) = (0.02, 0.06);

/// The slices in a sparse cloud (the airborne pipeline's: an airborne clip,
/// or a terrestrial scan too sparse for the dense pipeline), taller: a
/// sparse scan's trunk slice must be tall enough to hold a ring's
/// [`MIN_RING_POINTS`]. At 40 points/m² a birch's trunk (radius about
/// 12 cm, seen on one side) gives about 15 points per metre of height, so
/// it needs about 2 m; 0.02–0.10 of a 20 m tree is 1.6 m. On synthetic
/// terrestrial scans turned upside down (`silva synth --scan tls --density
/// D`, the four species, (x, y, z) → (x, −y, −z)) `silva reconstruct`
/// rejected, with [`DENSE_SLICES`] and with these: at 40 points/m² (seeds
/// 1–20) 43 and 72 of 80, at 20 points/m² (seeds 1–10) 1 and 21 of 40, at
/// 80 points/m² 38 and 40 of 40; the same scans upright, none either way
/// (one note on a lean at 80 points/m², as before). The reports of
/// `silva eval` on synthetic ALS (100 clips; 40 each leaf-on and at 8 and
/// 50 points/m²), on synthetic TLS (sparse, clean, with ground, leaf-on)
/// and on `/work/shared/data` were identical at (0.02, 0.10). The misses
/// are birches: their trunk slice is still too sparse to ring.
pub(crate) const SPARSE_SLICES: (f32, f32) = (0.02, 0.10);

/// A piece whose points lean more than this from vertical (degrees) is
/// measured as it stands, without [`upright_section`]: the lean fitted to a
/// branch that crosses the slice sideways means nothing.
const MAX_AXIS_LEAN_DEG: f32 = 70.0;

/// Trees shorter than this are not tested: their slices are too thin to
/// hold a ring.
const MIN_HEIGHT_M: f32 = 2.0;

/// A ring needs this many points on its circle, as the DBH fit does.
const MIN_RING_POINTS: usize = 30;

/// ... and they must cover at least this much of its circumference, in
/// degrees, counted in [`ARC_BIN_DEG`] bins that hold a point: one side of a trunk, which a
/// single scanner sees, but not the twigs of a whorl that cross a circle
/// around the leader at a few places (on a clean synthetic pine, eight
/// twigs over four of twelve sectors fitted a 1.2 m "stem").
const MIN_ARC_DEG: u32 = 120;

/// Width of the bins in which [`MIN_ARC_DEG`] is counted, in degrees.
const ARC_BIN_DEG: u32 = 5;

/// A stem near the top must be at least this thick (radius, metres) to
/// count as a trunk: thicker than any twig at a crown's top.
const MIN_TRUNK_RADIUS_M: f32 = 0.05;

/// ... and this many times thicker than any stem near the bottom.
const THICKER_BY: f32 = 2.0;

/// Rejects a cloud whose thickest stem is near its top (module docs).
/// Points closer than `link_m` belong to one piece of bark: a few times the
/// point spacing of a terrestrial scan. An airborne scan's points lie
/// farther apart than any stem is thick, so no piece of it rings a stem
/// and it passes.
/// The two slices lie at `slices` ([`DENSE_SLICES`] or [`SPARSE_SLICES`])
/// of the height from either end.
pub(crate) fn check_stands_on_its_trunk(
    points: &[Vec3],
    link_m: f32,
    slices: (f32, f32),
) -> Result<(), ReconstructError> {
    let (low, high) = super::z_range(points);
    let height = high - low;
    if height.is_nan() || height < MIN_HEIGHT_M {
        return Ok(());
    }
    let (near, far) = (slices.0 * height, slices.1 * height);
    let bottom = thickest_stem(&slice(points, low + near, low + far), link_m);
    let top = thickest_stem(&slice(points, high - far, high - near), link_m);
    if top >= MIN_TRUNK_RADIUS_M && top > THICKER_BY * bottom {
        return Err(ReconstructError::Degenerate(format!(
            "the cloud looks upside down: a stem {:.0} cm thick stands {:.1}–{:.1} m below its \
             top, and no stem near its bottom is half as thick ({:.0} cm at most)",
            200.0 * top,
            near,
            far,
            200.0 * bottom
        )));
    }
    if bottom == 0.0 {
        check_trunk_not_beside(points, link_m, slices)?;
    }
    Ok(())
}

/// Rejects a cloud whose trunk stands at one of its sides: a terrestrial
/// scan exported with `y` up, or turned by 90°, lies with its trunk
/// horizontal, so no slice near its bottom rings a stem, while a slice
/// across the trunk near its base, the cloud's end along the axis that
/// would be up ([`SIDEWAYS`]), does. Called only when the bottom holds no
/// ring; an upright tree's side ends hold only twigs.
fn check_trunk_not_beside(
    points: &[Vec3],
    link_m: f32,
    slices: (f32, f32),
) -> Result<(), ReconstructError> {
    let (side, radius) = most_on_a_side(points, 1, |turned| {
        let (low, high) = super::z_range(turned);
        let (near, far) = (slices.0 * (high - low), slices.1 * (high - low));
        thickest_stem(&slice(turned, low + near, low + far), link_m)
    });
    if radius >= MIN_TRUNK_RADIUS_M {
        return Err(ReconstructError::Degenerate(format!(
            "the cloud looks tilted onto its side: a stem {:.0} cm thick stands across its {} \
             end, as a trunk would if {} pointed up, and none rings its bottom (turn the cloud \
             so that {} becomes +z; a y-up export needs (x, y, z) → (x, −z, y))",
            200.0 * radius,
            side.base,
            side.up,
            side.up
        )));
    }
    Ok(())
}

/// [`seen_from_below`] compares the lowest and the highest tenth of the
/// clip's height.
const END_SHARE: f32 = 0.1;

/// Directions around an end's centroid are counted in sectors this wide
/// (degrees): a sector holds a point or not.
const SECTOR_DEG: u32 = 10;

/// A clip is flagged when its lowest tenth covers at least this share of
/// the sectors more than its highest tenth does…
const MORE_ROUND_BY: f32 = 0.1;

/// …and holds at least this many times as many points (or, when it covers
/// [`MUCH_ROUNDER_BY`] more, at least as many)…
const MORE_POINTS_BY: f32 = 2.0;

/// A lowest tenth this much rounder than the highest needs only as many
/// points to be flagged. A conifer's crown reaches down, so its lowest
/// tenth (above the cut ground) holds nearly as many returns as its top,
/// but spreads from the stem to one side rather than all round. On 192
/// synthetic AHN-like clips without their ground (`silva synth --scan als`,
/// each species seeds 1–24, leaf-off and leaf-on, points below the 1st
/// percentile of z + 0.5 m cut off), upright, the lowest tenth covered at
/// most 0.22 more of the sectors than the highest; turned over, 157 clips
/// are flagged instead of 133 (every pine whose lowest tenth is 0.3 or
/// more rounder), and no more upright ones (oak 21 leaf-off, whose trunk
/// has no returns, is flagged either way).
const MUCH_ROUNDER_BY: f32 = 0.3;

/// …and spreads at least this far sideways ([`median_spread`], metres):
/// wider than a trunk, which a terrestrial scan too sparse for the dense
/// pipeline also shows all round and most. On 20 such scans (`silva synth
/// --scan tls --density 40`, seeds 1–20) the lowest tenth spread 0.15–0.37
/// m; the highest tenth of the 48 airborne clips below 0.34–0.37 m on three
/// leaf-off poplars and 0.51 m or more on the others. (The RMS spread of an
/// oak's lowest tenth reached 1.32 m: a few twigs of its lowest limbs.)
const MIN_CROWN_TOP_SPREAD_M: f32 = 0.45;

/// A note when an airborne clip without ground looks scanned from below:
/// its lowest tenth is hit all round, more often than its highest, and
/// spreads like a crown's top (see the module docs; silva assumes the z
/// axis points up). On 48 synthetic AHN-like clips (`silva synth --scan
/// als`, seeds 1–24, leaf-off and leaf-on, the ground cut off at 0.5 m
/// above the 1st percentile of z) `silva reconstruct` flagged none upright
/// and 31 turned over (the misses are mostly pines, whose crowns reach
/// down, and narrow poplars); ahn3_delft and tiny are flagged turned by
/// 90°, 135° and 180°, not at 0°, 20°, 30°, 45° or 60°. Since
/// [`MUCH_ROUNDER_BY`], of the 192 clips there 157 are flagged turned over
/// (133 before), and 20 sparse terrestrial scans (`--scan tls --density
/// 40`, seeds 1–20) none upright, as before.
pub(crate) fn seen_from_below(points: &[Vec3]) -> Option<String> {
    let bottom = lowest_tenth(points)?;
    let top = highest_tenth(points)?;
    bottom.looks_like_the_top(&top, MUCH_ROUNDER_BY).then(|| {
        format!(
            "the cloud may be upside down: its lowest tenth holds {} points seen from {:.0} % \
             of the directions around it, its highest tenth {} points from {:.0} %, while an \
             airborne scan hits a crown's top most and all round (silva assumes the z axis \
             points up)",
            bottom.points,
            100.0 * bottom.round,
            top.points,
            100.0 * top.round
        )
    })
}

/// A lowest tenth at least this many times as wide ([`median_spread`]) as
/// the highest is a crown's top under a trunk in [`trunk_on_top`].
const CROWN_WIDER_BY: f32 = 2.0;

/// A note when a sparse cloud without its ground looks turned over with its
/// trunk on top: the highest tenth gathers as closely as a stem (a median
/// spread under [`MIN_CROWN_TOP_SPREAD_M`]), with at least as many points
/// as the lowest tenth, from at least as many directions, and the lowest
/// tenth spreads [`CROWN_WIDER_BY`] times as far. A terrestrial scan too
/// sparse for the dense pipeline shows no ring of bark to
/// [`check_stands_on_its_trunk`], and it sees a crown's top too poorly for
/// [`seen_from_below`]; but its trunk is the part it sees best. With
/// `silva reconstruct` on such scans turned over (`silva synth --scan tls
/// --density 20` and `40`, each species), those that no test flagged went
/// from 11 to 1 of 24 at 20 points/m² and from 2 to 0 at 40 on seeds
/// 1–6, where a Python prototype chose the rule (the one left, a pine,
/// spreads its lowest tenth only 1.3 times as far as its highest), and
/// from 19 to 4 of 32 and from 4 to 0 on seeds 7–14, held out.
/// Upright, none of the 112 is flagged, nor any of 200 synthetic AHN-like
/// clips without their ground (`--scan als`, seeds 1–25, leaf-off and
/// leaf-on; the closest, leaf-off poplars, have a narrow top over a trunk
/// with even fewer returns), nor ahn3_delft or tiny.
pub(crate) fn trunk_on_top(points: &[Vec3]) -> Option<String> {
    let bottom = lowest_tenth(points)?;
    let top = highest_tenth(points)?;
    let trunk_like = top.spread_m < MIN_CROWN_TOP_SPREAD_M
        && top.points >= bottom.points
        && top.round >= bottom.round
        && bottom.spread_m >= CROWN_WIDER_BY * top.spread_m;
    trunk_like.then(|| {
        format!(
            "the cloud may be upside down: its highest tenth holds {} points within a median \
             {:.2} m of their centre, seen from {:.0} % of the directions around them, as a \
             trunk would, and its lowest tenth {} points spreading {:.2} m, as a crown's top \
             would (silva assumes the z axis points up)",
            top.points,
            top.spread_m,
            100.0 * top.round,
            bottom.points,
            bottom.spread_m
        )
    })
}

/// A side end this much rounder than the highest tenth needs only as many
/// points for [`seen_from_beside`] (for the other rule it needs
/// [`MORE_POINTS_BY`] as many, as in [`seen_from_below`]). Stricter than
/// [`MUCH_ROUNDER_BY`]: a crown that the clip's box cuts shows a flat face
/// at that side, hit as densely as the top and across its whole width. On
/// 80 synthetic AHN-like clips without their ground (`silva synth --scan
/// als`, each species seeds 1–10, leaf-off and leaf-on, points below the
/// 1st percentile of z + 0.5 m cut off; a Python prototype of this test)
/// one upright leaf-on birch, cut by its box at x = −5 m, was taken for a
/// clip on its side at 0.3, none at 0.35. With `silva reconstruct` on the
/// same clips lying with +x, −x, +y or −y up, 65, 61, 66 and 56 of 80 are
/// now flagged (11, 12, 12 and 6 before), none upright; on 120 more (seeds
/// 11–25) 93, 95, 97 and 91 (10, 8, 13 and 17 before), and upright one
/// more than before, a leaf-off oak whose highest tenth holds a few twigs
/// (20 returns) and one side of its broad crown 65; on 120 more (seeds
/// 26–40) 97, 95, 98 and 91 (10, 8, 21 and 10 before), and again one more
/// upright, a leaf-on birch with 17 returns in its highest tenth. Sparse terrestrial
/// scans (`--scan tls --density 20`, seeds 1–6; the 11 of 24 that the
/// trunk tests do not reject) lying on a side go unflagged 1–3 times
/// instead of 8–9, none upright; ahn3_delft and tiny are flagged lying
/// every way and not upright.
const MUCH_ROUNDER_BESIDE_BY: f32 = 0.35;

/// A note when an airborne clip without ground looks as if it lies on its
/// side (exported with `y` up, or turned by 90°): one of its side ends, the
/// tenth of its extent along a horizontal axis, is hit all round (across
/// that axis) and more than its highest tenth, as the crown's top would be
/// if that axis pointed up. Where several ends do (on a lying crown the
/// sides next to its top can), the one with the most points is the top. The airborne counterpart of
/// [`check_trunk_not_beside`] and [`check_ground_beside`], which need bark
/// or ground; run only where [`seen_from_below`] finds nothing, for a clip
/// turned over shows its side ends better than its bottom, now on top (of
/// the turned-over clips of [`MUCH_ROUNDER_BESIDE_BY`] that
/// [`seen_from_below`] misses, 2 of 6 and 2 of 30 get this note instead: a
/// flag, with the wrong axis).
pub(crate) fn seen_from_beside(points: &[Vec3]) -> Option<String> {
    let top = highest_tenth(points)?;
    let (side, end) = SIDEWAYS
        .iter()
        .filter_map(|side| {
            let turned: Vec<Vec3> = points.iter().map(|&p| (side.turn)(p)).collect();
            let end = highest_tenth(&turned)?;
            end.looks_like_the_top(&top, MUCH_ROUNDER_BESIDE_BY)
                .then_some((side, end))
        })
        .max_by(|a, b| (a.1.points.cmp(&b.1.points)).then(a.1.round.total_cmp(&b.1.round)))?;
    Some(format!(
        "the cloud may lie on its side: the tenth of it towards {up} holds {} points seen from \
         {:.0} % of the directions around it, its highest tenth {} points from {:.0} %, while \
         an airborne scan hits a crown's top most and all round; if {up} is up, turn the cloud \
         so that {up} becomes +z (silva assumes the z axis points up)",
        end.points,
        100.0 * end.round,
        top.points,
        100.0 * top.round,
        up = side.up,
    ))
}

/// The lowest [`END_SHARE`] of the points' height, seen from above.
fn lowest_tenth(points: &[Vec3]) -> Option<End> {
    let (low, high) = super::z_range(points);
    End::of(&slice(points, low, low + END_SHARE * (high - low)))
}

/// The highest [`END_SHARE`] of the points' height, seen from above.
fn highest_tenth(points: &[Vec3]) -> Option<End> {
    let (low, high) = super::z_range(points);
    End::of(&slice(points, high - END_SHARE * (high - low), high))
}

/// One end of a clip, seen along the axis that would point up: how many
/// points it holds, from how much of the way round ([`round_share`]) and
/// how far they spread ([`median_spread`]).
struct End {
    points: usize,
    round: f32,
    spread_m: f32,
}

impl End {
    /// `slice` seen from above; `None` when it is empty.
    fn of(slice: &[Vec3]) -> Option<End> {
        (!slice.is_empty()).then(|| End {
            points: slice.len(),
            round: round_share(slice),
            spread_m: median_spread(slice),
        })
    }

    /// True when this end is seen more than `top` ([`MORE_ROUND_BY`] rounder
    /// with [`MORE_POINTS_BY`] as many points, or `much_rounder_by` rounder
    /// with as many) and spreads like a crown's top
    /// ([`MIN_CROWN_TOP_SPREAD_M`]).
    fn looks_like_the_top(&self, top: &End, much_rounder_by: f32) -> bool {
        let (n, top_n) = (self.points as f32, top.points as f32);
        let more_seen = (self.round >= top.round + MORE_ROUND_BY && n >= MORE_POINTS_BY * top_n)
            || (self.round >= top.round + much_rounder_by && n >= top_n);
        more_seen && self.spread_m >= MIN_CROWN_TOP_SPREAD_M
    }
}

/// The median horizontal distance of the points from their median point
/// (coordinate by coordinate), in metres: how far they spread sideways,
/// whatever a few stray twigs do.
fn median_spread(points: &[Vec3]) -> f32 {
    let mut xs: Vec<f32> = points.iter().map(|p| p.x).collect();
    let mut ys: Vec<f32> = points.iter().map(|p| p.y).collect();
    let centre = Vec2::new(median(&mut xs), median(&mut ys));
    let mut distances: Vec<f32> = points
        .iter()
        .map(|p| p.truncate().distance(centre))
        .collect();
    median(&mut distances)
}

/// The share of [`SECTOR_DEG`] sectors around the points' horizontal
/// centroid that hold a point (0 for no points).
fn round_share(points: &[Vec3]) -> f32 {
    if points.is_empty() {
        return 0.0;
    }
    let flat: Vec<Vec2> = points.iter().map(|p| p.truncate()).collect();
    let centre = flat.iter().sum::<Vec2>() / flat.len() as f32;
    let sectors = (360 / SECTOR_DEG) as usize;
    sectors_seen(&flat, centre, sectors) as f32 / sectors as f32
}

/// The points with `lo ≤ z ≤ hi`.
pub(crate) fn slice(points: &[Vec3], lo: f32, hi: f32) -> Vec<Vec3> {
    points
        .iter()
        .copied()
        .filter(|p| (lo..=hi).contains(&p.z))
        .collect()
}

/// Radius of the thickest ring among the pieces of `slice` (points closer
/// than `link` seen from above belong to one piece), 0 when no piece holds
/// a ring.
fn thickest_stem(slice: &[Vec3], link: f32) -> f32 {
    pieces(slice, link)
        .iter()
        .filter(|piece| piece.len() >= MIN_RING_POINTS)
        .filter_map(|piece| ring_radius(&upright_section(piece)))
        .fold(0.0, f32::max)
}

/// The piece seen along its own axis rather than from above: projected
/// onto the plane across the axis that [`axis_slope`] gives. Seen from
/// above, a slice as tall as a trunk is thick smears a leaning trunk into a
/// crescent: tree13's trunk (radius about 20 cm) leans 22° in its bottom
/// slice (0.4 m), which smears it by 0.16 m, and seen from above no circle
/// held 30 of its points; seen along its axis it rings, so tree13 turned
/// over is rejected. Even a thin slice of a trunk leaning 60° is an ellipse
/// twice as long as wide; along the axis it is a circle.
fn upright_section(piece: &[Vec3]) -> Vec<Vec2> {
    let slope = axis_slope(piece);
    let slope = if slope.length() <= MAX_AXIS_LEAN_DEG.to_radians().tan() {
        slope
    } else {
        Vec2::ZERO
    };
    let (across, side) = slope.extend(1.0).normalize().any_orthonormal_pair();
    piece
        .iter()
        .map(|p| Vec2::new(p.dot(across), p.dot(side)))
        .collect()
}

/// Thin layers in which [`axis_slope`] takes the centroids of a piece.
const AXIS_LAYERS: usize = 4;

/// How far a stem's axis drifts sideways per metre of height, from the
/// centroids of [`AXIS_LAYERS`] thin layers of its bark points (their
/// least-squares slope against height). The slope of the points
/// themselves ([`lean`]) mixes in the bark's own tilt across a leaning
/// stem: in a slice 0.4 m tall through a 20 cm trunk leaning 40°, it came
/// out near 4°.
fn axis_slope(piece: &[Vec3]) -> Vec2 {
    let (low, high) = super::z_range(piece);
    if high - low <= 0.0 {
        return Vec2::ZERO;
    }
    let centroids: Vec<Vec3> = height_layers(piece, low, high, AXIS_LAYERS)
        .iter()
        .filter(|layer| !layer.is_empty())
        .map(|layer| layer.iter().copied().sum::<Vec3>() / layer.len() as f32)
        .collect();
    if centroids.len() >= 3 {
        lean(&centroids)
    } else {
        Vec2::ZERO
    }
}

/// The `points` from height `low` to `high` (both included) in `n` layers
/// of equal height, lowest first. `high` must lie above `low`.
fn height_layers(points: &[Vec3], low: f32, high: f32, n: usize) -> Vec<Vec<Vec3>> {
    let layer = (high - low) / n as f32;
    let mut layers = vec![Vec::new(); n];
    for p in points.iter().filter(|p| (low..=high).contains(&p.z)) {
        let k = (((p.z - low) / layer) as usize).min(n - 1);
        layers[k].push(*p);
    }
    layers
}

/// Layers in which [`axis_lean`] takes the median point of a trunk.
const AXIS_LEAN_LAYERS: usize = 8;

/// Fewest points a layer of [`axis_lean`] needs to place the axis.
const AXIS_LEAN_MIN_POINTS: usize = 5;

/// How far a trunk's axis drifts sideways per metre of height, from the
/// `points` between heights `low` and `high`: the median point (coordinate
/// by coordinate) of each of [`AXIS_LEAN_LAYERS`] equal layers, and the
/// median of the slopes between every two of them (Theil–Sen). Zero with
/// fewer than two layers of [`AXIS_LEAN_MIN_POINTS`] points.
///
/// [`lean`], the slope of the points themselves, reads the tilted bark
/// across a thick trunk's slanted lowest end: tree1 turned 45° about +x
/// measured 17° with it (a Python prototype on the raw cloud; under 30° in
/// `silva reconstruct`), 42° with this. Turned 45° either way about x or
/// y, the prototype measured 42–48° with this, 17–58° with [`lean`]. A low
/// limb moves one layer's median, and a pairwise median shrugs that off.
pub(crate) fn axis_lean(points: &[Vec3], low: f32, high: f32) -> Vec2 {
    let span = high - low;
    if span.is_nan() || span <= 0.0 {
        return Vec2::ZERO;
    }
    let layer_m = span / AXIS_LEAN_LAYERS as f32;
    let centres: Vec<Vec3> = height_layers(points, low, high, AXIS_LEAN_LAYERS)
        .iter()
        .enumerate()
        .filter(|(_, layer)| layer.len() >= AXIS_LEAN_MIN_POINTS)
        .map(|(k, layer)| {
            let mut xs: Vec<f32> = layer.iter().map(|p| p.x).collect();
            let mut ys: Vec<f32> = layer.iter().map(|p| p.y).collect();
            Vec3::new(
                median(&mut xs),
                median(&mut ys),
                low + (k as f32 + 0.5) * layer_m,
            )
        })
        .collect();
    let (mut dx, mut dy) = (Vec::new(), Vec::new());
    for (i, a) in centres.iter().enumerate() {
        for b in &centres[i + 1..] {
            let slope = (b.truncate() - a.truncate()) / (b.z - a.z);
            dx.push(slope.x);
            dy.push(slope.y);
        }
    }
    if dx.is_empty() {
        return Vec2::ZERO;
    }
    Vec2::new(median(&mut dx), median(&mut dy))
}

/// How far the points drift sideways per metre of height: the
/// least-squares slope of their `x` and `y` against `z` (zero when they
/// span no height or the slope is not finite). For the points of a stem,
/// the tangent of its lean; `atan` of the length gives the angle from
/// vertical.
pub(crate) fn lean(points: &[Vec3]) -> Vec2 {
    let mean = points.iter().copied().sum::<Vec3>() / points.len().max(1) as f32;
    let (mut zz, mut xz) = (0.0, Vec2::ZERO);
    for p in points {
        let d = *p - mean;
        zz += d.z * d.z;
        xz += d.truncate() * d.z;
    }
    let slope = xz / zz;
    if zz > 0.0 && slope.is_finite() {
        slope
    } else {
        Vec2::ZERO
    }
}

/// The radius of the circle that `piece` rings, if it is a ring: enough
/// points on it, all round, close to the circle.
fn ring_radius(piece: &[Vec2]) -> Option<f32> {
    let (circle, inliers) = robust_circle(piece, MAX_TRUNK_RADIUS_M)?;
    let ring = inliers.len() >= MIN_RING_POINTS
        && arc_covered_deg(&inliers, circle.centre) >= MIN_ARC_DEG
        && circle_rms(&inliers, circle) <= 0.25 * circle.radius;
    ring.then_some(circle.radius)
}

/// How much of the circle around `centre` the `points` cover, in degrees:
/// the number of [`ARC_BIN_DEG`] bins that hold a point, times the width.
fn arc_covered_deg(points: &[Vec2], centre: Vec2) -> u32 {
    sectors_seen(points, centre, (360 / ARC_BIN_DEG) as usize) * ARC_BIN_DEG
}

/// The connected pieces of `points` when points closer than `link` seen from
/// above are joined: union–find over a grid of `link` cells.
fn pieces(points: &[Vec3], link: f32) -> Vec<Vec<Vec3>> {
    let flat: Vec<Vec2> = points.iter().map(|p| p.truncate()).collect();
    let cell = |p: Vec2| {
        let c = (p / link).floor();
        (c.x as i64, c.y as i64)
    };
    let mut grid: HashMap<(i64, i64), Vec<u32>> = HashMap::new();
    for (i, &p) in flat.iter().enumerate() {
        grid.entry(cell(p)).or_default().push(i as u32);
    }
    let mut sets = UnionFind::new(points.len());
    for (i, &p) in flat.iter().enumerate() {
        let (cx, cy) = cell(p);
        for (dx, dy) in [(0, 0), (1, -1), (1, 0), (1, 1), (0, 1)] {
            for &j in grid.get(&(cx + dx, cy + dy)).into_iter().flatten() {
                if flat[j as usize].distance(p) < link {
                    sets.union(i as u32, j);
                }
            }
        }
    }
    let mut by_set: HashMap<u32, Vec<Vec3>> = HashMap::new();
    for (i, &p) in points.iter().enumerate() {
        by_set.entry(sets.find(i as u32)).or_default().push(p);
    }
    by_set.into_values().collect()
}

/// Share of its cells that a flat surface covering a cloud's top must
/// reach before [`check_ground_below`] calls the cloud upside down.
const MIN_TOP_GROUND_SHARE: f32 = 0.5;

/// Rejects a cloud whose ground lies on top: turned over, a clip or a
/// plot scan shows a flat surface covering the top of the cloud and none
/// (or less) at its bottom. `split` is the cloud's ground split as it
/// stands. Both pipelines run it before their ground leaves.
pub(super) fn check_ground_below(
    points: &[Vec3],
    split: &GroundSplit,
) -> Result<(), ReconstructError> {
    let flipped: Vec<Vec3> = points.iter().map(|p| Vec3::new(p.x, p.y, -p.z)).collect();
    // The full fit only where its share could reach the test's half (the
    // cheap share is an upper bound of it).
    let top_share = if terrain_cell_share(&flipped) >= MIN_TOP_GROUND_SHARE {
        fit_terrain(&flipped)
            .filter(Terrain::is_ground)
            .map_or(0.0, |t| t.cell_share())
    } else {
        0.0
    };
    let bottom_share = match split.method {
        GroundMethod::None => 0.0,
        _ => split.terrain.as_ref().map_or(0.0, Terrain::cell_share),
    };
    if top_share >= MIN_TOP_GROUND_SHARE && top_share > bottom_share + 0.2 {
        return Err(ReconstructError::Degenerate(format!(
            "the cloud looks upside down: a flat surface covers {:.0} % of its top and only \
             {:.0} % of its bottom",
            top_share * 100.0,
            bottom_share * 100.0
        )));
    }
    check_ground_beside(points, bottom_share)?;
    let under = split
        .terrain
        .as_ref()
        .map_or(0.0, |t| share_under(points, t));
    if under >= MAX_SHARE_UNDER_GROUND {
        return Err(ReconstructError::Degenerate(format!(
            "the cloud looks upside down: {:.0} % of the points off its ground surface lie under \
             it, so the surface covers the cloud's top",
            under * 100.0
        )));
    }
    Ok(())
}

/// Points turned so that another axis is their `z`.
type Turn = fn(Vec3) -> Vec3;

/// One way a cloud can lie on its side.
struct Side {
    /// The axis that would point up.
    up: &'static str,
    /// The cloud's end where the ground or the trunk's base would be.
    base: &'static str,
    /// The points turned so that `up` is their `z` (the other two keep
    /// their handedness; [`fit_terrain`] needs only the up axis).
    turn: Turn,
}

/// The four ways a cloud can lie on its side.
static SIDEWAYS: [Side; 4] = [
    Side {
        up: "+x",
        base: "−x",
        turn: |p| Vec3::new(p.y, p.z, p.x),
    },
    Side {
        up: "−x",
        base: "+x",
        turn: |p| Vec3::new(p.z, p.y, -p.x),
    },
    Side {
        up: "+y",
        base: "−y",
        turn: |p| Vec3::new(p.z, p.x, p.y),
    },
    Side {
        up: "−y",
        base: "+y",
        turn: |p| Vec3::new(p.x, p.z, -p.y),
    },
];

/// The side on which `measure` of the cloud turned to stand on it (every
/// `step`-th point) is largest, with that measure.
fn most_on_a_side(
    points: &[Vec3],
    step: usize,
    measure: impl Fn(&[Vec3]) -> f32,
) -> (&'static Side, f32) {
    SIDEWAYS
        .iter()
        .map(|side| {
            let turned: Vec<Vec3> = points
                .iter()
                .step_by(step)
                .map(|&p| (side.turn)(p))
                .collect();
            (side, measure(&turned))
        })
        .fold(
            (&SIDEWAYS[0], 0.0),
            |best, s| if s.1 > best.1 { s } else { best },
        )
}

/// [`check_ground_beside`] looks at every this-many-th point of a larger
/// cloud: a grid of lowest points needs no more, and the test then costs
/// the same on a 5-million-point scan.
const MAX_SIDEWAYS_POINTS: usize = 200_000;

/// Rejects a cloud that lies on its side: its ground, turned with it,
/// stands as a wall. A clip exported with `y` up (the convention of many
/// mesh and game tools) or turned by 90° otherwise shows no ground below,
/// and the reconstruction took the clip's width for the tree's height
/// and a wall of ground returns for its crown. The terrain fit is run with
/// each horizontal axis as up ([`SIDEWAYS`]); the cloud is rejected when one
/// of them finds ground in at least [`MIN_SIDE_GROUND_SHARE`] of its cells and
/// `bottom_share` (the upright fit's) is lower by
/// [`SIDE_GROUND_MARGIN`]. Turns up to 45° leave the ground below, where
/// the upright fit finds it sloping ([`super::ground::STEEP_TERRAIN_DEG`]).
/// A cloud turned only part of the way onto a side (60–75°: 29 of the 64
/// plot scans turned 60° about x or y, `silva synth --scan tls
/// --ground-radius 4`, four species, seeds 1–8) is told its tilt and the
/// turn that levels it ([`partly_turned`]) instead of the axis to bring up.
fn check_ground_beside(points: &[Vec3], bottom_share: f32) -> Result<(), ReconstructError> {
    // No side can beat ground under every cell of the bottom by the margin
    // (an airborne clip with its ground, the inventory's usual input).
    if bottom_share + SIDE_GROUND_MARGIN >= 1.0 {
        return Ok(());
    }
    let step = points.len().div_ceil(MAX_SIDEWAYS_POINTS).max(1);
    let (side, share) = most_on_a_side(points, step, |turned| {
        let (low, high) = super::z_range(turned);
        // Nothing as tall as a tree stands on a side narrower than one:
        // seen from the side, a thin stem's whole bark is within the
        // ground tolerance of its lowest points, and "bare". The full fit
        // only where the plane can hold enough cells.
        if high - low >= MIN_HEIGHT_M && terrain_cell_share(turned) >= MIN_SIDE_GROUND_SHARE {
            fit_terrain(turned)
                .filter(Terrain::is_ground)
                .map_or(0.0, |t| t.cell_share())
        } else {
            0.0
        }
    });
    if share >= MIN_SIDE_GROUND_SHARE && share > bottom_share + SIDE_GROUND_MARGIN {
        let found = format!(
            "a flat surface covers {:.0} % of its {} end, as ground would if {} pointed up, and \
             only {:.0} % of its bottom",
            share * 100.0,
            side.base,
            side.up,
            bottom_share * 100.0,
        );
        return Err(ReconstructError::Degenerate(
            match partly_turned(points, side) {
                Some(plane) => format!(
                    "the cloud looks tilted by {:.0}°: {found}; as a plane it faces {} ({} to \
                     level it)",
                    plane.tilt_deg,
                    plane.facing(),
                    levelling_words(plane.up)
                ),
                None => format!(
                    "the cloud looks tilted onto its side: {found} (turn the cloud so that {} \
                     becomes +z; a y-up export needs (x, y, z) → (x, −z, y))",
                    side.up
                ),
            },
        ));
    }
    Ok(())
}

/// A cloud turned this far from upright (degrees) or farther lies on its
/// side, and [`check_ground_beside`] names the axis that is up.
const ON_ITS_SIDE_DEG: f32 = 80.0;

/// The ground plane ([`super::ground_plane::ground_plane`]) of a cloud
/// whose ground [`check_ground_beside`] found at `side`'s base end, when
/// the plane faces that side (within 45° of its up axis) and tilts less
/// than [`ON_ITS_SIDE_DEG`]: the cloud was turned part of the way onto that
/// side, and the plane's normal tells how far. Plot scans turned 60° lie
/// nearer to their side than to upright; asked to turn +x up, a user would
/// have turned them 90°.
fn partly_turned(points: &[Vec3], side: &Side) -> Option<GroundPlane> {
    let side_up = Vec3::new(
        (side.turn)(Vec3::X).z,
        (side.turn)(Vec3::Y).z,
        (side.turn)(Vec3::Z).z,
    );
    super::ground_plane::ground_plane(points, false).filter(|plane| {
        plane.up.angle_between(side_up).to_degrees() <= 45.0 && plane.tilt_deg < ON_ITS_SIDE_DEG
    })
}

/// The share of a side's grid cells whose lowest point is ground from which
/// [`check_ground_beside`] takes that side for the ground, as
/// [`check_ground_below`] does for the top.
const MIN_SIDE_GROUND_SHARE: f32 = 0.5;

/// ...when the upright fit's share is lower by at least this.
const SIDE_GROUND_MARGIN: f32 = 0.2;

/// Share of the points off the ground surface that lie under it, from which
/// [`check_ground_below`] takes a cloud as upside down. The terrain fit of a
/// turned-over plot can take the flat surface on top for ground when it
/// holds most cells' lowest points (a disc around a narrow crown); the tree
/// then hangs under it. A clip the right way up has only stray noise there.
const MAX_SHARE_UNDER_GROUND: f32 = 0.5;

/// Of the points more than the ground tolerance above `terrain` or more
/// than the ground split's noise depth under it, the share under it (0 for
/// none).
fn share_under(points: &[Vec3], terrain: &Terrain) -> f32 {
    let (mut over, mut under) = (0usize, 0usize);
    for p in points {
        let above = p.z - terrain.height_at(p.x, p.y);
        if above >= GROUND_TOLERANCE_M {
            over += 1;
        } else if above < -BELOW_GROUND_NOISE_M {
            under += 1;
        }
    }
    under as f32 / (over + under).max(1) as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Points on a vertical cylinder's bark from `z0` to `z1`.
    fn stem(centre: Vec2, radius: f32, z0: f32, z1: f32, n: usize) -> Vec<Vec3> {
        (0..n)
            .map(|i| {
                let a = i as f32 * 2.399_963; // golden angle
                let z = z0 + (z1 - z0) * (i as f32 + 0.5) / n as f32;
                (centre + radius * Vec2::new(a.cos(), a.sin())).extend(z)
            })
            .collect()
    }

    /// A 10 m column: a 20 cm trunk up to 3 m, then twigs of 1 cm radius
    /// ringing it up to the top.
    fn column() -> Vec<Vec3> {
        column_with_bark_points(3000)
    }

    /// [`column`] with `n` points on the trunk's bark.
    fn column_with_bark_points(n: usize) -> Vec<Vec3> {
        let mut points = stem(Vec2::ZERO, 0.2, 0.0, 3.0, n);
        for k in 0..8 {
            let a = k as f32 * std::f32::consts::TAU / 8.0;
            let at = 0.5 * Vec2::new(a.cos(), a.sin());
            points.extend(stem(at, 0.01, 3.0, 10.0, 1500));
        }
        points
    }

    #[test]
    fn a_column_on_its_trunk_passes() {
        assert_eq!(
            check_stands_on_its_trunk(&column(), 0.04, DENSE_SLICES),
            Ok(())
        );
    }

    #[test]
    fn a_column_on_its_top_is_upside_down() {
        let flipped: Vec<Vec3> = column().iter().map(|p| p.with_z(-p.z)).collect();
        let err = check_stands_on_its_trunk(&flipped, 0.04, DENSE_SLICES).unwrap_err();
        assert!(err.to_string().contains("upside down"), "{err}");
        assert!(err.to_string().contains("z axis points up"), "{err}");
    }

    #[test]
    fn a_column_on_its_side_names_the_axis_that_is_up() {
        // Twigs 1.5 m out as well: lying, the cloud is 3 m tall.
        let mut tree = column();
        for k in 0..8 {
            let a = (k as f32 + 0.5) * std::f32::consts::TAU / 8.0;
            tree.extend(stem(
                1.5 * Vec2::new(a.cos(), a.sin()),
                0.01,
                4.0,
                10.0,
                1500,
            ));
        }
        assert_eq!(check_stands_on_its_trunk(&tree, 0.04, DENSE_SLICES), Ok(()));
        let y_up: Vec<Vec3> = tree.iter().map(|p| Vec3::new(p.x, p.z, -p.y)).collect();
        let err = check_stands_on_its_trunk(&y_up, 0.04, DENSE_SLICES).unwrap_err();
        let e = err.to_string();
        assert!(e.contains("onto its side") && e.contains("+y"), "{e}");
        assert!(e.contains("40 cm thick"), "{e}");
    }

    /// [`check_stands_on_its_trunk`]'s link on tree13 (four times its
    /// median point spacing of 0.054 m).
    const TREE13_LINK_M: f32 = 0.216;

    /// The column leaning `deg` (turned about the `x` axis), its bark as
    /// sparsely scanned as tree13's (points about 5 cm apart, joined into
    /// pieces at four spacings, [`TREE13_LINK_M`]).
    fn leaning_column(deg: f32) -> Vec<Vec3> {
        let turn = glam::Quat::from_rotation_x(deg.to_radians());
        column_with_bark_points(1200)
            .iter()
            .map(|&p| turn * p)
            .collect()
    }

    #[test]
    fn a_leaning_column_on_its_top_is_upside_down() {
        // Not 60°: the top slice of this 5 m tall cloud (0.1–0.3 m below
        // its top) then cuts only the slanted end of the trunk.
        for deg in [20.0, 40.0] {
            let leaning = leaning_column(deg);
            assert_eq!(
                check_stands_on_its_trunk(&leaning, TREE13_LINK_M, DENSE_SLICES),
                Ok(()),
                "{deg}°"
            );
            let flipped: Vec<Vec3> = leaning.iter().map(|p| p.with_z(-p.z)).collect();
            let err = check_stands_on_its_trunk(&flipped, TREE13_LINK_M, DENSE_SLICES).unwrap_err();
            assert!(err.to_string().contains("upside down"), "{deg}°: {err}");
        }
    }

    #[test]
    fn a_leaning_trunk_is_measured_along_its_axis() {
        for deg in [20.0, 40.0, 60.0] {
            let slice = slice(&leaning_column(deg), 0.2, 0.6);
            let radius = thickest_stem(&slice, TREE13_LINK_M);
            assert!((radius - 0.2).abs() < 0.01, "{deg}°: {radius}");
        }
    }

    /// An airborne clip of a bare 10 m tree without its ground: returns
    /// from a dome-shaped crown top (radius 3 m, every 0.25 m) and a few
    /// from the trunk below it.
    fn airborne_crown() -> Vec<Vec3> {
        let mut points = Vec::new();
        for i in -12..=12 {
            for j in -12..=12 {
                let at = 0.25 * Vec2::new(i as f32, j as f32);
                if at.length() <= 3.0 {
                    points.push(at.extend(10.0 - at.length_squared() / 3.0));
                }
            }
        }
        points.extend((0..12).map(|k| Vec3::new(0.2, 0.0, 0.5 * k as f32)));
        points
    }

    #[test]
    fn an_airborne_clip_seen_from_below_is_flagged() {
        assert_eq!(seen_from_below(&airborne_crown()), None);
        let flipped: Vec<Vec3> = airborne_crown().iter().map(|p| p.with_z(-p.z)).collect();
        let note = seen_from_below(&flipped).expect("a note");
        assert!(note.contains("upside down") && note.contains("z axis points up"));
    }

    /// Lying with +y up (a y-up export, (x, y, z) → (x, z, −y)) the dome's
    /// top is at the +y end, hit all round across y and by more returns
    /// than the clip's highest tenth, now a slab of the crown's side; with
    /// −x up at the −x end. Upright, or turned over (which
    /// [`seen_from_below`] reports), no side end looks like the top.
    #[test]
    fn an_airborne_clip_lying_on_its_side_is_flagged_with_the_axis_up() {
        let crown = airborne_crown();
        assert_eq!(seen_from_beside(&crown), None);
        let y_up: Vec<Vec3> = crown.iter().map(|p| Vec3::new(p.x, p.z, -p.y)).collect();
        let note = seen_from_beside(&y_up).expect("a note");
        assert!(
            note.contains("if +y is up") && note.contains("z axis points up"),
            "{note}"
        );
        let minus_x_up: Vec<Vec3> = crown.iter().map(|p| Vec3::new(-p.z, p.y, p.x)).collect();
        let note = seen_from_beside(&minus_x_up).expect("a note");
        assert!(note.contains("if −x is up"), "{note}");
        assert_eq!(seen_from_beside(&[]), None);
    }

    /// Turned over, a ring of trunk bark lies on top of a row of twigs that
    /// spreads wider: the trunk is on top. Upright, or with a trunk as wide
    /// as the twigs spread, it is not.
    #[test]
    fn a_trunk_over_a_wider_crown_top_is_on_top() {
        let turned = |points: Vec<Vec3>| -> Vec<Vec3> {
            points.iter().map(|p| Vec3::new(p.x, -p.y, -p.z)).collect()
        };
        assert_eq!(trunk_on_top(&ring_below_twigs(0.2)), None);
        let note = trunk_on_top(&turned(ring_below_twigs(0.2))).expect("a note");
        assert!(
            note.contains("upside down") && note.contains("z axis points up"),
            "{note}"
        );
        assert_eq!(trunk_on_top(&turned(ring_below_twigs(0.3))), None);
        assert_eq!(trunk_on_top(&[]), None);
    }

    /// An airborne clip of a 10 m conifer without its ground: a cone-shaped
    /// top hit all round (radius 1.2 m at 1 m below the apex), a few stem
    /// returns, and at the bottom one low limb reaching out to one side
    /// with as many returns as the top.
    fn conifer_with_low_limb() -> Vec<Vec3> {
        let mut points = Vec::new();
        for k in 0..90 {
            let (turn, down) = (k as f32 * 2.4, (k % 10) as f32 * 0.1);
            let radius = 1.2 * down;
            points.push(Vec3::new(
                radius * turn.cos(),
                radius * turn.sin(),
                10.0 - down,
            ));
        }
        points.extend((2..9).map(|z| Vec3::new(0.05, 0.0, z as f32)));
        points.extend((0..90).map(|k| {
            Vec3::new(
                0.5 + 0.03 * k as f32,
                0.02 * (k % 3) as f32,
                0.01 * (k % 9) as f32,
            )
        }));
        points
    }

    /// Turned over, the conifer's top lies at the bottom with no more points
    /// than the limb now on top, but seen from every side: it is flagged.
    /// Upright, its limb is seen from one side and the clip is not.
    #[test]
    fn a_conifer_turned_over_is_flagged_by_its_round_top() {
        let upright = conifer_with_low_limb();
        assert_eq!(seen_from_below(&upright), None);
        let flipped: Vec<Vec3> = upright.iter().map(|p| p.with_z(-p.z)).collect();
        let note = seen_from_below(&flipped).expect("a note");
        assert!(note.contains("90 points"), "{note}");
    }

    /// A sparse terrestrial scan sees the trunk all round and most too, but
    /// a trunk is narrower than a crown's top: a ring of `radius` around
    /// the lowest metre of a 10 m cloud, twigs in a row at its top.
    fn ring_below_twigs(radius: f32) -> Vec<Vec3> {
        let mut points = stem(Vec2::ZERO, radius, 0.0, 1.0, 400);
        points.extend((0..20).map(|k| Vec3::new(0.1 * k as f32, 0.0, 10.0)));
        points
    }

    #[test]
    fn a_trunk_seen_all_round_is_no_crown_top() {
        assert_eq!(seen_from_below(&ring_below_twigs(0.3)), None);
        assert!(seen_from_below(&ring_below_twigs(1.0)).is_some());
    }

    #[test]
    fn an_empty_or_flat_clip_gets_no_note() {
        assert_eq!(seen_from_below(&[]), None);
        assert_eq!(seen_from_below(&[Vec3::ZERO; 5]), None);
    }

    /// A conifer's top: a 2 cm leader with a whorl of eight twigs that
    /// radiate and bend up through the top slice, crossing any circle
    /// around the leader at eight places.
    #[test]
    fn a_whorl_round_the_leader_is_no_stem() {
        let mut points = column();
        for k in 0..8 {
            let a = k as f32 * std::f32::consts::TAU / 8.0;
            let out = Vec2::new(a.cos(), a.sin());
            points.extend((0..400).map(|i| {
                let t = i as f32 / 400.0;
                let jitter = 0.004 * Vec2::new((t * 97.0).sin(), (t * 61.0).sin());
                (out * 1.2 * t + jitter).extend(9.45 + 0.3 * t)
            }));
        }
        assert_eq!(
            check_stands_on_its_trunk(&points, 0.04, DENSE_SLICES),
            Ok(())
        );
    }

    #[test]
    fn twigs_are_pieces_of_their_own_and_a_ring_is_one() {
        let mut slice = stem(Vec2::ZERO, 0.2, 0.0, 1.0, 200);
        slice.push(Vec3::new(1.0, 0.0, 0.5));
        slice.push(Vec3::new(1.01, 0.0, 0.5));
        let mut sizes: Vec<usize> = pieces(&slice, 0.04).iter().map(Vec::len).collect();
        sizes.sort_unstable();
        assert_eq!(sizes, vec![2, 200]);
        assert!((thickest_stem(&slice, 0.04) - 0.2).abs() < 0.01);
    }
}
