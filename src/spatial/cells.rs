//! Every point's nearest neighbours at once, through a grid of cubic cells.
//!
//! The dense graph (lsystem-from-adtree-skeletons §2.1.1) asks every point of
//! a cloud for its `k` nearest neighbours. One kd-tree query per point
//! descends the tree again for each point, although the points of one small
//! cell share nearly all of their candidates: on tree1 those queries were a
//! quarter of the dense pipeline's time. Here the points are sorted by cell,
//! each cell gathers the points of its 3 × 3 × 3 block once, and each of its
//! points ranks those candidates. A point's answer is certain when its `k`-th
//! neighbour lies nearer than the nearest face of the block that has points
//! beyond it; [`super::PointIndex::each_nearest_k_within`] asks the kd-tree
//! for the rest (an outlier, a sparse patch), so the answers are exactly the
//! kd-tree's.

use std::ops::Range;

use foldhash::{HashMap, HashMapExt};
use glam::Vec3;

use super::Neighbour;

/// Points sorted by the cell they fall in.
pub(super) struct CellGrid {
    /// Cell edge in metres.
    cell_m: f32,
    /// Corner of cell (0, 0, 0).
    lo: Vec3,
    /// Cells along x, y and z.
    dims: [u64; 3],
    /// Each sorted point's cell key, `x + nx·(y + ny·z)`, ascending.
    keys: Vec<u64>,
    /// Each sorted point's index in the input slice.
    order: Vec<u32>,
    /// Each sorted point's coordinates, by axis.
    sorted: [Vec<f32>; 3],
    /// The sorted points of each occupied row of cells along x, by the
    /// row's key `y + ny·z`.
    rows: HashMap<u64, Range<usize>>,
    /// What rounding may move a point across a cell face, in metres.
    slack_m: f32,
}

/// One occupied cell: its coordinates and its run of sorted points.
pub(super) struct Cell {
    at: [u64; 3],
    points: Range<usize>,
}

/// The candidates of one cell's block, by coordinate (so that the distances
/// to all of them compute in one vectorisable loop), and reusable buffers.
#[derive(Default)]
pub(super) struct Scratch {
    x: Vec<f32>,
    y: Vec<f32>,
    z: Vec<f32>,
    index: Vec<u32>,
    distance_sq: Vec<f32>,
    ranks: Vec<u64>,
    /// The last point's answer.
    nearest: Vec<Neighbour>,
}

/// Cells along one axis at most; past it the grid is not built.
const MAX_CELLS_PER_AXIS: f32 = (1u32 << 20) as f32;

impl CellGrid {
    /// The grid of `points` with cells `cell_m` wide, or `None` when the
    /// cell is not a positive length, there are no points, or an axis would
    /// have more than 2^20 cells.
    pub(super) fn new(points: &[Vec3], cell_m: f32) -> Option<Self> {
        if !(cell_m > 0.0 && cell_m.is_finite()) || points.is_empty() {
            return None;
        }
        let lo = points.iter().copied().fold(Vec3::INFINITY, Vec3::min);
        let hi = points.iter().copied().fold(Vec3::NEG_INFINITY, Vec3::max);
        let span = ((hi - lo) / cell_m).floor() + Vec3::ONE;
        if !span.is_finite() || span.max_element() > MAX_CELLS_PER_AXIS {
            return None;
        }
        let grid = Self {
            cell_m,
            lo,
            dims: span.to_array().map(|n| n as u64),
            keys: Vec::new(),
            order: Vec::new(),
            sorted: [Vec::new(), Vec::new(), Vec::new()],
            rows: HashMap::new(),
            slack_m: 16.0 * f32::EPSILON * (lo.abs().max(hi.abs()).max_element() + cell_m),
        };
        Some(grid.filled(points))
    }

