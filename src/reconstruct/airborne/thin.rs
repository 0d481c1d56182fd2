//! Thinning in voxel space: Hu et al. §5.1.
//!
//! The tree points are binned into voxels of pitch d_l; every occupied
//! ("black") voxel becomes one point at the mean of its points. A sequential
//! thinning then deletes black voxels that do not change the topology of the
//! black set — *simple* voxels under (26, 6) connectivity — peeling from the
//! six face directions in turn so the remainder stays centred, and keeping
//! curve end voxels so branches do not shrink. What remains are the
//! candidate skeleton points of the graph. On sparse airborne data most
//! voxels are isolated and survive; on denser crowns thinning removes the
//! bulk of the interior.
//!
//! [`contract`] then moves each candidate to the mean of the points around
//! it, which §5.1 does not do; see `Params::contraction_radius_m`.

use glam::{IVec3, Vec3};

use crate::reconstruct::principal_spreads;
use crate::reconstruct::radii::median;
use crate::spatial::PointIndex;

/// Offsets of the 26 neighbours and the centre, indexed `(dx+1)·9 + (dy+1)·3
/// + (dz+1)`; index 13 is the centre.
const CENTRE: usize = 13;

/// The six face directions, in the peeling order of the subiterations.
const FACES: [IVec3; 6] = [
    IVec3::new(0, 0, 1),
    IVec3::new(0, 0, -1),
    IVec3::new(1, 0, 0),
    IVec3::new(-1, 0, 0),
    IVec3::new(0, 1, 0),
    IVec3::new(0, -1, 0),
];

/// Candidate skeleton points of `points`: voxel means of the black voxels
/// left by sequential thinning at pitch `voxel_m` (§5.1). Sorted by voxel,
/// so the result does not depend on hashing.
pub(super) fn thin(points: &[Vec3], voxel_m: f32) -> Vec<Vec3> {
    let Some(origin) = points.iter().copied().reduce(Vec3::min) else {
        return Vec::new();
    };
    // Sorted by voxel (then input order), each voxel's points form one run.
    let mut keyed: Vec<((i32, i32, i32), u32)> = (points.iter().enumerate())
        .map(|(i, &p)| {
            // `as` saturates: absurd extents merge into edge voxels, no overflow.
            let k = ((p - origin) / voxel_m).floor().as_ivec3();
            ((k.z, k.y, k.x), i as u32)
        })
        .collect();
    keyed.sort_unstable();
    let voxels: Vec<(IVec3, Vec3)> = keyed
        .chunk_by(|a, b| a.0 == b.0)
        .map(|run| {
            let (z, y, x) = run[0].0;
            let sum: Vec3 = run.iter().map(|&(_, i)| points[i as usize]).sum();
            (IVec3::new(x, y, z), sum / run.len() as f32)
        })
        .collect();
    let Some(mut black) = Occupancy::new(voxels.iter().map(|(k, _)| *k)) else {
        // Absurd extents (hostile input): keep the downsampled voxels.
        return voxels.into_iter().map(|(_, p)| p).collect();
    };
    let masks = Masks::new();
    let cells: Vec<usize> = voxels.iter().map(|(k, _)| black.cell(*k)).collect();
    let faces = FACES.map(|f| black.offset(f));
    loop {
        let mut deleted = 0;
        for face in faces {
            for &cell in &cells {
                if black.is_black(cell) && !black.is_black(cell.wrapping_add_signed(face)) {
                    let here = black.neighbourhood(cell);
                    if masks.is_deletable(here) {
                        black.black[cell] = false;
                        deleted += 1;
                    }
                }
            }
        }
        if deleted == 0 {
            break;
        }
    }
    voxels
        .into_iter()
        .zip(cells)
        .filter(|&(_, cell)| black.is_black(cell))
        .map(|((_, p), _)| p)
        .collect()
}

/// Most cells of the dense occupancy grid (64 MB); a tree clip at 0.2 m
/// needs well under a million.
const MAX_GRID_CELLS: usize = 1 << 26;

/// Black/white voxels in a dense grid over the occupied box: thinning looks
/// up 27 neighbours per voxel and pass, which a hash map makes the slowest
/// stage. The box is padded by one white voxel on every side, so that every
/// neighbour of an occupied voxel is a cell of the grid, a fixed step away
/// in memory: the lookups need no bounds test.
struct Occupancy {
    /// Cells per axis, padding included.
    dims: IVec3,
    black: Vec<bool>,
    /// Step in `black` to each position of the 3×3×3 neighbourhood.
    steps: [isize; 27],
}

