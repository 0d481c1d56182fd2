//! Trunk insertion: Hu et al. §4.2, Eq. 3/4 and the λ1/λ2 rule.
//!
//! Airborne scans hit a trunk a few times at most, yet the skeleton has to
//! start at a trunk base on the ground. The lowest tree point v_low is taken
//! as a trunk point; the mean direction n_avg from it to its neighbours
//! within a sphere approximates the trunk axis. When that axis is close to
//! the crown's vertical centreline (λ1 ≤ 30°) and v_low is near it
//! (λ2 ≤ 0.5), the trunk is extended down along n_avg to the ground (Eq. 3).
//! Otherwise v_low is a low branch, not the trunk, and the root is put at the
//! centre of the crown's ground footprint g_b, with trunk points interpolated
//! up to the crown centroid v_c (Eq. 4).
//!
//! Four additions for AHN densities, where a trunk is hit once or not at
//! all: v_low counts as a trunk hit only when it starts a column of returns
//! (the points less than r above it stay within r / 2 of it horizontally),
//! since the lowest return is as often the tip of a low limb among other
//! limbs' returns; a lowest point without neighbours (n_avg undefined) is
//! taken as a hit on a vertical trunk, within the paper's λ2 ≤ 0.5 even
//! where returns with neighbours need the tighter [`Params::lambda2_max`];
//! above v_low the Eq. 3 trunk rises vertically to the crown's lowest
//! layer, then follows the Eq. 4 line to the crown centroid, as the Eq. 4
//! trunk does; and the footprint centre g_b is the area centroid of the
//! crown's projection rather than the centre of its bounding box (see
//! [`footprint_centre`]). A fifth, when a terrain is known: a column of
//! stem returns (one or more) 0.3–2.5 m above the ground ([`stem_column`])
//! places the base in preference to both equations. A sixth, for leaf-on
//! scans that show no stem: under a columnar crown Eq. 4's g_b is the
//! centre of the crown's lowest layer rather than of its footprint
//! ([`lowest_layer_centre`]). A seventh, for the crown above the centroid:
//! the trunk continues as a straight leader to just under the highest
//! return ([`leader`], [`Params::leader`]).

use glam::{Vec2, Vec3};

use super::Params;
use crate::reconstruct::ground::Terrain;
use crate::reconstruct::horizontal_spread;
use crate::reconstruct::metrics::COLUMNAR_SPREAD_M;
use crate::spatial::PointIndex;

/// Which of the paper's equations placed the trunk.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum TrunkRule {
    /// Eq. 3: extended down from the lowest point along n_avg.
    FromLowestPoint,
    /// Eq. 4: from the footprint centre up to the crown centroid.
    FromCrownCentre,
    /// Our addition: down from a column of stem returns under the crown
    /// (see [`stem_column`]).
    OnStemReturns,
}

/// The inserted trunk.
#[derive(Debug, Clone)]
pub(super) struct Trunk {
    /// The root (trunk base on the ground) first, then trunk points upward
    /// at voxel spacing; the second point is Algorithm 2's first `end`.
    pub(super) points: Vec<Vec3>,
    /// The rule that placed it.
    pub(super) rule: TrunkRule,
    /// λ1 in degrees.
    pub(super) lambda1_deg: f32,
    /// λ2.
    pub(super) lambda2: f32,
    /// Height of the leader's top above the root, when one was inserted
    /// (see [`Params::leader`]).
    pub(super) leader_top_m: Option<f32>,
}

impl Trunk {
    /// One line for the result's notes.
    pub(super) fn note(&self) -> String {
        let eq = match self.rule {
            TrunkRule::FromLowestPoint => "Eq. 3 (down from the lowest point)",
            TrunkRule::FromCrownCentre => "Eq. 4 (footprint centre to crown centroid)",
            TrunkRule::OnStemReturns => "a column of stem returns, then Eq. 4's line",
        };
        let leader = self.leader_top_m.map_or(String::new(), |top| {
            format!(", continued as a straight leader to {top:.1} m above the base")
        });
        format!(
            "trunk: {} points by {eq}, λ1 = {:.0}°, λ2 = {:.2}{leader}",
            self.points.len(),
            self.lambda1_deg,
            self.lambda2
        )
    }
}