    fn filled(mut self, points: &[Vec3]) -> Self {
        let mut keyed: Vec<(u64, u32)> = points
            .iter()
            .enumerate()
            .map(|(i, &p)| (self.key(self.cell_of(p)), i as u32))
            .collect();
        keyed.sort_unstable();
        self.keys = keyed.iter().map(|&(key, _)| key).collect();
        self.order = keyed.iter().map(|&(_, i)| i).collect();
        self.sorted =
            [0, 1, 2].map(|a| self.order.iter().map(|&i| points[i as usize][a]).collect());
        let mut start = 0;
        while start < self.keys.len() {
            let row = self.keys[start] / self.dims[0];
            let end = start + self.keys[start..].partition_point(|&k| k / self.dims[0] == row);
            self.rows.insert(row, start..end);
            start = end;
        }
        self
    }

    fn cell_of(&self, p: Vec3) -> [u64; 3] {
        let at = ((p - self.lo) / self.cell_m).floor().to_array();
        [0, 1, 2].map(|a| (at[a].max(0.0) as u64).min(self.dims[a] - 1))
    }

    /// The position of the `s`-th sorted point.
    fn position(&self, s: usize) -> Vec3 {
        Vec3::new(self.sorted[0][s], self.sorted[1][s], self.sorted[2][s])
    }

    /// The cell whose key is `key` (the inverse of [`Self::key`]).
    fn cell_at(&self, key: u64) -> [u64; 3] {
        let [nx, ny, _] = self.dims;
        [key % nx, key / nx % ny, key / nx / ny]
    }

    /// The key of cell `[x, y, z]`, `x + nx·(y + ny·z)`: keys order cells
    /// by z, then y, then x, so a row of cells along x is one run.
    fn key(&self, [x, y, z]: [u64; 3]) -> u64 {
        x + self.dims[0] * (y + self.dims[1] * z)
    }

    /// The occupied cells, each once.
    pub(super) fn cells(&self) -> impl Iterator<Item = Cell> + '_ {
        let mut start = 0;
        std::iter::from_fn(move || {
            let key = *self.keys.get(start)?;
            let end = start + self.keys[start..].partition_point(|&k| k == key);
            let cell = Cell {
                at: self.cell_at(key),
                points: start..end,
            };
            start = end;
            Some(cell)
        })
    }

    /// Gathers the points of the cell's 3 × 3 × 3 block into `scratch`.
    fn gather_block(&self, cell: &Cell, scratch: &mut Scratch) {
        let [x, y, z] = cell.at;
        let (nx, ny, nz) = (self.dims[0], self.dims[1], self.dims[2]);
        let (first_x, last_x) = (x.saturating_sub(1), (x + 1).min(nx - 1));
        scratch.x.clear();
        scratch.y.clear();
        scratch.z.clear();
        scratch.index.clear();
        for row_z in z.saturating_sub(1)..=(z + 1).min(nz - 1) {
            for row_y in y.saturating_sub(1)..=(y + 1).min(ny - 1) {
                let row_key = row_y + ny * row_z;
                let Some(row) = self.rows.get(&row_key) else {
                    continue;
                };
                let keys = &self.keys[row.clone()];
                let from = row.start + keys.partition_point(|&k| k % nx < first_x);
                let to = row.start + keys.partition_point(|&k| k % nx <= last_x);
                scratch.x.extend_from_slice(&self.sorted[0][from..to]);
                scratch.y.extend_from_slice(&self.sorted[1][from..to]);
                scratch.z.extend_from_slice(&self.sorted[2][from..to]);
                scratch.index.extend_from_slice(&self.order[from..to]);
            }
        }
    }

    /// How far `p`, in `cell`, lies from the nearest face of the block that
    /// has cells beyond it (less the rounding slack): every point outside
    /// the block is at least this far. Infinite when the block covers the
    /// grid.
    fn clearance(&self, cell: &Cell, p: Vec3) -> f32 {
        let mut clear = f32::INFINITY;
        for a in 0..3 {
            let at = cell.at[a];
            if at >= 2 {
                let face = self.lo[a] + (at - 1) as f32 * self.cell_m;
                clear = clear.min(p[a] - face);
            }
            if at + 2 < self.dims[a] {
                let face = self.lo[a] + (at + 2) as f32 * self.cell_m;
                clear = clear.min(face - p[a]);
            }
        }
        clear - self.slack_m
    }

    /// For every point of `cell`, its `k` nearest other points within
    /// `radius` (closest first, equal distances by index), when the block
    /// makes them certain: `visit(index, neighbours)` gets each certain
    /// answer and `unsure(index)` each other point.
    pub(super) fn nearest_k_within(
        &self,
        cell: &Cell,
        (k, radius): (usize, f32),
        scratch: &mut Scratch,
        mut visit: impl FnMut(usize, &[Neighbour]),
        mut unsure: impl FnMut(usize),
    ) {
        self.gather_block(cell, scratch);
        // A point of this cell already answered, and its k-th distance.
        let mut answered: Option<(Vec3, f32)> = None;
        for s in cell.points.clone() {
            let (me, p) = (self.order[s], self.position(s));
            // Only candidates within a bound are ranked. Any bound gives the
            // right answer: the k nearest within it are the k nearest, and a
            // bound holding fewer than k is widened to the radius. This one
            // holds k: by the triangle inequality, `p`'s k-th neighbour is
            // no farther than the answered point's plus the way to it (the
            // factor covers rounding).
            let bound = answered.map_or(radius, |(q, reach)| {
                ((reach + q.distance(p)) * (1.0 + 1e-5)).min(radius)
            });
            scratch.measure_from(p);
            scratch.rank_nearest(me, k, bound);
            if scratch.nearest.len() < k && bound < radius {
                scratch.rank_nearest(me, k, radius);
            }
            let reach = (scratch.nearest.len() == k).then(|| scratch.nearest[k - 1].distance_sq);
            answered = reach.map(|d| (p, d.sqrt()));
            let clear = self.clearance(cell, p);
            let certain = reach.is_some_and(|d| d < clear * clear) || clear > radius;
            if clear > 0.0 && certain {
                visit(me as usize, &scratch.nearest);
            } else {
                unsure(me as usize);
            }
        }
    }
}

