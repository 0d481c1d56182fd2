//! The dense pipeline for terrestrial and mobile scans, after AdTree
//! (Du et al. 2019, as summarised in lsystem-from-adtree-skeletons §2.1.1 and
//! multi-temporal-tree-growth §3.2.1).
//!
//! Steps:
//! 0. ground removal with [`super::ground::split_ground`]: a terrestrial
//!    plot scan usually holds the ground around the stem (LAS class 2, or
//!    found by the terrain fit); its points leave, and the trunk base is
//!    put on the terrain under the stem rather than at the lowest stem
//!    point left (up to [`super::ground::GROUND_TOLERANCE_M`] higher);
//! 1. clean-up with [`crate::cloud::clean::voxel_downsample`]: near-duplicate
//!    removal (more than `k` copies of a point would form an isolated clique
//!    in the graph) and, for huge clouds, voxel thinning to at most
//!    [`Params::max_points`], which bounds the graph's memory (about `2·k`
//!    edges per point);
//! 2. `graph`: a k-nearest-neighbour graph (in place of AdTree's 3D
//!    Delaunay graph), made connected by bridging components at their
//!    closest pairs (a large part too far to bridge is refused as a second
//!    tree), checks that the points stand upright on one stem
//!    (`check_one_stem`: two trees whose crowns touch are one graph, on two
//!    stems), and Dijkstra's shortest-path tree from the trunk base (every
//!    point of the lowest slice is a source, so the distance fronts start
//!    level instead of spreading from one bark point);
//! 3. `skeletonize`: cross-sections of equal geodesic distance collapse to
//!    skeleton nodes at branch centres (centroids; on thick one-sided
//!    sections, the centre of a fitted circle), with the arcs of one stem
//!    section that ragged distance fronts split joined again, and the
//!    pieces of a thick stem's ring joined through paths in the
//!    neighbouring bins ([`Params::ring_window_bins`]), except the points
//!    that lie well outside the circle fitted to the ring, a twig running
//!    along the bark ([`Params::ring_outlier_m`]); and, through
//!    `fork_rings`, a section that holds both stems of a narrow fork split
//!    in two when two circles fit it much better than one
//!    ([`Params::split_two_stems`]);
//! 4. `simplify`: near-duplicate children merged, noisy branches dropped
//!    (shorter than a few bins by subtree length; on thick stems, spurs
//!    from the axis out to a piece of the stem's own bark; strands that
//!    run within a bin of a heavier branch from the same fork; or, when
//!    enabled, bark patches that never leave their stem), detours of a
//!    thick stem's chain through a piece of its bark dropped, thick stems
//!    smoothed (and, when enabled, thin chains with Taubin's λ|μ filter
//!    within their sections' reach), Douglas–Peucker along chains,
//!    main extension first;
//! 5. `lateral_base`: laterals of thick stems extended back along their
//!    initial direction to the stem's axis, where the truth (and a QSM)
//!    starts them, rather than joined across the wood from the bark;
//! 6. `twins`: a twig that the stem reached more than once (pieces along
//!    the bark, each joined across the wood) joined to the stem once, its
//!    other pieces hanging from their twins;
//! 7. `stem_axis`: the trunk tracked up and down the main stem by circles
//!    fitted to slices half a metre tall, from a seed fit low on the stem,
//!    and its nodes moved onto their centres: a sparse one-sided trunk's
//!    sections are too thin for a circle, and their centroids lie towards
//!    the scanner; then the thick laterals of the tracked nodes (and
//!    theirs) tracked the same way, each under 0.8 of its fork's radius
//!    (`stem_axis::recentre_limbs`): a limb seen from a few sides leaves
//!    parallel chains on its bark;
//! 8. `tips`: each tip moved from its last section's centroid to the
//!    scan's last point ahead of it, and each twig on by the median gap
//!    between a twig's last scanned point and its end;
//! 9. the laterals of the tracked stem's nodes that never leave its fitted
//!    bark dropped (`simplify::bark_spurs`), and the chains along the
//!    tracked trunk's or a tracked limb's bark (`simplify::bark_strands`);
//! 10. the root, the tree's georeferenced position, moved onto the centre
//!     of a circle fitted to the trunk's foot (`foot_circle`), when one
//!     fits: the centroid of the lowest slice lies towards the scanners.
//!
//! Radii are not set here: the shared stage in [`super::radii`] does that
//! for both pipelines. The skeleton's radii on the way are the sections'
//! spreads, and on the tracked trunk and limbs the fitted circles' radii
//! (step 7).
//! The skeleton handed over keeps only the fitted circles' radii (0
//! elsewhere): the radius stage reads them as the stem's wood and its
//! measured radii.

use glam::Vec3;

use super::ground::{GroundMethod, Terrain, split_ground};
use super::radii::{
    MAX_TRUNK_RADIUS_M, MIN_TRUNK_SECTORS, circle_rms, robust_circle, trunk_sectors_seen,
};
use super::{ReconstructError, parts};
use crate::cloud::PointCloud;
use crate::cloud::clean::{occupied_voxels, voxel_downsample};
use crate::interrupt::Interrupt;
use crate::skeleton::{Anchor, NodeId, Skeleton};
use crate::spatial::PointIndex;

mod fork_rings;
mod graph;
mod lateral_base;
mod simplify;
mod skeletonize;
mod stem_axis;
mod tips;
mod twins;

pub(crate) use graph::UnionFind;
pub(crate) use simplify::point_segment_distance;

/// Bark points closer than this many point spacings belong to one piece of
/// bark in the upside-down test ([`super::upright`]).
const STEM_LINK_SPACINGS: f32 = 4.0;

/// Heights of the slices at the trunk's foot whose circle places the root
/// ([`foot_circle`]), in metres, tried in turn: 10 cm stays under the root
/// flare's buttresses and the first branches; a sparse scan rings the stem
/// only in a taller slice (at 30 points/m², `silva eval --synthetic 20
/// --scan tls --density 30 --mode dense`, no 10 cm slice held a circle; with
/// the taller ones the root's median offset from the true base went 0.136
/// -> 0.007 m).
const FOOT_SLICES_M: [f32; 3] = [0.1, 0.3, 0.5];

/// Fewest inliers of the foot's circle ([`foot_circle`]): as for a
/// section's circle fit in [`skeletonize`].
const MIN_FOOT_INLIERS: usize = 12;

/// Largest RMS distance of the foot circle's inliers from it, as a share
/// of its radius.
const MAX_FOOT_RMS_SHARE: f32 = 0.1;

