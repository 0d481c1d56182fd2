//! From the shortest-path tree to skeleton nodes at branch centres.
//!
//! AdTree's minimum spanning tree runs over the bark, zigzagging between
//! surface points, and AdTree then centres it (mean shift) and simplifies it
//! (lsystem-from-adtree-skeletons §2.1.1; multi-temporal-tree-growth §3.2.1
//! describes the same zigzag). silva does both in one step: points are
//! binned by their geodesic distance from the trunk base; within a bin, the
//! points that are linked by graph edges form one cross-section of one
//! branch, and its centroid becomes a skeleton node. A node's parent is the
//! cross-section that holds the shortest-path predecessor of its closest
//! point, so the skeleton inherits the shortest-path tree's topology while
//! its nodes sit inside the branches, not on the bark.

use foldhash::{HashMap, HashMapExt};

use glam::{DVec3, Vec2, Vec3};

use super::fork_rings::{TwoStemRule, split_two_stem_sections};
use super::graph::{Graph, UnionFind};
use crate::reconstruct::radii::kasa_fit;
use crate::reconstruct::{least_spread_axis, principal_spreads};
use crate::skeleton::{Node, NodeId};

/// Skeleton nodes (relative to the points' frame) and the number of points
/// behind each; node 0 is the root at `root`.
pub(super) struct Sections {
    pub(super) nodes: Vec<Node>,
    pub(super) counts: Vec<u32>,
}

/// How points are grouped into cross-sections.
pub(super) struct Sectioning {
    /// Width of the geodesic-distance bins, in metres.
    pub(super) bin_m: f32,
    /// Join same-bin sections whose extents overlap.
    pub(super) merge_overlapping_arcs: bool,
    /// Centre thick sections on a fitted circle.
    pub(super) centre_arcs: bool,
    /// Same-bin points of a thick stem are one section when graph edges join
    /// them through points at most this many bins away (0: within the bin
    /// only).
    pub(super) window_bins: u32,
    /// A section joined through the window counts as a thick stem's ring
    /// when its points spread this far from their centroid (RMS, metres).
    pub(super) thick_spread_m: f32,
    /// A joined section of at least this many per-bin pieces is a broken
    /// ring too, when its spread reaches `broken_ring_spread_m`.
    pub(super) broken_ring_pieces: u32,
    /// See `broken_ring_pieces`, in metres.
    pub(super) broken_ring_spread_m: f32,
    /// Points of a ring more than this far outside its fitted circle are a
    /// twig along the stem, not part of the ring (0: keep them in it).
    pub(super) ring_outlier_m: f32,
    /// Graph edges longer than this do not join the points of a bin into one
    /// section, in metres: in a sparsely sampled crown the nearest-neighbour
    /// edges also link neighbouring twigs, whose shared section would put
    /// the node between them.
    pub(super) max_link_m: f32,
    /// Graph edges longer than this do not join a thick stem's ring through
    /// the neighbouring bins, in metres (for the same reason).
    pub(super) max_ring_link_m: f32,
    /// Split sections that hold both stems of a narrow fork (`None`: off).
    pub(super) two_stems: Option<TwoStemRule>,
}

/// Builds one node per branch cross-section. `dist` and `pred` come from the
/// shortest-path tree over `graph`; every point must be reachable.
pub(super) fn cross_sections(
    points: &[Vec3],
    graph: &Graph,
    dist: &[f32],
    pred: &[u32],
    root: Vec3,
    opts: &Sectioning,
) -> Sections {
    let bin: Vec<u32> = dist.iter().map(|&d| (d / opts.bin_m) as u32).collect();
    let mut uf = grouped(points, graph, dist, pred, &bin, opts);
    let (mut nodes, counts, node_of) = numbered_sections(points, dist, pred, &bin, root, &mut uf);
    if opts.centre_arcs {
        let mut members: Vec<Vec<u32>> = vec![Vec::new(); nodes.len()];
        for i in 0..points.len() as u32 {
            members[node_of[uf.find(i) as usize] as usize].push(i);
        }
        centre_on_arcs(points, &members, &mut nodes, 2.0 * opts.bin_m);
    }
    Sections { nodes, counts }
}