impl Occupancy {
    /// The grid with `keys` (all non-negative) black; `None` when the
    /// grid, padding included, would exceed [`MAX_GRID_CELLS`].
    fn new(keys: impl Iterator<Item = IVec3> + Clone) -> Option<Self> {
        let cells = |dims: IVec3| {
            (dims.x as usize)
                .checked_mul(dims.y as usize)?
                .checked_mul(dims.z as usize)
                .filter(|&n| n <= MAX_GRID_CELLS)
        };
        let occupied = keys.clone().fold(IVec3::ZERO, IVec3::max) + 1;
        // The occupied box first: it bounds each axis, so the padding
        // cannot overflow. A thin box grows most with its padding (a
        // column 1 × 1 × n voxels takes 9n cells).
        cells(occupied)?;
        let dims = occupied + 2;
        let mut grid = Self {
            dims,
            black: vec![false; cells(dims)?],
            steps: [0; 27],
        };
        grid.steps = OFFSETS.map(|o| grid.offset(o));
        for k in keys {
            let cell = grid.cell(k);
            grid.black[cell] = true;
        }
        Some(grid)
    }

    /// The cell of the occupied voxel `k` (inside the occupied box).
    fn cell(&self, k: IVec3) -> usize {
        let k = k + 1;
        (k.z as usize * self.dims.y as usize + k.y as usize) * self.dims.x as usize + k.x as usize
    }

    /// The step in cells to the voxel `offset` away.
    fn offset(&self, offset: IVec3) -> isize {
        let (x, y) = (self.dims.x as isize, self.dims.y as isize);
        (offset.z as isize * y + offset.y as isize) * x + offset.x as isize
    }

    fn is_black(&self, cell: usize) -> bool {
        self.black[cell]
    }

    /// The 3×3×3 neighbourhood of the occupied voxel at `cell` as a 27-bit
    /// occupancy mask (centre excluded).
    fn neighbourhood(&self, cell: usize) -> u32 {
        let mut mask = 0u32;
        for (i, &step) in self.steps.iter().enumerate() {
            if i != CENTRE && self.black[cell.wrapping_add_signed(step)] {
                mask |= 1 << i;
            }
        }
        mask
    }
}

/// One contraction step: each candidate moves to the mean of the tree
/// points within `radius_m` of it (unchanged when `radius_m` is 0 or it has
/// no such points). See `Params::contraction_radius_m`.
pub(super) fn contract(candidates: &[Vec3], tree: &[Vec3], radius_m: f32) -> Vec<Vec3> {
    if radius_m <= 0.0 {
        return candidates.to_vec();
    }
    let index = PointIndex::new(tree);
    candidates
        .iter()
        .map(|&c| {
            let near = index.within(c, radius_m);
            if near.is_empty() {
                c
            } else {
                near.iter().map(|n| tree[n.index]).sum::<Vec3>() / near.len() as f32
            }
        })
        .collect()
}

/// Fewest candidates around one for its linearity in [`crown_linearity`].
const MIN_LINEARITY_NEIGHBOURS: usize = 5;

/// The median linearity `1 − σ₂²/σ₁²` (σ: spreads along the principal axes)
/// of the candidates within `radius_m` of each candidate in the crown's
/// upper 60 % by height, or `None` without any such neighbourhood. Twigs
/// seen bare give lines (near 1); foliage gives clumps (near 0.5 for a
/// scatter that fills a disc or ball). See `Params::bare_crown_linearity`.
pub(super) fn crown_linearity(candidates: &[Vec3], radius_m: f32) -> Option<f32> {
    let (lo, hi) = candidates.iter().fold((f32::MAX, f32::MIN), |(lo, hi), p| {
        (lo.min(p.z), hi.max(p.z))
    });
    let floor = lo + 0.4 * (hi - lo);
    let crown: Vec<Vec3> = candidates.iter().copied().filter(|p| p.z > floor).collect();
    let index = PointIndex::new(&crown);
    let mut linearity: Vec<f32> = crown
        .iter()
        .filter_map(|&c| {
            let near: Vec<Vec3> = index
                .within(c, radius_m)
                .iter()
                .map(|n| crown[n.index])
                .collect();
            if near.len() < MIN_LINEARITY_NEIGHBOURS {
                return None;
            }
            let [first, second, _] = principal_spreads(&near);
            (first > 0.0).then(|| (1.0 - (second / first).powi(2)) as f32)
        })
        .collect();
    (!linearity.is_empty()).then(|| median(&mut linearity))
}

fn offsets() -> impl Iterator<Item = IVec3> {
    OFFSETS.into_iter()
}

/// The 3×3×3 neighbourhood's offsets, indexed as [`CENTRE`] states.
/// A table: thinning asks for them 26 times per voxel and sweep.
const OFFSETS: [IVec3; 27] = {
    let mut table = [IVec3::ZERO; 27];
    let mut i = 0;
    while i < 27 {
        table[i] = IVec3::new(i as i32 / 9 - 1, (i as i32 / 3) % 3 - 1, i as i32 % 3 - 1);
        i += 1;
    }
    table
};