/// Settings of the dense pipeline. Lengths left `None` scale with the
/// cloud's median point spacing.
#[derive(Debug, Clone, PartialEq)]
pub struct Params {
    /// Neighbours per point in the graph.
    pub neighbours: usize,
    /// Clouds with more points (after de-duplication) are thinned on a voxel
    /// grid to at most this many; it bounds the graph's memory.
    pub max_points: usize,
    /// Points closer than this are duplicates, in metres.
    pub duplicate_m: f32,
    /// Width of the geodesic-distance bins that become cross-sections;
    /// `None`: [`Params::bin_spacings`] × the median point spacing.
    pub bin_width_m: Option<f32>,
    /// Automatic bin width in multiples of the median point spacing.
    pub bin_spacings: f32,
    /// Range the automatic bin width is clamped to, in metres.
    pub bin_range_m: (f32, f32),
    /// Graph links longer than this many median point spacings are cut: the
    /// pieces they joined are joined again by one bridge at their closest
    /// pair (see `connect`), and isolated outliers fall away as specks.
    ///
    /// In a sparsely hit crown a twig's `k` nearest neighbours reach across
    /// to the next twig, and shortest paths hop between twigs along such
    /// links; the skeleton then draws internodes through the air. Measured
    /// (release build, `silva eval`, 20 → 10, with
    /// [`Params::speck_reach_spacings`] keeping the old reach for specks):
    /// default occluded TLS (`--synthetic 20`) median precision 0.860 →
    /// 0.919, recall 0.862 → 0.853 (birches +8–10 points of precision and
    /// +1–2 of recall, pines +5–7 of precision, oaks +0.3–2; poplars lose
    /// 0.5–1.5 points of precision and 1–2 of recall); clean TLS
    /// (`--synthetic 20 --density 1000 --no-occlusion`) median recall
    /// 0.9967 → 0.9966, precision 0.9943 → 0.9952, 15 of 20 meeting both
    /// 0.99 as before; tree1 within 2 cm / 5 cm / supported 82.4 / 97.5 /
    /// 89.1 → 82.7 / 97.6 / 91.3 %, tree13 69.5 / 90.5 / 37.9 → 70.2 /
    /// 90.8 / 40.1 %; times unchanged.
    pub max_edge_spacings: f32,
    /// Lateral branches shorter than this many bin widths are noise.
    pub min_branch_bins: f32,
    /// Join cross-sections of one bin whose extents overlap (arcs of a
    /// thick stem that ragged distance fronts split).
    pub merge_overlapping_arcs: bool,
    /// A thick stem's cross-section is a thin band around the bark that the
    /// nearest-neighbour edges inside it leave in pieces; pieces joined by
    /// edges through this many neighbouring bins are one section when
    /// together they are a thick stem's ring (0: never join).
    pub ring_window_bins: u32,
    /// The RMS spread from its centroid, in metres, above which a joined
    /// section counts as a thick stem's ring.
    pub ring_spread_m: f32,
    /// A joined section that the bin alone splits into at least this many
    /// pieces is a broken ring as well (a limb thinner than
    /// [`Params::ring_spread_m`] seen in pieces)…
    ///
    /// Fewer pieces let the window join the arcs of more limbs (for the two
    /// sides of limbs of 2–10 cm radius, see [`Params::strand_reach_bins`])
    /// but cost the real trees' fit
    /// (2026-12-06, release, `DATA=/work/shared/data cargo run --release
    /// --example dense_sweep -- broken_ring_pieces 3 2`; 4 as in the
    /// figures there): on the 20 clean scans median precision 0.9963 →
    /// 0.9968 / 0.9967 and mean skeleton distance 18.1 → 17.5 / 17.6 mm,
    /// recall 0.9963 → 0.9962 / 0.9961, 15 of 20 meeting both 0.99, branch
    /// count / true 1.88 → 1.83 / 1.91; tree1 within 2 cm 83.7 → 80.2 /
    /// 76.6 %, within 5 cm 97.7 → 96.1 / 94.2 %; tree13 within 2 cm 70.6 →
    /// 70.3 / 67.1 %. Not for want of radii: with every internode's radius
    /// set to the median distance of its nearest points (`BROKEN_PIECES=3
    /// cargo run --release --example fit_breakdown -- tree1.xyz`), tree1
    /// reaches 86.1 % within 2 cm at 3 pieces and 88.6 % at 4: the loss
    /// lies in the skeleton the joined sections make, not in its radii.
    pub broken_ring_pieces: u32,
    /// …when its RMS spread reaches this, in metres. Lowered to 0.03 or
    /// 0.02 m with 4 pieces, nothing changes on the 20 clean scans or the
    /// real trees (the same sweep).
    pub broken_ring_spread_m: f32,
    /// Points of a thick ring more than this far outside the circle fitted
    /// to it (across the stem's axis) are a twig running along the bark and
    /// form their own cross-section (0: off).
    ///
    /// It finds twigs that hug a poplar's trunk. Groups of outside points
    /// that no later section grows from go back into the ring: at a fork
    /// they are pieces of the crotch or of a limb's first arc, and kept
    /// apart they were stubs out of the stem (a third tip on the Y-tree of
    /// `tests/reconstruct_dense.rs`, up to 0.2 points of precision on the
    /// oaks). Clean synthetic TLS scans (`silva eval --synthetic 20 --scan
    /// tls --density 1000 --no-occlusion`), 0 → 0.02 m: recall of the five
    /// poplars s3 95.0 → 95.8 %, s7 95.9 → 96.9 %, s11 96.7 → 97.9 %, s15
    /// 95.6 → 97.1 %, s19 97.3 → 97.9 %; precision of no tree down by more
    /// than 0.1 points; the occluded default TLS scans and the real trees
    /// hardly change.
    pub ring_outlier_m: f32,
    /// Graph edges longer than this many median point spacings do not join
    /// the points of a bin into one cross-section: in a sparsely sampled
    /// crown the `k` nearest neighbours reach across to the next twig, and
    /// a section holding both would put the node between them, off both.
    ///
    /// Longer links cost the real trees' fit as the wider strand rule does
    /// ([`Params::strand_reach_bins`]; 2026-12-06, release,
    /// `DATA=/work/shared/data cargo run --release --example dense_sweep --
    /// section_link_spacings 4 5`, against 3): on the 20 clean scans median
    /// recall 0.9963 → 0.9965 / 0.9966, precision 0.9963 → 0.9959 / 0.9961,
    /// branch count / true 1.88 → 1.88 / 1.85, 15 of 20 meeting both 0.99
    /// throughout; tree1 within 2 cm 83.7 → 81.9 / 80.9 %, tree13 70.6 →
    /// 68.5 / 66.3 %.
    pub section_link_spacings: f32,
    /// The same limit for the edges that join a thick stem's ring through
    /// the neighbouring bins ([`Params::ring_window_bins`]); a ring's band
    /// needs longer links than a single bin, whose pieces the window joins.
    pub ring_link_spacings: f32,
    /// Move thick sections' nodes to the centre of a circle fitted to their
    /// points (one-sided scans see arcs whose centroid is off the axis).
    pub centre_arcs: bool,
    /// Lateral subtrees that stay within this many cross-section spreads of
    /// the stem they leave are bark patches, not branches (0 keeps them).
    /// Off by default: with [`Params::ring_window_bins`] thick stems come out
    /// as whole rings, so bark patches no longer arise, and the rule cut
    /// real branches that hug their stem (poplars).
    pub stem_stub_spreads: f32,
    /// Laterals of forks whose cross-section spread reaches this many bin
    /// widths (a thick stem) are spurs out to a piece of the stem's own bark
    /// when they never get farther from the fork than that spread plus
    /// [`Params::spur_reach_bins`] bin widths (infinite: off, and with it
    /// the same rule on the tracked stem's fitted circles, step 9).
    ///
    /// Clean synthetic TLS scans (`silva eval --synthetic 8 --scan tls
    /// --density 1000 --no-occlusion`): median precision 97.7 → 99.0 %,
    /// median recall 99.2 → 99.1 % (the poplars lose 0.9–1.1 points of
    /// recall: short real twigs near their trunks go too).
    pub spur_spread_bins: f32,
    /// See [`Params::spur_spread_bins`].
    pub spur_reach_bins: f32,
    /// Laterals that never get farther than this many bin widths from a
    /// heavier branch of the fork they leave (its main extension, or a
    /// heavier lateral) are strands of that branch and are dropped (0:
    /// off). On a thin twig a bin holds a point or two per side, the sides
    /// are not always linked, and they become two chains a twig's width
    /// apart: one branch counted twice, with twice its length.
    ///
    /// Synthetic TLS scans (`silva eval --synthetic 20 --scan tls`), 0 → 1:
    /// median branch length / true 1.42 → 1.23, branch count / true 3.32 →
    /// 2.39, recall 0.8527 → 0.8512; precision 0.9268 → 0.9132, because the
    /// length dropped lay within the tolerance (the length farther than
    /// 10 cm from the truth is per tree 0.95–1.00 times what it was). Clean
    /// (`--density 1000 --no-occlusion`): length 1.49 → 1.11, count 4.61 →
    /// 1.96, precision 0.9960 → 0.9949, 15 of 20 trees meeting recall and
    /// precision ≥ 0.99 as before. tree1 within 2 cm 83.9 → 83.4 %, tree13
    /// 70.4 → 69.8 %. At 2 bin widths (main extension only) the length
    /// falls to 1.15 but tree13 loses 4 points within 2 cm.
    ///
    /// Re-measured at 1 / 1.5 / 2 / 3 bin widths (2026-12-06, release,
    /// `DATA=/work/shared/data cargo run --release --example dense_sweep --
    /// strand_reach_bins 1 1.5 2 3`). The 20 clean scans: median recall
    /// 0.9963 / 0.9963 / 0.9962 / 0.9959, precision 0.9963 / 0.9962 / 0.9962
    /// / 0.9960, branch count / true 1.88 / 1.78 / 1.64 / 1.35, 15 of 20
    /// meeting both 0.99 at every value. tree1 within 2 cm 83.7 / 82.6 /
    /// 81.5 / 78.0 %, tree13 70.6 / 66.9 / 65.1 / 60.7 %; tree13's LsJSON
    /// 63.1 / 57.8 / 53.9 / 48.3 KB. The occluded scans (`OCCLUDED=1`) at
    /// 1 → 2: recall 0.8424 → 0.8401, precision 0.9506 → 0.9477, branch
    /// count 1.89 → 1.43.
    ///
    /// Most of the extra branches at 1 are second chains along limbs of 2–10 cm
    /// radius. On the clean oak s1 (`silva synth --species oak --seed 1 --scan
    /// tls --density 1000 --no-occlusion`; 2,608 branches against the truth's
    /// 529), `tools/dense_strands.py` finds 1,642 laterals shorter than 0.5 m
    /// (345 m) on the true branch they fork from: 929 on wood of 2–5 cm radius,
    /// their tips a median 4.6 cm off its axis, and 423 on 5–10 cm wood, 8.0 cm
    /// off: together 1,352 of the 2,079 extra branches. As on the thin twigs
    /// above, the two sides of such a limb became two chains (seen on printed
    /// examples; the sectioning was not traced). A trial (not kept) that moved
    /// the branch's nodes halfway to the strands dropped at 2 won back part of
    /// the fit (tree1 83.1 %, tree13 67.3 %), but on the occluded scans recall
    /// still fell to 0.8405 and precision to 0.9484 (against 0.8430 and 0.9512
    /// at 1; these four medians taken as the upper of the two middle values,
    /// the sweep's figures above as their mean). So the value stays 1. The fix
    /// left to try is to join the two sides into one section before the chains
    /// form.
    ///
    /// On the same oak, the main chains of those limbs are off-centre too:
    /// on 2–5 cm wood, the first few nodes past each fork of the 1,047 short
    /// laterals lie a median 0.76 of the true radius off the axis, the
    /// lateral's nodes 1.03 (on the bark), 473 of the laterals on the
    /// opposite side (offsets more than 120° apart; a Python reading of the
    /// reconstruction against the truth). Two more trials, measured and not
    /// kept (2026-12-06, release):
    /// - a reach of twice the heavier branch's cross-section spread where
    ///   larger than the bin widths: clean scans branch count 1.88 → 1.51,
    ///   precision 0.9963 → 0.9979, recall 0.9963 → 0.9948; tree1 within
    ///   2 / 5 cm 83.7 / 97.7 → 74.4 / 90.9 %, below AdTree's 96.2 % at 5 cm;
    /// - each interior node of a chain the stem tracking left alone moved to
    ///   the centre of a circle fitted to the points in a slab one bin thick
    ///   and 10 cm across it (Kåsa; RMS under 0.15 of the radius, 6 of 12
    ///   sectors, radius under 10 cm), given the circle's radius, and then
    ///   the chains within those radii of the centred axes dropped as those
    ///   along the tracked stems' bark are (`simplify::bark_strands`):
    ///   clean scans branch count 1.88 → 1.81, mean skeleton distance 18.1
    ///   → 17.0 mm, precision 0.9963 → 0.9971, but the poplars s7 and s11
    ///   fell from recall 0.978 / 0.979 to 0.948 / 0.942 (their twigs run
    ///   beside their branches, inside the circles), and volume / true 1.07
    ///   → 1.12. The circles alone, with no strand dropped, moved tree1's
    ///   within 2 cm by −0.1 to −0.8 points (stricter or looser acceptance)
    ///   and left tree13, whose slabs hold too few points, unchanged.
    pub strand_reach_bins: f32,
    /// A short run of sections (at most [`Params::detour_max_nodes`])
    /// between two thick stem rings (spread of at least
    /// [`Params::spur_spread_bins`] bin widths) is the main chain detouring
    /// through a piece of the stem's bark, and is dropped, when each section
    /// is thinner than this share of the rings' spread (0: off)…
    ///
    /// Clean synthetic TLS scans (`silva eval --synthetic 8 --scan tls
    /// --density 1000 --no-occlusion`): skeleton within 2 cm of the true
    /// axis on poplar s3 70.8 → 84.7 %, s7 78.7 → 82.4 %, oak s1 79.5 →
    /// 83.3 %; median precision 99.0 → 99.2 %, median recall 99.1 % (the
    /// poplars lose 0.2–0.4 points).
    pub detour_thin_share: f32,
    /// …and lies at least this share of the rings' spread off their axis.
    pub detour_off_axis_share: f32,
    /// See [`Params::detour_thin_share`].
    pub detour_max_nodes: usize,
    /// Laterals of forks whose cross-section spread reaches this many bin
    /// widths (a thick stem) start on the stem's axis: each is extended back
    /// along its initial direction to the axis (see `lateral_base`;
    /// infinite: off).
    pub lateral_base_spread_bins: f32,
    /// A lateral's initial direction is fitted over this many stem spreads
    /// of its chain…
    pub lateral_direction_spreads: f32,
    /// …but over at least this many bin widths.
    pub lateral_direction_bins: f32,
    /// A lateral's base moves down the stem at most this many stem spreads
    /// below the fork it left (0: only along the fork's own internode).
    pub lateral_max_drop_spreads: f32,
    /// A lateral's base moves only when the line back along its initial
    /// direction passes the stem's axis within this many stem spreads.
    pub lateral_miss_spreads: f32,
    /// A lateral of a thick stem whose join turns into it (see `twins`)
    /// hangs from the nearest thin node of another branch within this many
    /// bin widths of its first node instead (0: off)…
    pub twin_gap_bins: f32,
    /// …when its join turns by at least this angle, in degrees.
    pub twin_min_turn_deg: f32,
    /// The trunk is tracked up and down the main stem by circles fitted to
    /// the points this far (metres) above and below each node, and its
    /// nodes moved onto their centres (see `stem_axis`; 0: off)…
    pub stem_half_slice_m: f32,
    /// …across the stem's direction between the chain's nodes this far
    /// (metres) below and above it…
    pub stem_axis_window_m: f32,
    /// …taking points within this distance (metres) of the node across
    /// the stem (the largest trunk radius looked for)…
    pub stem_reach_m: f32,
    /// …when at least this many of them lie on the circle…
    pub stem_min_points: usize,
    /// …starting from the first fit within [`Params::stem_seed_height_m`]
    /// of the root with at least this many…
    pub stem_seed_points: usize,
    /// …(metres above the root)…
    pub stem_seed_height_m: f32,
    /// …for as long as the fitted radius changes by at most this share
    /// from one tracked node to the next…
    pub stem_max_change: f32,
    /// …and fading the move out over this length of stem (metres) beyond.
    pub stem_fade_m: f32,
    /// The tracked stem's laterals are tracked in turn, with the same
    /// slices, where their circles stay at most this share of their fork's
    /// fitted radius (see `stem_axis::recentre_limbs`; 0: off)…
    pub limb_max_share: f32,
    /// …seeded at a node within this distance (metres) of the fork…
    pub limb_seed_reach_m: f32,
    /// …when they carry at least this much branch length (metres), on
    /// forks where the share allows circles of this radius (metres).
    pub limb_min_subtree_m: f32,
    /// See [`Params::limb_min_subtree_m`].
    ///
    /// Lowering it does not reach the thin limbs: at 0.08, 0.05 and 0.03 m
    /// (`DATA=/work/shared/data cargo run --release --example dense_sweep --
    /// limb_min_radius_m 0.08 0.05 0.03`, 2026-12-06) every figure of the
    /// clean synthetic scans and of tree1 and tree13 came out the same.
    pub limb_min_radius_m: f32,
    /// Split cross-sections that hold both stems of a narrow fork (see
    /// `fork_rings`)…
    pub split_two_stems: bool,
    /// …when they spread at least this many bin widths (RMS)…
    pub two_stem_spread_bins: f32,
    /// …and two circles fit their points with at most this share of one
    /// circle's mean deviation.
    pub two_stem_deviation_share: f32,
    /// Rounds of smoothing along thick chains (cross-section spread of at
    /// least two bin widths) before simplification.
    pub smoothing_rounds: usize,
    /// Taubin λ|μ step pairs along thin chains (cross-section spread below
    /// two bin widths) before simplification, see
    /// `simplify::smooth_thin_chains` (0: off). Their nodes are centroids of
    /// a handful of points and zigzag; smoothed, Douglas–Peucker drops more
    /// of them and the chain code needs fewer corrections.
    ///
    /// Off by default: on real scans it costs fit for a small saving. With
    /// 10 rounds (release build, chain code at the voxel size of the
    /// unsmoothed skeleton's r = 5): tree1 5,188 → 4,635 B, points within
    /// 2 cm of the cylinders 81.4 → 78.5 %; tree13 8,072 → 7,940 B, 67.3 →
    /// 65.3 %. Bytes per internode stay at 2.0–2.1: half or more of the
    /// corrections are the first internodes of laterals, which smoothing
    /// cannot predict (docs/chaincode.md §9).
    pub thin_smoothing_rounds: usize,
    /// A thin node moves at most its cross-section spread, or this many bin
    /// widths if more, from its section's centroid.
    pub thin_smoothing_reach_bins: f32,
    /// Move each tip from the centroid of its last cross-section to the
    /// scan's last point ahead of it (see `tips`).
    ///
    /// Measured (release build, one session, `silva eval`): tree1 within
    /// 2 cm of the cylinders 80.9 → 82.3 %, tree13 67.6 → 69.1 %; clean
    /// synthetic TLS (`--synthetic 20 --density 1000 --no-occlusion`) median
    /// recall 99.22 → 99.26 %, precision 99.34 → 99.36 %; default TLS
    /// (`--synthetic 12`) median recall 83.05 → 83.19 %, precision 84.48 →
    /// 84.40 % (thick tips on occluded poplars and pines lose up to 0.6
    /// points of precision).
    pub tips_reach_last_points: bool,
    /// Extend each thin tip beyond its last point by the median gap between
    /// a twig's last scanned point and its end, ln 2 / λ for λ points per
    /// metre (see `tips`).
    ///
    /// Measured (release build, one session, `silva eval`, against the same
    /// build with it off): clean synthetic TLS (`--synthetic 20 --density
    /// 1000 --no-occlusion`) median recall 99.26 → 99.64 %, precision 99.36
    /// → 99.40 %, both ≥ 99 % on 13 of 20 trees (12); default TLS
    /// (`--synthetic 12`) median recall 83.2 → 86.8 %, precision 84.4 →
    /// 85.7 %, mean skeleton distance 5.6 → 5.2 cm, every tree better in
    /// both; tree1 within 2 cm 82.3 → 82.2 %, tree13 69.1 → 69.6 %, its
    /// supported surface 36.0 → 38.0 %. The volume ratios to the truth
    /// barely move (default TLS median 1.18 → 1.17, largest 1.45 → 1.48).
    pub tips_expected_gap: bool,
    /// Douglas–Peucker tolerance in cross-section spreads, where larger than
    /// [`Params::simplify_bins`]: thick stems' centroids jitter more.
    pub simplify_spreads: f32,
    /// Douglas–Peucker tolerance, in bin widths.
    pub simplify_bins: f32,
    /// Components with fewer points are specks: dropped as isolated noise
    /// when farther than [`Params::speck_reach_spacings`] from the rest…
    pub min_component_points: usize,
    /// …median point spacings (bridged like larger pieces when nearer). This
    /// is the reach of the graph's links before they were cut at
    /// [`Params::max_edge_spacings`] = 10: a speck the longer links joined
    /// to the tree still joins it, one they left out is still dropped.
    pub speck_reach_spacings: f32,
    /// Components farther than this from the tree are not bridged, in metres.
    pub max_gap_m: f32,
    /// A far component with at least this share of the points is a second
    /// tree or object: an error rather than a silent drop.
    pub detached_share: f32,
}