/// The points grouped into cross-sections: each bin's points joined along
/// short graph edges, then thick stems' rings, overlapping arcs and the
/// two stems of narrow forks treated as [`Sectioning`] says.
fn grouped(
    points: &[Vec3],
    graph: &Graph,
    dist: &[f32],
    pred: &[u32],
    bin: &[u32],
    opts: &Sectioning,
) -> UnionFind {
    let n = points.len();
    let mut uf = UnionFind::new(n);
    // Bin 0 (everything within one bin of the base slice) is the root.
    let first_base = (0..n).find(|&i| bin[i] == 0).unwrap_or(0) as u32;
    for i in 0..n as u32 {
        if bin[i as usize] == 0 {
            uf.union(first_base, i);
        }
    }
    join_within_windows(graph, bin, 0, opts.max_link_m, &mut uf);
    if opts.window_bins > 0 {
        join_thick_rings(points, graph, dist, pred, bin, opts, &mut uf);
    }
    if opts.merge_overlapping_arcs {
        let stats = Stats::gather(points, dist, &mut uf);
        merge_overlapping(points, bin, &stats, &mut uf);
    }
    if let Some(rule) = &opts.two_stems {
        uf = split_two_stem_sections(points, &mut uf, rule);
    }
    uf
}

/// One node per section of `uf`, numbered by the geodesic distance of its
/// lowest point (so parents come first), at the section's centroid (the
/// root's at `root`), hanging from the section of that point's predecessor.
/// Returns the nodes, their point counts and each section root's node.
fn numbered_sections(
    points: &[Vec3],
    dist: &[f32],
    pred: &[u32],
    bin: &[u32],
    root: Vec3,
    uf: &mut UnionFind,
) -> (Vec<Node>, Vec<u32>, Vec<u32>) {
    let n = points.len();
    let Stats {
        lowest,
        sum,
        sum_sq,
        count,
    } = Stats::gather(points, dist, uf);
    let mut sections: Vec<usize> = (0..n).filter(|&r| count[r] > 0).collect();
    sections.sort_by(|&a, &b| {
        let (la, lb) = (lowest[a] as usize, lowest[b] as usize);
        (bin[la], dist[la])
            .partial_cmp(&(bin[lb], dist[lb]))
            .unwrap_or(std::cmp::Ordering::Equal)
    });
    let mut node_of = vec![u32::MAX; n];
    let mut nodes = Vec::with_capacity(sections.len());
    let mut counts = Vec::with_capacity(sections.len());
    for (id, &r) in sections.iter().enumerate() {
        node_of[r] = id as u32;
        let low = lowest[r] as usize;
        let (position, parent) = if id == 0 {
            (root, None)
        } else {
            let p = pred[low];
            // Reachability guarantees a predecessor in a lower bin, whose
            // section is already numbered; fall back to the root otherwise.
            let parent_node = if p == u32::MAX {
                0
            } else {
                node_of[uf.find(p) as usize]
            };
            let parent_node = if parent_node == u32::MAX {
                0
            } else {
                parent_node
            };
            let centroid = (sum[r] / f64::from(count[r])).as_vec3();
            (centroid, Some(NodeId::from_index(parent_node as usize)))
        };
        let c = f64::from(count[r]);
        let mean = sum[r] / c;
        let spread = (sum_sq[r] / c - mean.length_squared()).max(0.0).sqrt() as f32;
        // The spread stands in for the radius until the radius stage runs;
        // pruning uses it to tell bark noise from branches.
        nodes.push(Node {
            position,
            radius_m: spread,
            parent,
        });
        counts.push(count[r]);
    }
    (nodes, counts, node_of)
}