/// Places the trunk base and trunk points for tree points `tree` (ground
/// removed, at least one point) standing on `terrain` (the lowest tree point
/// is taken as ground level when there is none). §4.2.
pub(super) fn add_trunk(tree: &[Vec3], terrain: Option<&Terrain>, params: &Params) -> Trunk {
    let crown = CrownFrame::of(tree, terrain);
    let lowest = LowestPointTest::run(
        tree,
        crown.v_low,
        crown.centre_xy,
        crown.half_diagonal,
        params,
    );
    // Stem returns take precedence over Eq. 3: the returns of a column
    // average out the trunk's lean, whereas n_avg from the two or three
    // returns next to v_low tilts by 20° and more at AHN densities, which
    // Eq. 3 turns into an offset of h·tan(λ1) at the ground (0.46 m from a
    // stem hit 1.2 m up on a synthetic birch whose stem column is 0.01 m
    // from the true base).
    let column_xy =
        terrain.and_then(|t| stem_column(tree, t, crown.half_diagonal, crown.centre_xy));
    let (rule, mut points) = match (lowest.direction, column_xy) {
        (Some(n), None) => (TrunkRule::FromLowestPoint, crown.eq3_trunk(tree, n, params)),
        (_, Some(xy)) => (
            TrunkRule::OnStemReturns,
            crown.column_trunk(tree, xy, params),
        ),
        (None, None) => (TrunkRule::FromCrownCentre, crown.eq4_trunk(tree, params)),
    };
    let leader_top_m = if params.leader {
        extend_with_leader(&mut points, tree, trunk_spacing(params), params.voxel_m)
    } else {
        None
    };
    Trunk {
        points,
        rule,
        lambda1_deg: lowest.lambda1_deg,
        lambda2: lowest.lambda2,
        leader_top_m,
    }
}

/// Spacing of the inserted trunk points. The paper leaves it open. Half of
/// r_p keeps each trunk point short of k trunk neighbours within r_p, so
/// Algorithm 1's kNN pass links the trunk to the crown points around it
/// instead of letting the trunk form a closed clique.
fn trunk_spacing(params: &Params) -> f32 {
    params.neighbour_radius_m * 0.5
}

/// The crown's reference points of §4.2, and the ground under it.
struct CrownFrame<'t> {
    terrain: Option<&'t Terrain>,
    /// The lowest tree point.
    v_low: Vec3,
    /// Centre of the crown's ground footprint ([`footprint_centre`]).
    centre_xy: Vec2,
    /// The tree points' centroid.
    v_c: Vec3,
    /// Half the horizontal diagonal of the points' bounding box (λ2's
    /// scale).
    half_diagonal: f32,
}

impl<'t> CrownFrame<'t> {
    fn of(tree: &[Vec3], terrain: Option<&'t Terrain>) -> Self {
        let v_low = tree
            .iter()
            .copied()
            .min_by(|a, b| a.z.total_cmp(&b.z))
            .unwrap_or(Vec3::ZERO);
        let (v_min, v_max) = tree
            .iter()
            .fold((v_low, v_low), |(lo, hi), &p| (lo.min(p), hi.max(p)));
        CrownFrame {
            terrain,
            v_low,
            centre_xy: footprint_centre(tree),
            v_c: tree.iter().copied().sum::<Vec3>() / tree.len().max(1) as f32,
            half_diagonal: ((v_max - v_min) * 0.5)
                .truncate()
                .length()
                .max(f32::EPSILON),
        }
    }

    /// Ground height under `xy`: the terrain's surface, never above the
    /// lowest tree point; that point's height without a terrain.
    fn ground_at(&self, xy: Vec2) -> f32 {
        self.terrain
            .map_or(self.v_low.z, |t| t.surface_at(xy.x, xy.y).min(self.v_low.z))
    }

    /// Eq. 3: v_t = v_low − n_avg·t, with t = h / n_avg.z reaching the
    /// ground, rising through v_low.
    fn eq3_trunk(&self, tree: &[Vec3], n_avg: Vec3, params: &Params) -> Vec<Vec3> {
        let v_low = self.v_low;
        let h = v_low.z - self.ground_at(v_low.truncate());
        let mut root = v_low - n_avg * (h / n_avg.z);
        root.z = self.ground_at(root.truncate());
        self.rising_from(tree, root, v_low, params)
    }

    /// A trunk standing on the ground at the stem column `xy`.
    fn column_trunk(&self, tree: &[Vec3], xy: Vec2, params: &Params) -> Vec<Vec3> {
        let root = xy.extend(self.ground_at(xy));
        self.rising_from(tree, root, root, params)
    }

    /// A trunk from `root` straight up to the crown's lowest layer above
    /// `through` (see [`rising_trunk`]), then on to v_c.
    fn rising_from(&self, tree: &[Vec3], root: Vec3, through: Vec3, params: &Params) -> Vec<Vec3> {
        let low = above(root, through, params.voxel_m);
        let crown_base = crown_base_z(tree, through, params.trunk_sphere_m);
        rising_trunk(root, low, crown_base, self.v_c, trunk_spacing(params))
    }

    /// Eq. 4: v_t = v_c − (v_c − g_b)/‖v_c − g_b‖·t between g_b and v_c,
    /// with g_b on the ground under [`lowest_layer_centre`].
    fn eq4_trunk(&self, tree: &[Vec3], params: &Params) -> Vec<Vec3> {
        let base_xy = lowest_layer_centre(tree, self.centre_xy);
        let g_b = base_xy.extend(self.ground_at(base_xy));
        line(
            g_b,
            above(g_b, self.v_c, params.voxel_m),
            trunk_spacing(params),
        )
    }
}