impl Default for Params {
    fn default() -> Self {
        Self {
            neighbours: 10,
            max_points: 250_000,
            duplicate_m: 0.002,
            bin_width_m: None,
            bin_spacings: 0.6,
            bin_range_m: (0.03, 0.5),
            max_edge_spacings: 10.0,
            min_branch_bins: 3.0,
            merge_overlapping_arcs: true,
            ring_window_bins: 1,
            ring_spread_m: 0.11,
            broken_ring_pieces: 4,
            broken_ring_spread_m: 0.04,
            ring_outlier_m: 0.02,
            section_link_spacings: 3.0,
            ring_link_spacings: 4.0,
            centre_arcs: true,
            stem_stub_spreads: 0.0,
            spur_spread_bins: 4.0,
            spur_reach_bins: 1.5,
            strand_reach_bins: 1.0,
            detour_thin_share: 0.5,
            detour_off_axis_share: 0.5,
            detour_max_nodes: 2,
            lateral_base_spread_bins: 4.0,
            lateral_direction_spreads: 1.0,
            lateral_direction_bins: 4.0,
            lateral_max_drop_spreads: 4.0,
            lateral_miss_spreads: 1.0,
            twin_gap_bins: 3.0,
            stem_half_slice_m: 0.25,
            stem_axis_window_m: 1.0,
            stem_reach_m: 0.6,
            stem_min_points: 20,
            stem_seed_points: 30,
            stem_seed_height_m: 2.5,
            stem_max_change: 0.3,
            stem_fade_m: 1.0,
            limb_max_share: 0.8,
            limb_seed_reach_m: 1.0,
            limb_min_subtree_m: 2.0,
            limb_min_radius_m: 0.08,
            twin_min_turn_deg: 30.0,
            split_two_stems: true,
            two_stem_spread_bins: 2.0,
            two_stem_deviation_share: 0.5,
            smoothing_rounds: 3,
            thin_smoothing_rounds: 0,
            thin_smoothing_reach_bins: 1.0,
            tips_reach_last_points: true,
            tips_expected_gap: true,
            simplify_spreads: 0.25,
            simplify_bins: 0.3,
            min_component_points: 5,
            speck_reach_spacings: 20.0,
            max_gap_m: 1.0,
            detached_share: 0.1,
        }
    }
}