/// Joins the pieces of thick stems' rings (see [`join_within_windows`]).
/// Only sections that come out thick, or that fall apart into several
/// pieces across a few centimetres (a thinner limb's broken ring), are
/// joined: among twigs, the window would delay forks and lose short
/// branches for nothing. `dist` and `pred` are the shortest-path tree's.
fn join_thick_rings(
    points: &[Vec3],
    graph: &Graph,
    dist: &[f32],
    pred: &[u32],
    bin: &[u32],
    opts: &Sectioning,
    uf: &mut UnionFind,
) {
    let mut wide = uf.clone();
    join_within_windows(
        graph,
        bin,
        opts.window_bins,
        opts.max_ring_link_m,
        &mut wide,
    );
    let stats = Stats::gather(points, dist, &mut wide);
    // Fine pieces per joined section: many pieces mark a broken ring.
    let mut pieces = vec![0u32; points.len()];
    for i in 0..points.len() as u32 {
        if uf.find(i) == i {
            pieces[wide.find(i) as usize] += 1;
        }
    }
    let is_ring = |r: usize| {
        let spread = stats.spread(r);
        spread >= opts.thick_spread_m
            || (pieces[r] >= opts.broken_ring_pieces && spread >= opts.broken_ring_spread_m)
    };
    let rings = if opts.ring_outlier_m > 0.0 {
        fit_rings(points, bin, &mut wide, is_ring)
    } else {
        HashMap::new()
    };
    let mut outside = vec![false; points.len()];
    let mut joined = uf.clone();
    let mut first = vec![u32::MAX; points.len()];
    for i in 0..points.len() as u32 {
        let r = wide.find(i) as usize;
        if !is_ring(r) {
            continue;
        }
        if let Some(ring) = rings.get(&(r as u32))
            && ring.margin(points[i as usize]) > opts.ring_outlier_m.max(ring.tolerance_m)
        {
            outside[i as usize] = true;
            continue;
        }
        if first[r] == u32::MAX {
            first[r] = i;
        } else {
            joined.union(first[r], i);
        }
    }
    if rings.is_empty() {
        *uf = joined;
        return;
    }
    let mut split = split_off_outside(graph, &outside, opts.max_link_m, &mut wide, &mut joined);
    rejoin_dead_ends(dist, pred, &outside, &first, &mut wide, &mut split);
    *uf = split;
}

/// Puts groups of outside points that no section grows from back into their
/// ring, whose first member is `first[ring]`. A twig along the bark is a run
/// of such groups, each the parent (by the shortest-path predecessor of its
/// lowest point) of the next and the last of the twig where it leaves; a
/// group that nothing continues is a lump on the bark, or, at a fork, a
/// piece of the crotch or of a limb's first arc while the limb itself
/// parts from the ring: kept apart, it became a stub out of the stem (the
/// Y-tree of `tests/reconstruct_dense.rs` got a third tip, the clean
/// synthetic oaks lost up to 0.2 points of precision).
fn rejoin_dead_ends(
    dist: &[f32],
    pred: &[u32],
    outside: &[bool],
    first: &[u32],
    wide: &mut UnionFind,
    split: &mut UnionFind,
) {
    let n = outside.len();
    let group: Vec<u32> = (0..n as u32).map(|i| split.find(i)).collect();
    let mut lowest = vec![u32::MAX; n];
    for (i, &g) in group.iter().enumerate() {
        let low = &mut lowest[g as usize];
        if *low == u32::MAX || dist[i] < dist[*low as usize] {
            *low = i as u32;
        }
    }
    let mut continued = vec![false; n];
    for (g, &low) in lowest.iter().enumerate() {
        let p = if low == u32::MAX {
            u32::MAX
        } else {
            pred[low as usize]
        };
        if p != u32::MAX && group[p as usize] as usize != g {
            continued[group[p as usize] as usize] = true;
        }
    }
    for i in 0..n as u32 {
        let ring_first = first[wide.find(i) as usize];
        let g = group[i as usize];
        if outside[i as usize]
            && ring_first != u32::MAX
            && g != group[ring_first as usize]
            && !continued[g as usize]
        {
            split.union(ring_first, i);
        }
    }
}

/// The circle a thick section's points lie on, across the band's axis.
struct Ring {
    centre: Vec3,
    axis: Vec3,
    radius_m: f32,
    /// How far outside the circle the ring's own points may lie, from
    /// their median deviation.
    tolerance_m: f32,
}

impl Ring {
    /// How far `p` lies outside the ring, across the axis (negative inside).
    fn margin(&self, p: Vec3) -> f32 {
        let d = p - self.centre;
        (d - self.axis * d.dot(self.axis)).length() - self.radius_m
    }
}