/// Eq. 3's test of the lowest point `v_low` (§5.3): a trunk hit when the
/// points around it run near vertical (λ1) and it lies near the footprint's
/// centre (λ2).
struct LowestPointTest {
    /// Angle of the points' mean direction around `v_low` to the vertical.
    lambda1_deg: f32,
    /// Horizontal distance of `v_low` from the footprint centre, over half
    /// the footprint's diagonal.
    lambda2: f32,
    /// The trunk direction `n_avg` when the test passes.
    direction: Option<Vec3>,
}

impl LowestPointTest {
    fn run(
        tree: &[Vec3],
        v_low: Vec3,
        centre_xy: Vec2,
        half_diagonal: f32,
        params: &Params,
    ) -> Self {
        // A lowest point without neighbours is an isolated trunk hit below
        // the crown (common at AHN densities); the paper's n_avg is
        // undefined there, and the trunk is taken as vertical (§5.3: trunks
        // grow nearly perpendicular to the ground).
        let measured = mean_direction(tree, v_low, params.trunk_sphere_m);
        let n_avg = measured.unwrap_or(Vec3::Z);
        let lambda2 = (v_low.truncate() - centre_xy).length() / half_diagonal;
        let lambda1_deg = n_avg.angle_between(Vec3::Z).to_degrees();
        // v_low can only be a trunk hit when it starts a column: at AHN
        // densities the lowest return is as often the tip of a low limb,
        // with other limbs' returns around it at the same height (λ1 and
        // λ2 alone accepted such a limb 1.8 m from the trunk on a
        // synthetic poplar).
        let column = starts_column(tree, v_low, params.trunk_sphere_m);
        // A lone return (no neighbour within r) cannot be a drooping limb's
        // tip among its foliage, the case the tighter λ2 limit guards
        // against, so the paper's own limit applies to it.
        let lambda2_limit = if measured.is_none() {
            LONE_HIT_LAMBDA2_MAX
        } else {
            params.lambda2_max
        };
        let passes = column
            && lambda1_deg <= params.lambda1_max_deg
            && lambda2 <= lambda2_limit
            && n_avg.z > 1e-3;
        Self {
            lambda1_deg,
            lambda2,
            direction: passes.then_some(n_avg),
        }
    }
}

/// Appends [`leader`]'s points towards the highest of `tree` to `trunk`
/// (root first, not empty) and returns the leader's top above the root.
fn extend_with_leader(
    trunk: &mut Vec<Vec3>,
    tree: &[Vec3],
    step_m: f32,
    voxel_m: f32,
) -> Option<f32> {
    let apex = tree
        .iter()
        .copied()
        .reduce(|a, p| if p.z > a.z { p } else { a })?;
    let rise = leader(trunk, apex, step_m, voxel_m);
    let top_m = rise.last().map(|top| top.z - trunk[0].z);
    trunk.extend(rise);
    top_m
}

/// Steepest lean from the vertical, in degrees, of a leader that
/// [`leader`] inserts: §5.3's trunks grow nearly upright, and a line to a
/// highest return farther out is a limb's, not a leader's (the synthetic
/// crowns' centroid-to-apex lines lean 3–20°).
const LEADER_MAX_LEAN_DEG: f32 = 30.0;

/// Points that continue `trunk` (root first, at least one point) in a
/// straight line to one voxel under the crown's highest return `apex`, at
/// `step_m` spacing, without the trunk's top itself; none when the line
/// would be shorter than a step or lean more than [`LEADER_MAX_LEAN_DEG`].
///
/// Not in Hu et al., whose §4.2 trunk ends at the crown centroid (see
/// [`Params::leader`]). Excurrent crowns (conifers, poplars, birches) carry
/// a leader from the trunk to the apex; a needle shell or leaf-on crown
/// returns nothing near it, and without these points Algorithm 2 carries
/// the main stem from limb to limb instead.
fn leader(trunk: &[Vec3], apex: Vec3, step_m: f32, voxel_m: f32) -> Vec<Vec3> {
    let Some(&from) = trunk.last() else {
        return Vec::new();
    };
    let to = apex - Vec3::Z * voxel_m;
    let rise = to - from;
    let lean_deg = rise.angle_between(Vec3::Z).to_degrees();
    if rise.z <= step_m || lean_deg > LEADER_MAX_LEAN_DEG {
        return Vec::new();
    }
    line(from, to, step_m).into_iter().skip(1).collect()
}

/// The trunk from `root` through `low` (its lowest hit or a step above the
/// root) to the crown centroid `v_c`. At AHN densities there are no further
/// trunk hits above `low`, so the trunk continues to the crown's centre of
/// mass as in Eq. 4; without it the skeleton would have to find its way up
/// through the empty space under the crown. It rises vertically to the
/// crown's lowest layer `crown_base` (§5.3: trunks grow nearly perpendicular
/// to the ground) and then follows the Eq. 4 line to the centroid.
fn rising_trunk(root: Vec3, low: Vec3, crown_base: f32, v_c: Vec3, spacing: f32) -> Vec<Vec3> {
    let mut points = line(root, low, spacing);
    let mut from = low;
    if crown_base > low.z + spacing && crown_base < v_c.z {
        let knee = Vec3::new(low.x, low.y, crown_base);
        points.extend(line(low, knee, spacing).into_iter().skip(1));
        from = knee;
    }
    if v_c.z > from.z + spacing {
        points.extend(line(from, v_c, spacing).into_iter().skip(1));
    }
    points
}