/// Each stem of a split section has at least this many points (see
/// `fork_rings`).
const TWO_STEM_MIN_POINTS: usize = 12;

/// The twin a lateral moves to lies within this share of its join's length
/// (see `twins`).
const TWIN_GAP_SHARE: f32 = 0.5;

/// The dense pipeline's result, before radii.
#[derive(Debug, Clone)]
pub struct DenseOutput {
    /// The skeleton, its radii those of the circles fitted to the tracked
    /// trunk, 0 elsewhere (module docs); its anchor is the absolute trunk
    /// base.
    pub skeleton: Skeleton,
    /// The points the skeleton was built from (cleaned, without ground),
    /// relative to the skeleton's anchor: `cloud.offset == anchor.origin`.
    pub cloud: PointCloud,
    /// Best efforts worth reporting (thinning, dropped or bridged parts).
    pub notes: Vec<String>,
    /// The bin width used, in metres.
    pub bin_width_m: f32,
}

/// Builds the skeleton of the one tree in `cloud` (radii provisional),
/// checking `interrupt` before each step. The steps are those of the
/// module documentation, one function each.
pub fn reconstruct(
    cloud: &PointCloud,
    params: &Params,
    interrupt: &Interrupt,
) -> Result<DenseOutput, ReconstructError> {
    interrupt.check("clean-up")?;
    let mut notes = Vec::new();
    let (points, ground) = cleaned_points(cloud, params, &mut notes)?;
    let mut graph = neighbour_graph(points, cloud.offset, &ground, params, interrupt, &mut notes)?;
    let (sources, root, foot) = trunk_base(
        &graph.points,
        &graph.foot,
        graph.bin_m,
        ground.terrain.as_ref(),
    );
    let sections = cross_sections(&mut graph, &sources, root, params, interrupt)?;
    // Express everything relative to the trunk base: the anchor carries the
    // absolute position in f64, so the georeference stays exact.
    let origin = cloud.offset + root.as_dvec3();
    let mut nodes = sections.nodes;
    for node in &mut nodes {
        node.position -= root;
    }
    interrupt.check("simplification")?;
    let nodes = simplify::merge_close_siblings(nodes, sections.counts, graph.bin_m);
    let skeleton = Skeleton::from_nodes(Anchor::at(origin), nodes)
        .map_err(|e| ReconstructError::Degenerate(format!("internal skeleton error: {e}")))?;
    let skeleton = simplified(skeleton, graph.bin_m, params);
    let mut skeleton = refined(skeleton, graph.bin_m, params, interrupt)?;
    interrupt.check("stem axis")?;
    let tree_points: Vec<Vec3> = graph.points.iter().map(|&p| p - root).collect();
    let index = PointIndex::new(&tree_points);
    let mut tracked = recentre_stem(&mut skeleton, &tree_points, &index, graph.bin_m, params);
    let limbs = recentre_limbs(
        &mut skeleton,
        &tree_points,
        &index,
        &tracked,
        graph.bin_m,
        params,
    );
    tracked.extend(limbs);
    interrupt.check("tip placement")?;
    if params.tips_reach_last_points || params.tips_expected_gap {
        let rule = tips::TipRule {
            bin_m: graph.bin_m,
            reach_last_points: params.tips_reach_last_points,
            expected_gap: params.tips_expected_gap,
        };
        tips::place_tips(&mut skeleton, &tree_points, &index, &rule);
    }
    keep_fitted_radii(&mut skeleton, &tracked);
    let skeleton = without_bark_spurs(&skeleton, graph.bin_m, params);
    let shift = foot.map_or(Vec3::ZERO, |f| (f - root.truncate()).extend(0.0));
    let tree_points = tree_points.into_iter().map(|p| p - shift).collect();
    Ok(DenseOutput {
        skeleton: rooted_on_foot(skeleton, shift),
        cloud: PointCloud::from_points(origin + shift.as_dvec3(), tree_points),
        notes,
        bin_width_m: graph.bin_m,
    })
}