/// Fits a [`Ring`] to each section (a root of `wide`) that `is_ring`
/// accepts: the band's axis is the direction the points spread least along,
/// and the circle is fitted (Kåsa) across it. Sections whose fit is
/// implausible get none and stay joined whole.
fn fit_rings(
    points: &[Vec3],
    bin: &[u32],
    wide: &mut UnionFind,
    is_ring: impl Fn(usize) -> bool,
) -> HashMap<u32, Ring> {
    let mut members: HashMap<u32, Vec<Vec3>> = HashMap::new();
    for i in 0..points.len() as u32 {
        let r = wide.find(i);
        if bin[i as usize] > 0 && is_ring(r as usize) {
            members.entry(r).or_default().push(points[i as usize]);
        }
    }
    members
        .into_iter()
        .filter_map(|(r, pts)| Some((r, ring_of(&pts)?)))
        .collect()
}

fn ring_of(pts: &[Vec3]) -> Option<Ring> {
    if pts.len() < 12 {
        return None;
    }
    let axis = least_spread_axis(pts)?;
    let plane = Across::new(pts, axis);
    let flat = plane.flat(pts);
    let circle = kasa_fit(&flat)?;
    let extent = flat.iter().map(|q| q.length()).fold(0.0, f32::max);
    if !(circle.radius.is_finite() && circle.radius < 2.0 * extent) {
        return None;
    }
    let mut ring = Ring {
        centre: plane.lift(circle.centre),
        axis,
        radius_m: circle.radius,
        tolerance_m: 0.0,
    };
    let mut deviation: Vec<f32> = pts.iter().map(|&p| ring.margin(p).abs()).collect();
    let mid = deviation.len() / 2;
    ring.tolerance_m =
        RING_TOLERANCE_MADS * *deviation.select_nth_unstable_by(mid, f32::total_cmp).1;
    Some(ring)
}

/// How many median deviations from its circle a point of a ring may lie
/// outside it: an oblique or oval band deviates along its whole length, a
/// twig beside a round stem stands out.
const RING_TOLERANCE_MADS: f32 = 3.0;

/// Rebuilds the sections with the points marked `outside` their ring taken
/// out of it: they form sections of their own, joined by graph edges among
/// themselves (no longer than `max_link_m`) within their bin's section. A twig that runs along its stem's
/// bark leaves the stem's ring here instead of bending its node.
fn split_off_outside(
    graph: &Graph,
    outside: &[bool],
    max_link_m: f32,
    wide: &mut UnionFind,
    joined: &mut UnionFind,
) -> UnionFind {
    let n = outside.len();
    let mut split = UnionFind::new(n);
    // First non-outside member of each joined section: outside points may
    // share a fine piece with the bark, so they must not be its root.
    let mut kept = vec![u32::MAX; n];
    for i in 0..n as u32 {
        if outside[i as usize] {
            let r = wide.find(i);
            for &(w, length) in graph.neighbours(i as usize) {
                if outside[w as usize] && length <= max_link_m && wide.find(w) == r {
                    split.union(i, w);
                }
            }
        } else {
            let r = joined.find(i) as usize;
            if kept[r] == u32::MAX {
                kept[r] = i;
            } else {
                split.union(kept[r], i);
            }
        }
    }
    split
}