impl Scratch {
    /// The squared distance from `p` to each gathered candidate.
    fn measure_from(&mut self, p: Vec3) {
        self.distance_sq.clear();
        let coords = self.x.iter().zip(&self.y).zip(&self.z);
        self.distance_sq.extend(coords.map(|((&x, &y), &z)| {
            let (dx, dy, dz) = (x - p.x, y - p.y, z - p.z);
            dx * dx + dy * dy + dz * dz
        }));
    }

    /// The `k` nearest measured candidates within `within`, point `me`
    /// left out, closest first and equal distances by index, into
    /// [`Self::nearest`].
    fn rank_nearest(&mut self, me: u32, k: usize, within: f32) {
        let within_sq = within * within;
        // Branch-free compaction: every candidate is written, and the
        // length only grows past those that qualify (a branch per candidate
        // mispredicted about as often as it was taken).
        self.ranks.resize(self.index.len(), 0);
        let mut kept = 0;
        for (&distance_sq, &j) in self.distance_sq.iter().zip(&self.index) {
            self.ranks[kept] = rank(distance_sq, j);
            kept += usize::from(distance_sq <= within_sq && j != me);
        }
        self.ranks.truncate(kept);
        if self.ranks.len() > k {
            self.ranks.select_nth_unstable(k - 1);
            self.ranks.truncate(k);
        }
        self.ranks.sort_unstable();
        self.nearest.clear();
        self.nearest.extend(self.ranks.iter().map(|&r| unrank(r)));
    }
}

/// A neighbour as one integer that orders by distance and then by index:
/// the bits of a non-negative `f32` order as the number does.
fn rank(distance_sq: f32, index: u32) -> u64 {
    (u64::from(distance_sq.to_bits()) << 32) | u64::from(index)
}

fn unrank(rank: u64) -> Neighbour {
    Neighbour {
        index: (rank & u64::from(u32::MAX)) as usize,
        distance_sq: f32::from_bits((rank >> 32) as u32),
    }
}