/// Heights above the ground of the stem band searched by [`stem_column`],
/// in metres: above the ground returns' noise, below most crowns' lowest
/// limbs.
const STEM_BAND_M: (f32, f32) = (0.3, 2.5);

/// Horizontal radius of a stem column around one of its returns, in metres:
/// returns lie on the bark all round a trunk, so the far side of a trunk up
/// to 0.8 m thick at its flared base is this far from a return on its near
/// side. (At 0.5 m, a poplar's two stem returns 0.63 m apart on opposite
/// sides of its trunk made no column, and the base fell back to Eq. 3 or 4.)
const STEM_COLUMN_RADIUS_M: f32 = 0.8;

/// Core radius of a stem column's isolation test, in metres: the returns
/// within it must outnumber those in the ring [`STEM_RING_M`] (see
/// [`stem_column`]). Tighter than the column, so that a low limb's spread of
/// returns does not pass for a thick stem.
const STEM_CORE_RADIUS_M: f32 = 0.5;

/// The ring around a candidate stem column whose band returns count
/// against it, inner and outer radius in metres (see [`stem_column`]). The
/// inner radius clears the far side of a flared trunk base up to 0.8 m
/// thick, seen from a return on its near side.
const STEM_RING_M: (f32, f32) = (0.8, 2.5);

/// The horizontal position of the stem, from the returns in the stem band
/// (0.3–2.5 m above the ground): the mean position of the best-isolated
/// column of band returns within [`STEM_COLUMN_RADIUS_M`] of one of them,
/// if it lies within §4.2's λ2 ≤ 0.5 of the footprint centre. One return
/// alone in the band makes a column: standing clear of the crown, it is
/// the stem seen once, whereas Eq. 3 would follow n_avg from it, tilted by
/// its neighbours higher up. (On a synthetic oak hit on its stem 1.8 and
/// 2.51 m up, the second just above the band, Eq. 3 put the base 0.78 m
/// from the truth; the lone band return puts it 0.25 m off. In
/// `silva eval --synthetic N --scan als` over seeds 1–300 leaf-off and
/// 1–100 leaf-on, 8 clips changed rule and no base offset of them grew;
/// the largest fell from 1.34 to 0.44 m.)
/// Not in the paper, whose v_low is the lowest return: when ground returns
/// are in the clip the lowest tree return is as often ground noise or a limb
/// tip, while a leaf-off (AHN) scan hits the stem below the crown a few
/// times. Only with a terrain: without one the band's ground level is
/// unknown (the lowest return of a segmented tree may be the bottom of its
/// crown).
///
/// A stem stands alone in the band, whereas the returns of a low limb that
/// arcs down into it continue along the limb. On 600 synthetic AHN-like
/// trees (`silva eval --synthetic 20 --scan als --seed S`, S = 1, 21, …,
/// 581) the largest group was a limb 5–7 m from the stem on six oaks: its
/// 0.5 m disk held 3–8 returns, the stem's 1–4, but returns continued in
/// the ring [`STEM_RING_M`] around the limb's group, where the stems' groups
/// had none or one. So a group needs more returns in its core
/// ([`STEM_CORE_RADIUS_M`]) than in its ring, and the groups rank by returns
/// in the core per return in the ring (plus one), times 1 − λ2 (their
/// distance from the footprint centre over the half diagonal): a drooping
/// limb's tip at the crown's edge can be as isolated as the stem. (On a
/// synthetic leaf-on oak, `--leaves on --seed 85`, a limb tip 5.7 m out
/// with two returns and one in its ring tied with a lone stem return
/// 0.7 m from the centre, and won on its count: base 5.79 m off, now
/// 0.39 m. No other base moved in `silva eval --synthetic N --scan als`
/// over seeds 1–300 leaf-off, 1–100 on a 15° slope and 1–100 and 301–400
/// leaf-on.) The column, whose mean
/// places the base, is wider than the core to gather both sides of a thick
/// stem; counted in the column, a limb's spread of returns 6 m from an
/// oak's stem passed the isolation test too.
fn stem_column(
    tree: &[Vec3],
    terrain: &Terrain,
    half_diagonal: f32,
    centre_xy: Vec2,
) -> Option<Vec2> {
    let band: Vec<Vec2> = tree
        .iter()
        .filter(|p| {
            let h = p.z - terrain.height_at(p.x, p.y);
            (STEM_BAND_M.0..=STEM_BAND_M.1).contains(&h)
        })
        .map(|p| p.truncate())
        .collect();
    let within = |c: Vec2, r: f32| band.iter().copied().filter(move |q| q.distance(c) <= r);
    let count_within = |c: Vec2, r: f32| within(c, r).count();
    let best = band
        .iter()
        .filter(|c| c.distance(centre_xy) <= LONE_HIT_LAMBDA2_MAX * half_diagonal)
        .map(|&c| {
            let group: Vec<Vec2> = within(c, STEM_COLUMN_RADIUS_M).collect();
            let core = count_within(c, STEM_CORE_RADIUS_M);
            let ring = count_within(c, STEM_RING_M.1) - count_within(c, STEM_RING_M.0);
            let lambda2 = c.distance(centre_xy) / half_diagonal;
            (group, core, ring, lambda2)
        })
        .filter(|(_, core, ring, _)| ring < core)
        .max_by(|(a, core_a, ring_a, l_a), (b, core_b, ring_b, l_b)| {
            let score = |n: usize, ring: usize, lambda2: f32| {
                n as f32 / (ring + 1) as f32 * (1.0 - lambda2)
            };
            score(*core_a, *ring_a, *l_a)
                .total_cmp(&score(*core_b, *ring_b, *l_b))
                .then(core_a.cmp(core_b))
                .then(a.len().cmp(&b.len()))
        })
        .map(|(group, ..)| group)?;
    Some(best.iter().copied().sum::<Vec2>() / best.len() as f32)
}