/// Joins the points of each bin that graph edges no longer than
/// `max_link_m` connect through points of the neighbouring bins, `window`
/// bins either way.
///
/// A bin of a thick stem is a thin band around the bark whose circumference
/// is long compared with the point spacing: the nearest-neighbour edges
/// inside the band alone leave it in pieces, and each piece would become a
/// node on the bark. Paths through the bands just above and below close the
/// ring, while a twig still parts from its stem once no path within the
/// window joins them: forks are found at most `window` bins late, and the
/// nodes keep the fine bins' resolution along the branches.
fn join_within_windows(
    graph: &Graph,
    bin: &[u32],
    window: u32,
    max_link_m: f32,
    uf: &mut UnionFind,
) {
    let n = bin.len();
    let mut by_bin: Vec<u32> = (0..n as u32).collect();
    by_bin.sort_unstable_by_key(|&v| bin[v as usize]);
    // Start of each bin's run in `by_bin`.
    let last = bin.iter().copied().max().unwrap_or(0) as usize;
    let mut start = vec![0usize; last + 2];
    for &v in &by_bin {
        start[bin[v as usize] as usize + 1] += 1;
    }
    for b in 1..start.len() {
        start[b] += start[b - 1];
    }
    let mut local = vec![u32::MAX; n];
    for b in 0..=last {
        let lo = start[b.saturating_sub(window as usize)];
        let hi = start[(b + window as usize + 1).min(last + 1)];
        let members = &by_bin[lo..hi];
        for (k, &v) in members.iter().enumerate() {
            local[v as usize] = k as u32;
        }
        let mut window_uf = UnionFind::new(members.len());
        for (k, &v) in members.iter().enumerate() {
            for &(w, len) in graph.neighbours(v as usize) {
                let lw = local[w as usize];
                if lw != u32::MAX && len <= max_link_m {
                    window_uf.union(k as u32, lw);
                }
            }
        }
        // Points of bin `b` in one window component form one section.
        let mut first_of = vec![u32::MAX; members.len()];
        for &v in &by_bin[start[b]..start[b + 1]] {
            let c = window_uf.find(local[v as usize]) as usize;
            if first_of[c] == u32::MAX {
                first_of[c] = v;
            } else {
                uf.union(first_of[c], v);
            }
        }
        for &v in members {
            local[v as usize] = u32::MAX;
        }
    }
}

/// Moves the nodes of thick sections from the centroid to the centre of a
/// circle fitted (Kåsa) to the section's points across the branch direction.
/// A scanner sees one side of a thick branch: the centroid of that arc lies
/// towards the scanner, the circle's centre on the axis. Sections thinner
/// than `min_spread_m` or with fewer than 12 points keep the centroid, as do
/// implausible fits.
fn centre_on_arcs(points: &[Vec3], members: &[Vec<u32>], nodes: &mut [Node], min_spread_m: f32) {
    for id in 1..nodes.len() {
        let (spread, centroid) = (nodes[id].radius_m, nodes[id].position);
        if members[id].len() < 12 || spread < min_spread_m {
            continue;
        }
        let section: Vec<Vec3> = members[id].iter().map(|&i| points[i as usize]).collect();
        let parent = nodes[id].parent.map_or(0, NodeId::index);
        let towards = (centroid - nodes[parent].position).normalize_or(Vec3::Z);
        let dir = band_axis(&section).map_or(towards, |a| a * a.dot(towards).signum());
        let e1 = dir.any_orthonormal_vector();
        let e2 = dir.cross(e1);
        let flat: Vec<Vec2> = section
            .iter()
            .map(|&p| {
                let d = p - centroid;
                Vec2::new(d.dot(e1), d.dot(e2))
            })
            .collect();
        let Some(circle) = kasa_fit(&flat) else {
            continue;
        };
        if circle.radius < 3.0 * spread && circle.centre.length() < 2.0 * spread {
            nodes[id].position = centroid + e1 * circle.centre.x + e2 * circle.centre.y;
        }
    }
}

/// A section whose spread along its least-spread axis stays below this share
/// of its spread along the middle axis is a flat band (see [`band_axis`]).
const BAND_FLATNESS: f64 = 0.5;

/// The axis of a section that forms a flat band across its branch (a ring or
/// a wide arc of a thick stem): the direction its points spread least along.
/// `None` when the section is not clearly flat (a short arc, a lump at a
/// fork), whose least-spread axis may point across the branch.
///
/// The direction from the parent section is no substitute on a thick stem:
/// bins are a few centimetres deep and the stem decimetres wide, so
/// successive sections' centroids jitter sideways by as much as they
/// advance, and a circle fitted across that direction threw the node up or
/// down the stem by up to its radius (folds in the trunk: 30 of 249 thick
/// internodes of the clean synthetic oak s1 turned back by more than 90°,
/// 12 with the band's axis).
pub(super) fn band_axis(section: &[Vec3]) -> Option<Vec3> {
    let [_, middle, least] = principal_spreads(section);
    (least < BAND_FLATNESS * middle)
        .then(|| least_spread_axis(section))
        .flatten()
}

/// The plane across a section's axis through its points' mean, with
/// coordinates `e1`, `e2` in it: where circles are fitted to a section.
pub(super) struct Across {
    mean: Vec3,
    e1: Vec3,
    e2: Vec3,
}