/// Step 10: the root moved horizontally by `shift` onto the centre of the
/// trunk's foot circle ([`foot_circle`]), and the anchor with it; every
/// other node stays where it is. Last, because the steps before read the
/// stem's direction off its chain, root included: with the root on the
/// axis under a chain still on the bark, the stem tracking's slices tilted,
/// and a synthetic pine's trunk (`silva synth --species pine --seed 80
/// --scan tls`) was no longer tracked.
fn rooted_on_foot(mut skeleton: Skeleton, shift: Vec3) -> Skeleton {
    let origin = skeleton.anchor().origin + shift.as_dvec3();
    let crs = skeleton.anchor().crs.clone();
    skeleton.set_anchor(Anchor { origin, crs });
    for id in skeleton.ids().skip(1).collect::<Vec<_>>() {
        skeleton.set_position(id, skeleton.position(id) - shift);
    }
    skeleton
}

/// What step 0 learnt of the ground under the tree.
struct GroundSeen {
    /// The terrain, when the terrain fit found ground.
    terrain: Option<Terrain>,
    /// The ground's up direction when it tilts enough for a note: the
    /// terrain's normal past [`super::ground::STEEP_TERRAIN_DEG`], or the
    /// normal of a plane [`super::ground_plane`] found tilted. The lean
    /// check ([`super::check_upright`]) measures the trunk against it.
    tilted_up: Option<Vec3>,
}

/// Steps 0 and 1: the points without ground, de-duplicated and, for huge
/// clouds, thinned (see [`thin`]); and what was seen of the ground.
fn cleaned_points(
    cloud: &PointCloud,
    params: &Params,
    notes: &mut Vec<String>,
) -> Result<(Vec<Vec3>, GroundSeen), ReconstructError> {
    let (points, ground) = without_ground(cloud, notes)?;
    let tree_points = points.len();
    let (points, thinned) = thin(points, params.duplicate_m, params.max_points);
    if let Some(voxel) = thinned {
        notes.push(format!(
            "thinned {tree_points} points to {} on a {:.1} cm voxel grid",
            points.len(),
            voxel * 100.0
        ));
    }
    require_points(points.len())?;
    Ok((points, ground))
}

/// The connected neighbourhood graph of a cloud, with the scales the later
/// steps measure in.
struct NeighbourGraph {
    /// The points that remain after noise components were dropped.
    points: Vec<Vec3>,
    edges: Vec<Edge>,
    /// Median distance to the nearest neighbour, in metres.
    spacing: f32,
    /// Width of the geodesic-distance bins, in metres.
    bin_m: f32,
    /// The points' heights above the ground.
    foot: FootHeights,
}

/// Step 2, first half: the k-nearest-neighbour graph, made connected (see
/// [`connect`]); then the checks that the points can be a tree, against
/// the ground step 0 found under them. `offset` is the cloud's, for the
/// real coordinates of stems in an error ([`check_one_stem`]).
fn neighbour_graph(
    points: Vec<Vec3>,
    offset: glam::DVec3,
    ground: &GroundSeen,
    params: &Params,
    interrupt: &Interrupt,
    notes: &mut Vec<String>,
) -> Result<NeighbourGraph, ReconstructError> {
    interrupt.check("the neighbour graph")?;
    let index = PointIndex::new(&points);
    let spacing = index.median_spacing(&points).unwrap_or(0.0);
    let spacing_m = spacing.max(params.duplicate_m);
    let knn = graph::knn_edges(
        &points,
        &index,
        params.neighbours,
        params.max_edge_spacings * spacing_m,
    );
    drop(index);
    let bin_m = params.bin_width_m.unwrap_or_else(|| {
        (params.bin_spacings * spacing).clamp(params.bin_range_m.0, params.bin_range_m.1)
    });
    interrupt.check("connecting the graph")?;
    let reach_m = params.speck_reach_spacings * spacing_m;
    let (points, edges) = connect(points, knn, bin_m, reach_m, params, notes)?;
    require_points(points.len())?;
    super::check_height(&points)?;
    let base_z = points.iter().map(|p| p.z).fold(f32::INFINITY, f32::min);
    let top_z = points.iter().map(|p| p.z).fold(f32::NEG_INFINITY, f32::max);
    // Two trees whose crowns touch are refused for their stems after the
    // upright checks, whose errors then name both readings.
    let foot = FootHeights::new(&points, ground.terrain.as_ref());
    let one_stem = check_one_stem(&points, &foot, offset);
    let or_two_trees = |e| or_several_trees(e, &one_stem);
    // The trunk tests name the axis that is up, so their error comes before
    // the spreads' and the lean's (a tree lying on its side leans ~90°).
    // Ground found under the tree already shows that +z is up, give or take
    // the terrain's slope, which its note states: a plot scan turned by 45°
    // keeps its trunk across one end of the cloud once its ground is gone,
    // and the side test would ask for a turn by 90°.
    let upright = super::check_upright(&points, base_z, top_z, ground.tilted_up);
    if ground.terrain.is_none() {
        super::upright::check_stands_on_its_trunk(
            &points,
            (STEM_LINK_SPACINGS * spacing).max(0.02),
            super::upright::DENSE_SLICES,
        )
        .map_err(or_two_trees)?;
    }
    notes.extend(upright.map_err(or_two_trees)?);
    one_stem?;
    Ok(NeighbourGraph {
        points,
        edges,
        spacing,
        bin_m,
        foot,
    })
}

/// Each point's height above the terrain (infinite where no scanned ground
/// lies under it), or its z when there is no terrain under the tree; and
/// the lowest of them.
struct FootHeights {
    heights: Vec<f32>,
    lowest: f32,
}

impl FootHeights {
    fn new(points: &[Vec3], terrain: Option<&Terrain>) -> Self {
        let above_ground = |p: &Vec3| {
            let t = terrain?;
            t.surface_near(p.x, p.y).map(|ground| p.z - ground)
        };
        let heights: Vec<f32> = points
            .iter()
            .map(|p| above_ground(p).unwrap_or(f32::INFINITY))
            .collect();
        let lowest = heights.iter().copied().fold(f32::INFINITY, f32::min);
        if lowest.is_finite() {
            return FootHeights { heights, lowest };
        }
        // No terrain, or none under the tree: heights are z.
        let heights: Vec<f32> = points.iter().map(|p| p.z).collect();
        let lowest = heights.iter().copied().fold(f32::INFINITY, f32::min);
        FootHeights { heights, lowest }
    }
}