/// λ2 limit for a lowest point without neighbours: §4.2's 0.5.
const LONE_HIT_LAMBDA2_MAX: f32 = 0.5;

/// Side of the grid cells of [`footprint_centre`], in metres: at 10–30
/// returns per m² nearly every 0.5 m cell under a crown holds one.
const FOOTPRINT_CELL_M: f32 = 0.5;

/// Centre of the crown's ground footprint: the mean of the centres of the
/// grid cells that hold a tree point. §4.2 takes the centre of the
/// footprint's bounding box, g_b, which one far-reaching limb moves by half
/// its reach; the area centroid weighs each part of the crown by the ground
/// it covers, and unlike the points' centroid it does not lean toward the
/// side the scanner saw deepest.
///
/// Other centres measured against it (2026-12-06, `tools/als_top_and_base.py`
/// on the synthetic clips of `silva eval --synthetic 100 --scan als`, seeds
/// 1–100 and 101–200, whose trunks Eq. 4 placed: 34 and 36): bases within
/// 0.5 m of the truth 30 and 32 with the reconstruction; 33 and 31 with the
/// returns' mean, 30 and 31 their median, 31 and 31 the area centroid of
/// their convex hull, 11 and 7 the mean of the lowest tenth, 23 and 26 of
/// the highest, 6 and 6 the highest return. None is better on both. Those
/// that miss have no return 0.5–3.5 m up within 0.25 m of the bark (oaks
/// 21 and 29, birches 50 and 78): their base is a guess from the crown.
///
/// Nor did the point where the crown's limbs converge in plan do better
/// (2026-12-07, a Python prototype on the same clips, remade with `silva
/// synth --scan als`): each return whose 0.6 m neighbourhood has a
/// linearity of at least 0.2 and a direction at least 0.3 horizontal votes
/// for the 0.1 m cells its horizontal line passes within 0.3 m of, and the
/// cell with most votes is the base. Of the 18 oaks and birches of seeds
/// 1–200 whose trunk Eq. 4 placed, 11 had their base within 0.5 m by the
/// footprint centre and 9 by the vote. Over all 100 oak and birch clips,
/// whatever placed their trunk, the vote put 25 of the 50 oaks within
/// 0.5 m (the footprint centre 10) but 18 of the 50 birches (27): drooping
/// twigs do not point back to the stem. Neither the vote's peak against
/// its median nor the footprint centre's share of the peak told the cases
/// apart.
fn footprint_centre(tree: &[Vec3]) -> Vec2 {
    let cells: std::collections::HashSet<(i32, i32)> = tree
        .iter()
        .map(|p| {
            let c = (p.truncate() / FOOTPRINT_CELL_M).floor();
            (c.x as i32, c.y as i32)
        })
        .collect();
    let sum: Vec2 = cells
        .iter()
        .map(|&(i, j)| (Vec2::new(i as f32, j as f32) + 0.5) * FOOTPRINT_CELL_M)
        .sum();
    sum / cells.len().max(1) as f32
}

/// Share of the tree points, lowest first, that make up a crown's lowest
/// layer in [`lowest_layer_centre`].
const LOWEST_LAYER_SHARE: usize = 10;

/// Where Eq. 4's trunk base g_b goes when no return marks the stem: the
/// footprint centre `footprint_xy`, except under a columnar crown (spread
/// under [`COLUMNAR_SPREAD_M`]), where it is the mean position of the
/// lowest tenth of the returns. Not in the paper (§4.2 uses the footprint
/// for every crown): a leaf-on crown hides the stem, and a columnar crown's
/// short lowest limbs ring the trunk, so its lowest layer is centred on the
/// trunk, whereas its footprint follows the upper crown's sway (0.6–0.9 m
/// off on synthetic poplars whose lowest layer is 0.3–0.4 m off). A broad
/// crown's lowest layer is one or two long limbs on one side, metres off.
fn lowest_layer_centre(tree: &[Vec3], footprint_xy: Vec2) -> Vec2 {
    let (_, spread) = horizontal_spread(tree);
    if spread >= COLUMNAR_SPREAD_M || tree.len() < LOWEST_LAYER_SHARE {
        return footprint_xy;
    }
    let mut heights: Vec<f32> = tree.iter().map(|p| p.z).collect();
    let k = tree.len() / LOWEST_LAYER_SHARE;
    let (_, &mut top, _) = heights.select_nth_unstable_by(k, f32::total_cmp);
    let layer: Vec<Vec2> = tree
        .iter()
        .filter(|p| p.z <= top)
        .map(|p| p.truncate())
        .collect();
    layer.iter().copied().sum::<Vec2>() / layer.len().max(1) as f32
}