impl Across {
    pub(super) fn new(pts: &[Vec3], axis: Vec3) -> Self {
        let e1 = axis.any_orthonormal_vector();
        Self {
            mean: pts.iter().copied().sum::<Vec3>() / pts.len() as f32,
            e1,
            e2: axis.cross(e1),
        }
    }

    /// The points' coordinates in the plane.
    pub(super) fn flat(&self, pts: &[Vec3]) -> Vec<Vec2> {
        pts.iter()
            .map(|&p| Vec2::new((p - self.mean).dot(self.e1), (p - self.mean).dot(self.e2)))
            .collect()
    }

    /// The point of the plane at coordinates `q`.
    pub(super) fn lift(&self, q: Vec2) -> Vec3 {
        self.mean + self.e1 * q.x + self.e2 * q.y
    }
}

/// Per cross-section (indexed by union-find root): the point closest to the
/// base, the coordinate sums and the point count.
struct Stats {
    lowest: Vec<u32>,
    sum: Vec<DVec3>,
    sum_sq: Vec<f64>,
    count: Vec<u32>,
}

impl Stats {
    fn gather(points: &[Vec3], dist: &[f32], uf: &mut UnionFind) -> Stats {
        let n = points.len();
        let mut st = Stats {
            lowest: vec![u32::MAX; n],
            sum: vec![DVec3::ZERO; n],
            sum_sq: vec![0f64; n],
            count: vec![0u32; n],
        };
        for i in 0..n as u32 {
            let r = uf.find(i) as usize;
            let low = st.lowest[r];
            if low == u32::MAX || dist[i as usize] < dist[low as usize] {
                st.lowest[r] = i;
            }
            let p = points[i as usize].as_dvec3();
            st.sum[r] += p;
            st.sum_sq[r] += p.length_squared();
            st.count[r] += 1;
        }
        st
    }

    /// RMS distance of section `r`'s points from their centroid.
    fn spread(&self, r: usize) -> f32 {
        let c = f64::from(self.count[r].max(1));
        let mean = self.sum[r] / c;
        (self.sum_sq[r] / c - mean.length_squared()).max(0.0).sqrt() as f32
    }

    fn centroid(&self, r: usize) -> Vec3 {
        (self.sum[r] / f64::from(self.count[r].max(1))).as_vec3()
    }
}