/// One of step 2's checks: refuses a cloud that stands on stems at least
/// `parts::MIN_STEMS_APART_M` apart ([`parts::stems_apart`]). The crowns of
/// two trees can touch and join the graph into one, with the second tree
/// hanging from the first as a branch down to the ground; their stems stay
/// apart. `offset` is the cloud's, to give the stems' real coordinates.
///
/// Measured with `tools/tls_pairs.py` (`silva reconstruct` on two `silva
/// synth --scan tls` clouds, seeds 1001–1080 in 40 pairs of the four
/// species, the second moved 2, 3, 4, 6 and 8 m along x): 174 of the 200
/// pairs were refused for their stems, 7 as upside down with the reading
/// of [`or_several_trees`], 19 for the gap between their crowns; before
/// this check, 176 became one tree, all 80 at 2 and 3 m among them, and 5
/// went to the airborne pipeline under `--mode auto`, as they did with it
/// until the survey measured the trunk coverage about the larger stem
/// (`reconstruct::trunk_coverage`). With `--ground-radius 4` all 200 were
/// refused (172 for their stems, 9 as upside down with that reading, 19
/// for their gap). Two oaks 6 m apart (pair 32) were not, until the
/// terrain fit let its inliers settle (`ground::SETTLING_ROUNDS`): the
/// terrain had kept the ground under one oak only, and the second's stem
/// had no height above ground. Taking such heights above the terrain's
/// extrapolation instead found that stem too, but also, as a second stem,
/// the limb of a single oak hanging near the extrapolated ground 7 m out
/// over a 20° slope (oak 125 of `silva eval --synthetic 100 --scan tls
/// --ground-radius 6 --ground-slope 20 --seed 101`), so it was not kept.
/// None of 1,000 single trees (`silva eval --synthetic 100 --scan tls` in
/// 10 variants: occluded or not, leaf-on, 30–40 points/m², ground discs of
/// 4–8 m on slopes up to 30°) and none of `../shared/data` stood on two
/// stems; a synthetic oak's limb resting on a 20° slope did, until
/// [`parts::standing_stems`] asked stems to stand.
fn check_one_stem(
    points: &[Vec3],
    foot: &FootHeights,
    offset: glam::DVec3,
) -> Result<(), ReconstructError> {
    let apart = parts::stems_apart(points, &foot.heights, foot.lowest);
    let [first, second, ..] = apart[..] else {
        return Ok(());
    };
    let at = |s: parts::Stem| [offset.x + s.centre.x as f64, offset.y + s.centre.y as f64];
    Err(ReconstructError::SeveralStems {
        stems: apart.len(),
        apart_m: first.centre.distance(second.centre),
        first: at(first),
        second: at(second),
    })
}

/// `error`, an upright check's, extended by the other reading when the
/// cloud also stands on several stems (`one_stem`): two trees whose crowns
/// touch stand wide at the bottom, with two narrow tops, and can look
/// upside down (two poplars 6 m apart did); a tree upside down can hang
/// twigs that look like stems (1 of 40 synthetic trees turned over did).
fn or_several_trees(
    error: ReconstructError,
    one_stem: &Result<(), ReconstructError>,
) -> ReconstructError {
    match (error, one_stem) {
        (
            ReconstructError::Degenerate(reason),
            Err(ReconstructError::SeveralStems { stems, apart_m, .. }),
        ) => ReconstructError::Degenerate(format!(
            "{reason}; or it holds {stems} trees whose crowns touch, on stems {apart_m:.1} m \
             apart (then split the cloud into one tree per file)"
        )),
        (error, _) => error,
    }
}

/// The trunk base: every point of the lowest slice (one bin high) is a
/// source of the shortest-path tree; the root sits at their horizontal
/// centroid, at the lowest point's height. Also the centre of the trunk's
/// circle at its foot, when one fits ([`foot_circle`]), where the root goes
/// in the end ([`rooted_on_foot`]).
///
/// Over a terrain (step 0), heights are taken above it, so on a slope the
/// lowest slice is the stem's oblique cut along the ground, whose centroid
/// is the stem's centre (a level slice would hold only its downhill side,
/// 0.15 m too low on a 20° slope under a 0.7 m oak), and the root stands on
/// the ground there. Only points over scanned ground count: a limb reaching
/// past the plot's ground hangs over the plane's extrapolation, which can be
/// decimetres off at 10 m.
fn trunk_base(
    points: &[Vec3],
    foot: &FootHeights,
    bin_m: f32,
    terrain: Option<&Terrain>,
) -> (Vec<u32>, Vec3, Option<glam::Vec2>) {
    let FootHeights { heights, lowest } = foot;
    let (heights, lowest) = (heights.as_slice(), *lowest);
    let sources: Vec<u32> = (0..points.len() as u32)
        .filter(|&i| heights[i as usize] < lowest + bin_m)
        .collect();
    let base_xy = sources
        .iter()
        .map(|&i| points[i as usize].truncate())
        .sum::<glam::Vec2>()
        / sources.len() as f32;
    let lowest_z = sources
        .iter()
        .map(|&i| points[i as usize].z)
        .fold(f32::INFINITY, f32::min);
    let base_z = terrain.map_or(lowest_z, |t| {
        t.surface_at(base_xy.x, base_xy.y).min(lowest_z)
    });
    let foot = foot_circle(points, heights, lowest);
    (sources, base_xy.extend(base_z), foot)
}

/// The centre of the circle fitted ([`robust_circle`]) to the points within
/// the first of [`FOOT_SLICES_M`] of the lowest (`heights` as in
/// [`trunk_base`]) where it is the trunk's: it holds half of them or more,
/// as inliers over a third of its girth ([`MIN_TRUNK_SECTORS`] of 12
/// sectors) with an RMS of at most [`MAX_FOOT_RMS_SHARE`] of its radius,
/// and at least [`MIN_FOOT_INLIERS`] of them.
///
/// A scan sees a trunk from a few sides, so the centroid of its lowest
/// slice lies towards the scanners, up to its radius off the axis. The
/// root is where the tree stands in the inventory: on the synthetic
/// terrestrial scans of `silva eval --synthetic 100 --scan tls` (no
/// ground) it lay a median 0.092 m (at most 0.316 m) from the true base,
/// and 0.002 m (at most 0.004 m) on this circle's centre; with
/// `--ground-radius 4 --seed 101` 0.092 m (at most 0.246 m) and 0.003 m
/// (0.007 m).
fn foot_circle(points: &[Vec3], heights: &[f32], lowest: f32) -> Option<glam::Vec2> {
    FOOT_SLICES_M
        .iter()
        .find_map(|&slice_m| foot_circle_within(points, heights, lowest + slice_m))
}

/// [`foot_circle`] on the points lower than `top` (in `heights`).
fn foot_circle_within(points: &[Vec3], heights: &[f32], top: f32) -> Option<glam::Vec2> {
    let foot: Vec<glam::Vec2> = points
        .iter()
        .zip(heights)
        .filter(|&(_, &h)| h < top)
        .map(|(p, _)| p.truncate())
        .collect();
    let (circle, inliers) = robust_circle(&foot, MAX_TRUNK_RADIUS_M)?;
    let trunk = inliers.len() >= MIN_FOOT_INLIERS
        && 2 * inliers.len() >= foot.len()
        && trunk_sectors_seen(&inliers, circle.centre) >= MIN_TRUNK_SECTORS
        && circle_rms(&inliers, circle) <= MAX_FOOT_RMS_SHARE * circle.radius;
    trunk.then_some(circle.centre)
}

/// Step 2, second half, and step 3: the shortest-path tree from the trunk
/// base, and the cross-sections of equal geodesic distance that become
/// skeleton nodes. Takes the graph's edges: once they are in the adjacency
/// lists their memory is freed, as the graph's is after this step.
fn cross_sections(
    graph: &mut NeighbourGraph,
    sources: &[u32],
    root: Vec3,
    params: &Params,
    interrupt: &Interrupt,
) -> Result<skeletonize::Sections, ReconstructError> {
    interrupt.check("the shortest-path tree")?;
    let edges = std::mem::take(&mut graph.edges);
    let g = graph::Graph::from_edges(graph.points.len(), &edges);
    drop(edges);
    let (dist, pred) = graph::shortest_path_tree(&g, sources);
    interrupt.check("skeletonisation")?;
    let (bin_m, spacing) = (graph.bin_m, graph.spacing);
    let sectioning = skeletonize::Sectioning {
        bin_m,
        merge_overlapping_arcs: params.merge_overlapping_arcs,
        centre_arcs: params.centre_arcs,
        window_bins: params.ring_window_bins,
        thick_spread_m: params.ring_spread_m,
        broken_ring_pieces: params.broken_ring_pieces,
        broken_ring_spread_m: params.broken_ring_spread_m,
        ring_outlier_m: params.ring_outlier_m,
        max_link_m: params.section_link_spacings * spacing,
        max_ring_link_m: params.ring_link_spacings * spacing,
        two_stems: params.split_two_stems.then_some(fork_rings::TwoStemRule {
            min_spread_m: params.two_stem_spread_bins * bin_m,
            min_points: TWO_STEM_MIN_POINTS,
            max_deviation_share: params.two_stem_deviation_share,
        }),
    };
    Ok(skeletonize::cross_sections(
        &graph.points,
        &g,
        &dist,
        &pred,
        root,
        &sectioning,
    ))
}