/// Precomputed adjacency masks of the 27 neighbourhood positions.
struct Masks {
    /// 26-adjacent positions of each position.
    adj26: [u32; 27],
    /// 6-adjacent positions of each position.
    adj6: [u32; 27],
    /// The 18-neighbourhood of the centre (face and edge neighbours).
    n18: u32,
    /// The 6 face neighbours of the centre.
    n6: u32,
}

impl Masks {
    fn new() -> Self {
        let pos: Vec<IVec3> = offsets().collect();
        let mut adj26 = [0u32; 27];
        let mut adj6 = [0u32; 27];
        for i in 0..27 {
            for j in 0..27 {
                let d = (pos[i] - pos[j]).abs();
                if i != j && d.max_element() <= 1 {
                    adj26[i] |= 1 << j;
                    if d.element_sum() == 1 {
                        adj6[i] |= 1 << j;
                    }
                }
            }
        }
        let n18 = (0..27)
            .filter(|&i| i != CENTRE && pos[i].abs().element_sum() <= 2)
            .fold(0, |m, i| m | 1 << i);
        Self {
            adj26,
            adj6,
            n18,
            n6: adj6[CENTRE],
        }
    }

    /// A black voxel may go when it is simple and not a curve end: its black
    /// 26-neighbours form one 26-component, its white 18-neighbours form one
    /// 6-component touching a face, and it has at least two black neighbours.
    fn is_deletable(&self, black: u32) -> bool {
        if black.count_ones() < 2 {
            return false;
        }
        if self.components(black, &self.adj26, u32::MAX) != 1 {
            return false;
        }
        let white = !black & self.n18;
        self.components(white, &self.adj6, self.n6) == 1
    }

    /// Number of connected components of `set` (under `adj`) that contain a
    /// position of `must_touch`.
    fn components(&self, set: u32, adj: &[u32; 27], must_touch: u32) -> u32 {
        let mut left = set;
        let mut count = 0;
        while left != 0 {
            let mut comp = 1u32 << left.trailing_zeros();
            loop {
                let mut grow = comp;
                let mut bits = comp;
                while bits != 0 {
                    let i = bits.trailing_zeros() as usize;
                    grow |= adj[i] & set;
                    bits &= bits - 1;
                }
                if grow == comp {
                    break;
                }
                comp = grow;
            }
            left &= !comp;
            if comp & must_touch != 0 {
                count += 1;
            }
        }
        count
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Returns along twigs give lines (linearity near 1); a clump that
    /// fills a block gives far less (0.33 here: the crown's upper 60 % cut
    /// its lower layers off).
    #[test]
    fn twigs_are_linear_and_clumps_are_not() {
        let twigs: Vec<Vec3> = (0..40)
            .flat_map(|t| {
                let s = t as f32 * 0.15;
                [
                    Vec3::new(s, 0.0, 5.0 + s),
                    Vec3::new(0.0, 3.0 + s, 5.0 + 0.5 * s),
                ]
            })
            .collect();
        let linear = crown_linearity(&twigs, 0.6).expect("neighbourhoods");
        assert!(linear > 0.95, "twigs {linear}");
        let mut clump = Vec::new();
        for x in -3..=3 {
            for y in -3..=3 {
                for z in -3..=3 {
                    clump.push(Vec3::new(x as f32, y as f32, 10.0 + z as f32) * 0.2);
                }
            }
        }
        let round = crown_linearity(&clump, 0.6).expect("neighbourhoods");
        assert!(round < 0.5, "clump {round}");
        assert_eq!(crown_linearity(&clump[..3], 0.6), None);
    }

    #[test]
    fn a_solid_block_thins_to_a_few_voxels_and_a_line_survives() {
        let mut block = Vec::new();
        for x in 0..5 {
            for y in 0..5 {
                for z in 0..5 {
                    block.push(Vec3::new(x as f32, y as f32, z as f32) * 0.2 + 0.1);
                }
            }
        }
        let thinned = thin(&block, 0.2);
        assert!(
            !thinned.is_empty() && thinned.len() < 20,
            "{}",
            thinned.len()
        );
        let line: Vec<Vec3> = (0..10)
            .map(|z| Vec3::new(0.1, 0.1, z as f32 * 0.2 + 0.1))
            .collect();
        assert_eq!(thin(&line, 0.2).len(), 10);
    }

    #[test]
    fn isolated_voxels_are_kept_and_averaged() {
        let pts = [
            Vec3::new(0.01, 0.01, 0.01),
            Vec3::new(0.03, 0.03, 0.03),
            Vec3::splat(2.0),
        ];
        let thinned = thin(&pts, 0.2);
        assert_eq!(thinned.len(), 2);
        assert!(thinned.iter().any(|p| p.distance(Vec3::splat(0.02)) < 1e-6));
    }
}