/// Joins sections of one bin whose extents (largest distance of a point to
/// the centroid) overlap: on a thick stem the distance fronts are ragged,
/// so one cross-section of the stem falls apart into arcs, and the arcs'
/// extents overlap, while separate twigs keep apart.
fn merge_overlapping(points: &[Vec3], bin: &[u32], stats: &Stats, uf: &mut UnionFind) {
    let n = points.len();
    let mut extent = vec![0f32; n];
    for i in 0..n as u32 {
        let r = uf.find(i) as usize;
        let d = points[i as usize].distance(stats.centroid(r));
        extent[r] = extent[r].max(d);
    }
    // Sections by bin, then by centroid x for a sweep.
    let mut sections: Vec<(u32, f32, u32)> = (0..n)
        .filter(|&r| stats.count[r] > 0 && bin[stats.lowest[r] as usize] > 0)
        .map(|r| (bin[stats.lowest[r] as usize], stats.centroid(r).x, r as u32))
        .collect();
    sections.sort_by(|a, b| {
        (a.0, a.1)
            .partial_cmp(&(b.0, b.1))
            .unwrap_or(std::cmp::Ordering::Equal)
    });
    let widest = extent.iter().copied().fold(0.0, f32::max);
    for (i, &(bin_a, xa, a)) in sections.iter().enumerate() {
        let (ca, ea) = (stats.centroid(a as usize), extent[a as usize]);
        for &(bin_b, xb, b) in &sections[i + 1..] {
            if bin_b != bin_a || xb - xa > ea + widest {
                break;
            }
            let (cb, eb) = (stats.centroid(b as usize), extent[b as usize]);
            if ca.distance(cb) < ea + eb {
                uf.union(a, b);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::graph::{Graph, shortest_path_tree};
    use super::*;

    #[test]
    fn a_ring_of_points_collapses_to_its_centre() {
        // Two rings of 8 points, 0.1 m apart vertically: bin 0 holds the
        // lower ring, the upper ring becomes one node at its centre.
        let mut pts = Vec::new();
        for z in [0.0, 0.1] {
            for k in 0..8 {
                let a = k as f32 * std::f32::consts::TAU / 8.0;
                pts.push(Vec3::new(1.0 + 0.05 * a.cos(), 0.05 * a.sin(), z));
            }
        }
        let mut edges = Vec::new();
        for k in 0..8u32 {
            edges.push((k, (k + 1) % 8, 0.04));
            edges.push((8 + k, 8 + (k + 1) % 8, 0.04));
            edges.push((k, k + 8, 0.1));
        }
        let g = Graph::from_edges(pts.len(), &edges);
        let (dist, pred) = shortest_path_tree(&g, &(0..8).collect::<Vec<_>>());
        let s = cross_sections(
            &pts,
            &g,
            &dist,
            &pred,
            Vec3::new(1.0, 0.0, 0.0),
            &Sectioning {
                bin_m: 0.08,
                merge_overlapping_arcs: true,
                centre_arcs: false,
                window_bins: 0,
                thick_spread_m: 0.0,
                broken_ring_pieces: u32::MAX,
                broken_ring_spread_m: 0.0,
                ring_outlier_m: 0.0,
                max_link_m: f32::INFINITY,
                max_ring_link_m: f32::INFINITY,
                two_stems: None,
            },
        );
        assert_eq!(s.nodes.len(), 2);
        assert!(s.nodes[1].position.distance(Vec3::new(1.0, 0.0, 0.1)) < 1e-4);
        assert_eq!(s.nodes[1].parent, Some(NodeId::ROOT));
        assert_eq!(s.counts, vec![8, 8]);
    }

    /// A scanner sees half of a 0.3 m stem: one band of an arc, whose parent
    /// section lies off to the side and below (sections of a thick stem
    /// jitter). The node goes to the stem's axis within the band, not along
    /// the slanted direction from the parent, which would throw it
    /// decimetres up or down the stem.
    #[test]
    fn an_arc_is_centred_across_its_band_not_across_the_way_from_its_parent() {
        let mut points = Vec::new();
        for z in [1.0, 1.03] {
            for k in 0..=20 {
                let a = (k as f32 / 20.0 - 0.5) * std::f32::consts::PI;
                points.push(Vec3::new(0.3 * a.cos(), 0.3 * a.sin(), z));
            }
        }
        let centroid = points.iter().copied().sum::<Vec3>() / points.len() as f32;
        let mut nodes = vec![
            Node {
                position: Vec3::new(0.05, 0.0, 0.9),
                radius_m: 0.2,
                parent: None,
            },
            Node {
                position: centroid,
                radius_m: 0.2,
                parent: Some(NodeId::ROOT),
            },
        ];
        let members = vec![Vec::new(), (0..points.len() as u32).collect()];
        centre_on_arcs(&points, &members, &mut nodes, 0.06);
        let node = nodes[1].position;
        assert!(node.truncate().length() < 0.02, "{node}");
        assert!((node.z - 1.015).abs() < 0.005, "{node}");
    }

    fn stem_sections(window_bins: u32) -> Sections {
        stem_with_twig(window_bins, 0.02, &[])
    }

    /// [`stem_sections`] with `twig` points added and the ring outlier
    /// margin set.
    fn stem_with_twig(window_bins: u32, ring_outlier_m: f32, twig: &[Vec3]) -> Sections {
        use super::super::graph::knn_edges;
        use crate::spatial::PointIndex;
        // A low-discrepancy (R2) sequence over the bark: even, not a lattice.
        let mut pts: Vec<Vec3> = (0..3000)
            .map(|k| {
                let a = (k as f32 * 0.754_877_7).fract() * std::f32::consts::TAU;
                let z = (k as f32 * 0.569_840_3).fract() * 1.5;
                Vec3::new(0.4 * a.cos(), 0.4 * a.sin(), z)
            })
            .collect();
        pts.extend_from_slice(twig);
        let index = PointIndex::new(&pts);
        let g = Graph::from_edges(pts.len(), &knn_edges(&pts, &index, 6, 1.0));
        let sources: Vec<u32> = (0..pts.len() as u32)
            .filter(|&i| pts[i as usize].z < 0.03)
            .collect();
        let (dist, pred) = shortest_path_tree(&g, &sources);
        cross_sections(
            &pts,
            &g,
            &dist,
            &pred,
            Vec3::ZERO,
            &Sectioning {
                bin_m: 0.03,
                merge_overlapping_arcs: false,
                centre_arcs: false,
                window_bins,
                thick_spread_m: 0.11,
                broken_ring_pieces: 3,
                broken_ring_spread_m: 0.04,
                ring_outlier_m,
                max_link_m: f32::INFINITY,
                max_ring_link_m: f32::INFINITY,
                two_stems: None,
            },
        )
    }

    /// A sparse scan of a 0.4 m-radius stem: with fine bins each band is
    /// a thin, gappy ring. Joined through the neighbouring bins it gives one
    /// node per bin on the axis; without the window, pieces of bark do.
    #[test]
    fn a_thick_stem_gives_one_node_per_band_on_its_axis() {
        let off_axis = |s: &Sections| {
            s.nodes
                .iter()
                .filter(|n| n.position.truncate().length() > 0.1)
                .count()
        };
        let pieces = stem_sections(0);
        assert!(
            off_axis(&pieces) > 20,
            "expected bark pieces without the window"
        );
        let rings = stem_sections(1);
        // The topmost, partial band may leave a piece.
        assert!(off_axis(&rings) <= 2, "{} off-axis nodes", off_axis(&rings));
        assert!(rings.nodes.len() <= 60, "{} nodes", rings.nodes.len());
    }

    /// A 1 cm twig running up the 0.4 m stem of [`stem_sections`] 4 cm
    /// outside its bark, close enough for nearest-neighbour edges to tie it
    /// to the bark.
    fn twig_along_the_bark() -> Vec<Vec3> {
        (0..560)
            .map(|k| {
                let a = (k % 4) as f32 * std::f32::consts::FRAC_PI_2;
                let z = 0.05 + (k / 4) as f32 * 0.01;
                Vec3::new(0.45 + 0.01 * a.cos(), 0.01 * a.sin(), z)
            })
            .collect()
    }

    /// Nodes on the axis of [`twig_along_the_bark`].
    fn twig_nodes(s: &Sections) -> usize {
        s.nodes
            .iter()
            .filter(|n| {
                let p = n.position;
                (0.3..1.3).contains(&p.z) && p.truncate().distance(Vec2::new(0.45, 0.0)) < 0.03
            })
            .count()
    }

    /// Split off its ring, the twig keeps its own nodes along its axis; left
    /// in the ring, it only drags the stem's nodes sideways.
    #[test]
    fn a_twig_along_the_bark_leaves_the_stems_ring() {
        let twig = twig_along_the_bark();
        let split = stem_with_twig(1, 0.02, &twig);
        assert!(
            twig_nodes(&split) >= 20,
            "{} twig nodes",
            twig_nodes(&split)
        );
        let kept = stem_with_twig(1, 0.0, &twig);
        assert!(twig_nodes(&kept) <= 3, "{} twig nodes", twig_nodes(&kept));
    }

    /// Across the stem from the twig, a lump of three points 5 cm outside
    /// the bark, as a piece of a fork's crotch or of a limb's first arc is
    /// while the limb still parts from the ring: nothing grows from it, so
    /// it stays in the stem's ring instead of becoming a stub out of the
    /// stem, and the twig still leaves.
    #[test]
    fn a_lump_on_the_bark_stays_in_the_stems_ring() {
        let mut points = twig_along_the_bark();
        points.extend([
            Vec3::new(-0.45, 0.0, 0.7),
            Vec3::new(-0.45, 0.01, 0.705),
            Vec3::new(-0.451, -0.01, 0.71),
        ]);
        let s = stem_with_twig(1, 0.02, &points);
        let stubs: Vec<Vec3> = s
            .nodes
            .iter()
            .map(|n| n.position)
            .filter(|p| p.truncate().distance(Vec2::new(-0.45, 0.0)) < 0.05)
            .collect();
        assert!(stubs.is_empty(), "stub nodes at the lump: {stubs:?}");
        assert!(twig_nodes(&s) >= 20, "{} twig nodes", twig_nodes(&s));
    }
}