/// Step 4: noisy branches and bark detours dropped, chains smoothed and
/// simplified (Douglas–Peucker), main extension first.
fn simplified(skeleton: Skeleton, bin_m: f32, params: &Params) -> Skeleton {
    let keep = simplify::noise_branches(
        &skeleton,
        &simplify::Pruning {
            min_branch_m: params.min_branch_bins * bin_m,
            stem_spreads: params.stem_stub_spreads,
            spur_spread_m: params.spur_spread_bins * bin_m,
            spur_reach_m: params.spur_reach_bins * bin_m,
            strand_reach_m: params.strand_reach_bins * bin_m,
        },
    );
    let skeleton = skeleton.retain(&keep);
    let keep = simplify::bark_detours(
        &skeleton,
        &simplify::Detours {
            thick_spread_m: params.spur_spread_bins * bin_m,
            thin_share: params.detour_thin_share,
            off_axis_share: params.detour_off_axis_share,
            max_nodes: params.detour_max_nodes,
        },
    );
    let mut skeleton = skeleton.retain(&keep);
    simplify::smooth_chains(&mut skeleton, params.smoothing_rounds, 2.0 * bin_m);
    simplify::smooth_thin_chains(
        &mut skeleton,
        &simplify::ThinSmoothing {
            rounds: params.thin_smoothing_rounds,
            thick_spread_m: 2.0 * bin_m,
            min_reach_m: params.thin_smoothing_reach_bins * bin_m,
        },
    );
    let mut skeleton = simplify::douglas_peucker(
        &skeleton,
        params.simplify_bins * bin_m,
        params.simplify_spreads,
    );
    skeleton.order_main_extension_first();
    skeleton
}

/// Steps 5 and 6: laterals of thick stems started on the stem's axis, and
/// twigs that the stem reached more than once joined to it once.
fn refined(
    skeleton: Skeleton,
    bin_m: f32,
    params: &Params,
    interrupt: &Interrupt,
) -> Result<Skeleton, ReconstructError> {
    interrupt.check("lateral bases")?;
    let thick_spread_m = params.lateral_base_spread_bins * bin_m;
    let skeleton = lateral_base::to_parent_axis(
        &skeleton,
        &lateral_base::BaseRule {
            thick_spread_m,
            direction_spreads: params.lateral_direction_spreads,
            min_direction_m: params.lateral_direction_bins * bin_m,
            max_drop_spreads: params.lateral_max_drop_spreads,
            max_miss_spreads: params.lateral_miss_spreads,
            snap_m: bin_m,
        },
    );
    interrupt.check("twin joins")?;
    let mut skeleton = twins::rejoin_twins(
        &skeleton,
        &twins::TwinRule {
            thick_spread_m,
            max_gap_m: params.twin_gap_bins * bin_m,
            max_gap_share: TWIN_GAP_SHARE,
            min_turn_deg: params.twin_min_turn_deg,
        },
    );
    skeleton.order_main_extension_first();
    Ok(skeleton)
}

/// Step 7: the trunk's nodes on the centres of circles fitted to tall
/// slices of its bark (see `stem_axis`), unless turned off. Returns the
/// nodes so tracked.
fn recentre_stem(
    skeleton: &mut Skeleton,
    points: &[Vec3],
    index: &PointIndex,
    bin_m: f32,
    params: &Params,
) -> Vec<NodeId> {
    if params.stem_half_slice_m <= 0.0 {
        return Vec::new();
    }
    stem_axis::recentre_stem(skeleton, points, index, &stem_rule(bin_m, params))
}

/// Step 7b: the tracked stem's thick laterals tracked in turn (see
/// `stem_axis::recentre_limbs`). Returns the nodes so tracked.
fn recentre_limbs(
    skeleton: &mut Skeleton,
    points: &[Vec3],
    index: &PointIndex,
    tracked: &[NodeId],
    bin_m: f32,
    params: &Params,
) -> Vec<NodeId> {
    let limb = stem_axis::LimbRule {
        max_share: params.limb_max_share,
        seed_reach_m: params.limb_seed_reach_m,
        min_subtree_m: params.limb_min_subtree_m,
        min_radius_m: params.limb_min_radius_m,
    };
    let rules = (&stem_rule(bin_m, params), &limb);
    stem_axis::recentre_limbs(skeleton, points, index, tracked, rules)
}

/// The trunk tracker's settings.
fn stem_rule(bin_m: f32, params: &Params) -> stem_axis::StemRule {
    stem_axis::StemRule {
        half_window_m: params.stem_half_slice_m,
        axis_window_m: params.stem_axis_window_m,
        reach_m: params.stem_reach_m,
        min_radius_m: 2.0 * bin_m,
        min_points: params.stem_min_points,
        seed_points: params.stem_seed_points,
        seed_height_m: params.stem_seed_height_m,
        max_change: params.stem_max_change,
        fade_m: params.stem_fade_m,
    }
}

/// Every radius but the `tracked` nodes' fitted ones set to 0: a section's
/// spread is not a measurement the radius stage should trust (an arc's
/// centroid lies inside its circle), a circle fitted to a tall slice is.
fn keep_fitted_radii(skeleton: &mut Skeleton, tracked: &[NodeId]) {
    let mut fitted = vec![false; skeleton.len()];
    for id in tracked {
        fitted[id.index()] = true;
    }
    for id in skeleton.ids() {
        if !fitted[id.index()] {
            skeleton.set_radius(id, 0.0);
        }
    }
}

/// Step 9: the skeleton without the tracked stem's spurs to its bark
/// (`simplify::bark_spurs`) and the strands along the tracked trunk's and
/// limbs' bark (`simplify::bark_strands`), unless the spur rule is off, in canonical
/// order either way (`Skeleton::retain` returns it so).
fn without_bark_spurs(skeleton: &Skeleton, bin_m: f32, params: &Params) -> Skeleton {
    if !params.spur_spread_bins.is_finite() {
        return skeleton.retain(&vec![true; skeleton.len()]);
    }
    let reach_m = params.spur_reach_bins * bin_m;
    let spurs = simplify::bark_spurs(skeleton, reach_m);
    let strands = simplify::bark_strands(skeleton, reach_m);
    let keep: Vec<bool> = spurs.iter().zip(&strands).map(|(&a, &b)| a && b).collect();
    skeleton.retain(&keep)
}

/// Removes near-duplicates (points within one `duplicate_m` voxel), then
/// thins on coarser voxels until at most `max_points` remain. Returns the
/// points and, when thinning beyond de-duplication was needed, the voxel.
fn thin(points: Vec<Vec3>, duplicate_m: f32, max_points: usize) -> (Vec<Vec3>, Option<f32>) {
    let budget = max_points.max(1);
    let mut voxel = duplicate_m;
    // A cloud within the budget needs no count: de-duplication only
    // lowers it.
    let mut count = if points.len() > budget {
        occupied_voxels(&points, voxel)
    } else {
        points.len()
    };
    let mut thinned = None;
    // Only counts until the size is found: selecting the points is the
    // costly part, and it is done once, at the last size.
    while count > budget {
        // Tree surfaces are two-dimensional: the count falls with voxel².
        voxel *= ((count as f32 / budget as f32).sqrt() * 1.05).max(1.1);
        count = occupied_voxels(&points, voxel);
        thinned = Some(voxel);
    }
    let cloud = PointCloud::from_points(glam::DVec3::ZERO, points);
    (voxel_downsample(&cloud, voxel).points, thinned)
}

fn require_points(found: usize) -> Result<(), ReconstructError> {
    if found < super::MIN_POINTS {
        return Err(ReconstructError::TooFewPoints {
            found,
            needed: super::MIN_POINTS,
        });
    }
    Ok(())
}