/// Whether the tree points less than `radius_m` above `v_low` all lie
/// within half of `radius_m` of it horizontally: a trunk seen from above is
/// a column of returns (or one return below the crown), whereas the lowest
/// layer of a crown spreads over metres.
fn starts_column(tree: &[Vec3], v_low: Vec3, radius_m: f32) -> bool {
    let reach = radius_m * 0.5;
    tree.iter()
        .filter(|p| p.z < v_low.z + radius_m)
        .all(|p| (p.truncate() - v_low.truncate()).length() <= reach)
}

/// Height of the crown's lowest layer: the lowest tree point outside the
/// column of `radius_m` / 2 around `v_low` (see [`starts_column`]).
fn crown_base_z(tree: &[Vec3], v_low: Vec3, radius_m: f32) -> f32 {
    let reach = radius_m * 0.5;
    tree.iter()
        .filter(|p| (p.truncate() - v_low.truncate()).length() > reach)
        .map(|p| p.z)
        .fold(f32::INFINITY, f32::min)
}

/// n_avg: the normalised mean of the unit directions from `v_low` to its
/// neighbours within `radius_m`; `None` without neighbours (or when the
/// directions cancel).
fn mean_direction(tree: &[Vec3], v_low: Vec3, radius_m: f32) -> Option<Vec3> {
    let index = PointIndex::new(tree);
    let sum: Vec3 = index
        .within(v_low, radius_m)
        .iter()
        .map(|n| tree[n.index] - v_low)
        .filter(|d| d.length_squared() > 1e-8)
        .map(Vec3::normalize)
        .sum();
    sum.try_normalize()
}

/// `top`, or a point one step straight above `base` when `top` is not at
/// least that high: the first trunk segment must point up for Algorithm 2's
/// bending angles to be defined.
fn above(base: Vec3, top: Vec3, step_m: f32) -> Vec3 {
    if top.z > base.z + step_m {
        top
    } else {
        base + Vec3::Z * step_m
    }
}

/// Points from `from` (included) to `to` (included) at about `step_m`
/// spacing; at least the two ends.
fn line(from: Vec3, to: Vec3, step_m: f32) -> Vec<Vec3> {
    let length = from.distance(to);
    let steps = ((length / step_m).ceil() as usize).clamp(1, 100_000);
    (0..=steps)
        .map(|s| from.lerp(to, s as f32 / steps as f32))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reconstruct::ground::fit_terrain;

    /// A ring of crown returns 6 m up, radius 3 m around the origin.
    fn crown() -> Vec<Vec3> {
        (0..60)
            .map(|k| {
                let a = k as f32 * 0.7;
                let z = 6.0 + (k % 7) as f32 * 0.5;
                Vec3::new(3.0 * a.cos(), 3.0 * a.sin(), z)
            })
            .collect()
    }

    #[test]
    fn a_return_below_the_crown_is_a_trunk_hit() {
        let mut tree = crown();
        tree.push(Vec3::new(0.2, -0.1, 1.0));
        let trunk = add_trunk(&tree, None, &Params::default());
        assert_eq!(trunk.rule, TrunkRule::FromLowestPoint);
        assert!(trunk.points[0].truncate().distance(Vec2::new(0.2, -0.1)) < 1e-3);
    }

    #[test]
    fn a_low_limb_among_others_is_not_a_trunk_hit() {
        let mut tree = crown();
        // The lowest return is a limb tip 1 m from the centreline, with
        // other limbs' returns beside it at the same height.
        // λ1 and λ2 alone accept it: its neighbour lies nearly above it.
        tree.push(Vec3::new(1.0, 0.0, 4.6));
        tree.push(Vec3::new(1.0, -0.2, 5.3));
        tree.push(Vec3::new(-1.0, 0.2, 4.9));
        tree.push(Vec3::new(0.1, 1.0, 5.0));
        let trunk = add_trunk(&tree, None, &Params::default());
        assert!(trunk.lambda1_deg <= 30.0 && trunk.lambda2 <= 0.25);
        assert_eq!(trunk.rule, TrunkRule::FromCrownCentre);
    }

    #[test]
    fn a_lone_return_off_centre_is_still_a_trunk_hit() {
        let mut tree = crown();
        // λ2 ≈ 0.36 (the half diagonal is about 4.3 m): over the tighter
        // limit for returns with neighbours, within §4.2's 0.5 for a lone one.
        tree.push(Vec3::new(1.5, 0.3, 1.0));
        let trunk = add_trunk(&tree, None, &Params::default());
        assert!(trunk.lambda2 > 0.25 && trunk.lambda2 <= 0.5);
        assert_eq!(trunk.rule, TrunkRule::FromLowestPoint);
    }

    #[test]
    fn stem_returns_under_the_crown_place_the_base_when_the_lowest_point_is_noise() {
        let mut tree = crown();
        // A leaf-off scan: three stem returns 1.2 m off the crown's centre,
        // and ground noise 0.2 m up under the crown's edge as the lowest
        // tree point (no column, so neither Eq. 3 nor the centre applies).
        tree.extend([
            Vec3::new(1.2, 0.5, 0.7),
            Vec3::new(1.1, 0.6, 1.4),
            Vec3::new(1.3, 0.4, 2.2),
            Vec3::new(-2.5, 1.0, 0.2),
            Vec3::new(-2.0, -1.5, 0.25),
        ]);
        // Flat ground at z = 0 around the tree.
        let ground: Vec<Vec3> = (-20..=20)
            .flat_map(|i| (-20..=20).map(move |j| Vec3::new(i as f32 * 0.4, j as f32 * 0.4, 0.0)))
            .collect();
        let terrain = fit_terrain(&ground).expect("flat ground");
        let trunk = add_trunk(&tree, Some(&terrain), &Params::default());
        assert_on_stem_returns(&trunk, Vec2::new(1.2, 0.5), 0.1);
        // Without a terrain the band has no ground level: not used.
        let terrain_free = add_trunk(&tree, None, &Params::default());
        assert_ne!(terrain_free.rule, TrunkRule::OnStemReturns);
    }

    #[test]
    fn one_stem_return_in_the_band_places_the_base_under_it() {
        // An oak-like stem seen twice, 1.8 m up in the stem band and 2.6 m
        // up just above it, on opposite sides of the stem. Eq. 3 from the
        // lower return would follow the tilted line between the two, 0.7 m
        // off at the ground.
        let mut tree = crown_ring(4.0, 4.5, 9);
        tree.extend([Vec3::new(0.15, 0.1, 1.8), Vec3::new(-0.2, -0.15, 2.6)]);
        let trunk = add_trunk(&tree, Some(&flat_terrain()), &Params::default());
        assert_on_stem_returns(&trunk, Vec2::new(0.15, 0.1), 0.05);
    }

    #[test]
    fn a_lone_stem_return_near_the_centre_outranks_a_limb_tip_at_the_edge() {
        // A leaf-on crown whose drooping limb ends 5 m out in the stem band
        // (two returns, a third of the limb 1.3 m on), and one stem return.
        // Both are as isolated (one core return per ring return plus one);
        // the stem lies near the footprint's centre.
        let mut tree = crown_ring(8.0, 4.0, 9);
        tree.extend([
            Vec3::new(0.3, 0.2, 0.5),
            Vec3::new(-3.0, -4.0, 1.4),
            Vec3::new(-3.2, -4.1, 1.7),
            Vec3::new(-3.8, -5.2, 2.4),
        ]);
        let trunk = add_trunk(&tree, Some(&flat_terrain()), &Params::default());
        assert_on_stem_returns(&trunk, Vec2::new(0.3, 0.2), 0.05);
    }

    /// Asserts that `trunk` stands on stem returns, its base on the ground
    /// within `tolerance_m` of `xy`.
    fn assert_on_stem_returns(trunk: &Trunk, xy: Vec2, tolerance_m: f32) {
        assert_eq!(trunk.rule, TrunkRule::OnStemReturns);
        let base = trunk.points[0];
        assert!(base.truncate().distance(xy) < tolerance_m, "base at {base}");
        assert!(base.z.abs() < 0.05, "base at {base}");
    }

    /// 200 crown returns on a cylinder of `radius` from `base_z` up, in
    /// `layers` layers 0.5 m apart.
    fn crown_ring(radius: f32, base_z: f32, layers: usize) -> Vec<Vec3> {
        (0..200)
            .map(|k| {
                let a = k as f32 * 0.7;
                let z = base_z + (k % layers) as f32 * 0.5;
                Vec3::new(radius * a.cos(), radius * a.sin(), z)
            })
            .collect()
    }

    /// Flat ground at z = 0, 20 m across.
    fn flat_terrain() -> Terrain {
        let ground: Vec<Vec3> = (-25..=25)
            .flat_map(|i| (-25..=25).map(move |j| Vec3::new(i as f32 * 0.4, j as f32 * 0.4, 0.0)))
            .collect();
        fit_terrain(&ground).expect("flat ground")
    }

    #[test]
    fn returns_on_opposite_sides_of_a_thick_stem_make_one_column() {
        // A poplar-like stem 0.64 m thick at 0.5 m, hit once on each side
        // (0.63 m apart), under a crown from 3 m; nothing else in the band.
        let mut tree = crown_ring(1.5, 3.0, 9);
        tree.extend([Vec3::new(-0.14, 0.31, 0.50), Vec3::new(0.31, -0.16, 0.54)]);
        let trunk = add_trunk(&tree, Some(&flat_terrain()), &Params::default());
        // Between the hits.
        assert_on_stem_returns(&trunk, Vec2::ZERO, 0.15);
    }

    #[test]
    fn a_low_limb_in_the_stem_band_does_not_outvote_a_lone_stem() {
        // A broad crown 8 m in radius whose stem shows two returns, and a
        // limb that arcs down into the stem band 4.5 m out: nine returns in
        // a line along it, five of them in any 0.5 m disk.
        let mut tree = crown_ring(8.0, 6.0, 7);
        tree.extend([Vec3::new(0.1, 0.0, 0.8), Vec3::new(-0.1, 0.1, 1.9)]);
        tree.extend((0..9).map(|i| Vec3::new(4.5, -1.0 + 0.25 * i as f32, 2.0)));
        let trunk = add_trunk(&tree, Some(&flat_terrain()), &Params::default());
        assert_on_stem_returns(&trunk, Vec2::ZERO, 0.2);
    }

    #[test]
    fn a_columnar_crown_stands_on_the_centre_of_its_lowest_layer() {
        // A poplar-like crown 1.2 m across: a ring of short limbs around
        // the origin 3–4 m up, and the upper crown swayed 0.8 m to +x.
        let mut tree: Vec<Vec3> = (0..20)
            .map(|k| {
                let a = k as f32 * 0.9;
                Vec3::new(0.6 * a.cos(), 0.6 * a.sin(), 3.0 + (k % 4) as f32 * 0.3)
            })
            .collect();
        tree.extend((0..180).map(|k| {
            let a = k as f32 * 0.7;
            let z = 5.0 + k as f32 * 0.08;
            Vec3::new(0.8 + 0.7 * a.cos(), 0.7 * a.sin(), z)
        }));
        let footprint = footprint_centre(&tree);
        assert!(footprint.length() > 0.5, "{footprint}");
        let trunk = add_trunk(&tree, None, &Params::default());
        assert_eq!(trunk.rule, TrunkRule::FromCrownCentre);
        let base = trunk.points[0].truncate();
        assert!(base.length() < 0.2, "{base}");
    }

    #[test]
    fn one_far_reaching_limb_barely_moves_the_footprint_centre() {
        // A full crown disc of radius 3 m, 6 m up. A limb reaching 4 m
        // beyond it moves the bounding box centre by 2 m; the footprint's
        // area centroid moves by a few decimetres.
        let mut tree: Vec<Vec3> = (-10..=10)
            .flat_map(|i| (-10..=10).map(move |j| Vec3::new(i as f32 * 0.3, j as f32 * 0.3, 6.0)))
            .filter(|p| p.truncate().length() <= 3.0)
            .collect();
        tree.extend((0..40).map(|k| Vec3::new(3.0 + k as f32 * 0.1, 0.0, 7.0)));
        let centre = footprint_centre(&tree);
        assert!(centre.length() < 0.6, "{centre}");
        let trunk = add_trunk(&tree, None, &Params::default());
        assert_eq!(trunk.rule, TrunkRule::FromCrownCentre);
        assert!(trunk.points[0].truncate().length() < 0.6);
    }

    #[test]
    fn the_leader_rises_from_the_trunk_top_to_a_voxel_under_the_apex() {
        let trunk = [Vec3::ZERO, Vec3::new(0.0, 0.0, 6.0)];
        let apex = Vec3::new(0.5, 0.0, 15.0);
        let rise = leader(&trunk, apex, 0.6, 0.2);
        let top = *rise.last().unwrap();
        assert!(top.distance(apex - Vec3::Z * 0.2) < 1e-5);
        assert!(rise.iter().all(|p| p.z > 6.0));
        let steps = rise.windows(2).map(|w| w[0].distance(w[1]));
        assert!(steps.into_iter().all(|d| d <= 0.6 + 1e-5));
    }

    #[test]
    fn a_highest_return_far_to_the_side_is_a_limb_not_a_leader() {
        let trunk = [Vec3::ZERO, Vec3::new(0.0, 0.0, 6.0)];
        assert!(leader(&trunk, Vec3::new(6.0, 0.0, 12.0), 0.6, 0.2).is_empty());
        assert!(leader(&trunk, Vec3::new(0.0, 0.0, 6.5), 0.6, 0.2).is_empty());
    }

    #[test]
    fn the_trunk_carries_a_leader_only_when_asked() {
        let mut tree = crown();
        tree.push(Vec3::new(0.2, 0.1, 12.0));
        let with = add_trunk(&tree, None, &Params::default());
        let top = with.points.last().unwrap();
        assert!(top.z > 11.0, "leader top {top}");
        assert!(with.note().contains("leader"));
        let params = Params {
            leader: false,
            ..Params::default()
        };
        let without = add_trunk(&tree, None, &params);
        assert!(without.points.last().unwrap().z < 10.0);
        assert!(!without.note().contains("leader"));
    }
}