/// The points that are not ground (step 0), and what was seen of the
/// ground ([`GroundSeen`]), with notes on both; an error when the ground lies on top
/// ([`super::upright::check_ground_below`]). A surface the terrain fit finds with hardly
/// anything standing on it is no ground under a tree but the tree itself,
/// lying (or a tilted cloud's flat side): all points stay, for the upright
/// checks to judge. Without ground, a plot scan turned too far for the
/// terrain grid still shows its ground as a plane in 3D, and gets a note
/// ([`super::ground_plane`]).
fn without_ground(
    cloud: &PointCloud,
    notes: &mut Vec<String>,
) -> Result<(Vec<Vec3>, GroundSeen), ReconstructError> {
    let split = split_ground(cloud);
    super::upright::check_ground_below(&cloud.points, &split)?;
    let nothing_stands = split.tree.len() < super::MIN_POINTS;
    if split.method == GroundMethod::None
        || (split.method == GroundMethod::Geometry && nothing_stands)
    {
        let plane = super::ground_plane::tilted_ground(&cloud.points);
        notes.extend(plane.map(|g| g.note()));
        let ground = GroundSeen {
            terrain: None,
            tilted_up: plane.map(|g| g.up),
        };
        return Ok((cloud.points.clone(), ground));
    }
    notes.push(split.note());
    let steep = split.steep_note();
    let steep_terrain = split.terrain.as_ref().filter(|_| steep.is_some());
    let tilted_up = steep_terrain.map(Terrain::up);
    notes.extend(steep);
    let ground = GroundSeen {
        terrain: split.terrain,
        tilted_up,
    };
    Ok((split.tree.points, ground))
}

/// An undirected graph edge: two point indices and the length in metres.
type Edge = (u32, u32, f32);

/// Makes the graph connected: bridges every component to the largest one
/// at their closest pairs, except specks (fewer than
/// [`Params::min_component_points`] points) farther than `reach_m` from the
/// rest, which are dropped as isolated noise; rejects or drops parts that
/// lie farther than [`Params::max_gap_m`] (or `reach_m`, the reach of the
/// graph's links before they were cut, if longer). Returns the kept points
/// and edges.
fn connect(
    points: Vec<Vec3>,
    knn: Vec<Edge>,
    bin_m: f32,
    reach_m: f32,
    params: &Params,
    notes: &mut Vec<String>,
) -> Result<(Vec<Vec3>, Vec<Edge>), ReconstructError> {
    let (labels, sizes) = graph::components(points.len(), &knn);
    let bridges = graph::bridge_components(&points, &labels, &sizes, 2.0 * bin_m);
    let total = points.len() as f32;
    let max_gap_m = params.max_gap_m.max(reach_m);
    let mut dropped = vec![false; sizes.len()];
    let (mut specks, mut speck_points) = (0, 0);
    let mut used = Vec::new();
    let mut widest = 0.0f32;
    for b in &bridges {
        let (a, c, gap) = b.edge;
        let joined_label = labels[c as usize] as usize;
        let cut_off = dropped[labels[a as usize] as usize];
        if b.points < params.min_component_points && (gap > reach_m || cut_off) {
            dropped[joined_label] = true;
            specks += 1;
            speck_points += b.points;
            continue;
        }
        if gap <= max_gap_m && !cut_off {
            used.push(b.edge);
            widest = widest.max(gap);
            continue;
        }
        let share = b.points as f32 / total;
        if share >= params.detached_share && gap.is_finite() {
            return Err(ReconstructError::Disconnected {
                share_pct: 100.0 * share,
                gap_m: gap,
            });
        }
        dropped[joined_label] = true;
        notes.push(format!(
            "dropped a detached part of {} points {gap:.2} m away from the tree",
            b.points
        ));
    }
    if speck_points > 0 {
        notes.push(format!(
            "dropped {speck_points} isolated points in {specks} specks of fewer than {} points",
            params.min_component_points
        ));
    }
    if !used.is_empty() {
        notes.push(format!(
            "bridged {} gaps in the scan (widest {widest:.2} m)",
            used.len()
        ));
    }
    let keep: Vec<bool> = labels.iter().map(|&l| !dropped[l as usize]).collect();
    Ok(retained(&points, knn, used, &keep))
}

/// The points marked in `keep`, renumbered, and the edges among them of
/// the k-nearest-neighbour graph and the bridges `used`.
fn retained(
    points: &[Vec3],
    knn: Vec<Edge>,
    used: Vec<Edge>,
    keep: &[bool],
) -> (Vec<Vec3>, Vec<Edge>) {
    let mut new_id = vec![u32::MAX; points.len()];
    let mut kept = Vec::with_capacity(points.len());
    for (i, &p) in points.iter().enumerate() {
        if keep[i] {
            new_id[i] = kept.len() as u32;
            kept.push(p);
        }
    }
    let edges = knn
        .into_iter()
        .chain(used)
        .filter(|&(a, b, _)| keep[a as usize] && keep[b as usize])
        .map(|(a, b, w)| (new_id[a as usize], new_id[b as usize], w))
        .collect();
    (kept, edges)
}

#[cfg(test)]
mod tests {
    use rand::{Rng, SeedableRng};

    use super::*;

    /// `n` points on the bark of a 0.3 m trunk, 4 m tall, with duplicates.
    fn bark(n: usize) -> Vec<Vec3> {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let mut pts: Vec<Vec3> = (0..n)
            .map(|_| {
                let phi = rng.random::<f32>() * std::f32::consts::TAU;
                Vec3::new(0.3 * phi.cos(), 0.3 * phi.sin(), 4.0 * rng.random::<f32>())
            })
            .collect();
        pts.extend_from_within(..n / 10);
        pts
    }

    /// What `thin` computes, the plain way: select at every trial size.
    fn thin_by_selecting(points: Vec<Vec3>, duplicate_m: f32, max: usize) -> Vec<Vec3> {
        let cloud = PointCloud::from_points(glam::DVec3::ZERO, points);
        let (mut out, mut voxel) = (voxel_downsample(&cloud, duplicate_m), duplicate_m);
        while out.len() > max {
            voxel *= ((out.len() as f32 / max as f32).sqrt() * 1.05).max(1.1);
            out = voxel_downsample(&cloud, voxel);
        }
        out.points
    }

    #[test]
    fn thinning_finds_its_voxel_by_counting_and_keeps_what_selecting_would() {
        let pts = bark(40_000);
        let (thinned, voxel) = thin(pts.clone(), 0.002, 5_000);
        assert!(
            thinned.len() <= 5_000 && thinned.len() > 2_500,
            "{}",
            thinned.len()
        );
        assert!(voxel.is_some_and(|v| v > 0.002));
        assert_eq!(thinned, thin_by_selecting(pts, 0.002, 5_000));
    }

    /// A stem sampled every 2 cm (links cut at 10 spacings, 0.2 m; specks
    /// reached within 20, 0.4 m) with three pieces beside it: two points
    /// 0.3 m away and ten 0.8 m away are bridged, two points 0.8 m away are
    /// a speck and dropped.
    #[test]
    fn pieces_are_bridged_and_far_specks_dropped() {
        let mut points: Vec<Vec3> = (0..200)
            .map(|i| Vec3::new(0.0, 0.0, 0.02 * i as f32))
            .collect();
        let piece =
            |x: f32, z: f32, n: usize| (0..n).map(move |i| Vec3::new(x, 0.0, z + 0.02 * i as f32));
        points.extend(piece(0.3, 1.0, 2));
        points.extend(piece(0.8, 2.0, 10));
        points.extend(piece(-0.8, 3.0, 2));
        let index = PointIndex::new(&points);
        let knn = graph::knn_edges(&points, &index, 10, 0.2);
        let mut notes = Vec::new();
        let (kept, edges) =
            connect(points, knn, 0.03, 0.4, &Params::default(), &mut notes).unwrap();
        assert_eq!(kept.len(), 212);
        assert!(kept.iter().all(|p| p.x > -0.5));
        let (labels, sizes) = graph::components(kept.len(), &edges);
        assert_eq!((sizes.len(), labels.len()), (1, 212));
        assert_eq!(
            notes,
            [
                "dropped 2 isolated points in 1 specks of fewer than 5 points",
                "bridged 2 gaps in the scan (widest 0.80 m)"
            ]
        );
    }

    #[test]
    fn a_cloud_within_the_budget_loses_only_its_duplicates() {
        let pts = bark(4_000);
        let (kept, voxel) = thin(pts.clone(), 0.002, 5_000);
        assert_eq!(voxel, None);
        assert!(kept.len() < pts.len() && kept.len() >= 3_600);
        assert_eq!(kept, thin_by_selecting(pts, 0.002, 5_000));
    }
}
