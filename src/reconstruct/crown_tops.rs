//! Two crowns in one clip: the canopy's tops, and how deep the canopy dips
//! between them.
//!
//! A clip cut around one tree of a row or a park often holds the crown of a
//! neighbour that touches it. [`super::parts`] refuses a clip whose parts
//! lie metres apart; crowns that touch form one part, and the airborne
//! pipeline reconstructs them as one tree with one trunk. Seen from above
//! they still show two tops with the canopy low between them, whereas a
//! single crown, however broad, slopes down from one top. Not in Hu et al.;
//! a canopy height model with local maxima is the usual start of
//! individual tree detection from airborne LiDAR.
//!
//! [`two_crowns`] grids the highest return per cell (height above the
//! terrain), smooths the grid, takes as tops the cells highest within
//! [`TOP_WINDOW_M`] and at least [`MIN_TOP_SHARE`] as high as the highest,
//! and for every two tops [`MIN_APART_M`] or more apart measures the lowest
//! canopy on the straight line between them: its dip below the lower top,
//! as a share of that top's height. A dip of [`TWO_CROWNS_DIP`] or more
//! makes the airborne pipeline add a best-effort note.
//!
//! Measured (2026-12-07, release build). Single trees: of 1,400 synthetic
//! AHN-like clips (`silva eval --synthetic 100 --scan als --repeat 1` with
//! `--seed` 1, 101, 401 and 1001 at 20 returns per m², 901 at 30, 501, 1101
//! and 101 at 10, 601 and 1 at 5, 701 and 1 at 2, 801 leaf-on, 1201 leaf-on
//! at 5) none got the note, nor did any cloud of `/work/shared/data`. Two
//! trees: 60 random pairs of seeds 1001–1100 (`silva synth --scan als`,
//! each clip's ground kept on its own side, `silva reconstruct --mode
//! airborne`) with their trunks 6, 8, 10, 12 and 15 m apart got the note in
//! 15, 33, 47, 47 and 31 cases and were refused as separate parts in 0, 1,
//! 5, 8 and 28; before, only the refusals told them from one tree. So most
//! crowns that touch with trunks 10 m or more apart are flagged, about half
//! at 8 m, a quarter at 6 m.
//!
//! The settings were chosen on a Python prototype of this function (single
//! clips of seeds 1–400 at 20 returns per m², of seeds 1–100 at 2, 5, 10
//! and 40, leaf-on and on a 15° slope; 120 pairs of seeds 1–400, 6–12 m
//! apart) and on the first runs of this one: with 4 returns per cell three
//! sparse oaks (2 and 10 returns per m²) dipped 0.2–0.5 alone, and with
//! tops down to half the highest the low side limb of a 21 m oak (seed 409)
//! made a second top. The values below flag none of them, and 31, 83, 108
//! and 113 of the 120 prototype pairs at 6, 8, 10 and 12 m instead of 39,
//! 94, 110 and 117. Of the single clips above, those of seeds 501 and on
//! (800) and the pairs of seeds 1001–1100 played no part in the choice.

use glam::Vec3;

/// Canopy below this height above the terrain is not crown (metres): stems,
/// shrubs, ground noise.
const CANOPY_MIN_M: f32 = 1.0;

/// Smallest grid cell (metres). Sparser clips get larger cells, so that a
/// cell holds about [`RETURNS_PER_CELL`] returns and gaps between returns
/// do not read as dips.
const MIN_CELL_M: f32 = 0.5;

/// Returns per grid cell aimed at (see [`MIN_CELL_M`]); with 4, sparse
/// leaf-off oaks (2 and 10 returns per m²) showed holes as dips.
const RETURNS_PER_CELL: f32 = 8.0;

/// Standard deviation of the Gaussian that smooths the grid (metres).
const SMOOTHING_M: f32 = 1.0;

/// A top is the highest cell within this distance along each axis
/// (metres): a window of 7 m × 7 m, about a crown, so that the twigs of one
/// crown do not make tops of their own (with 2.5 m, three of 900 single
/// clips, sparse oaks, dipped 0.2–0.34 in the prototype).
const TOP_WINDOW_M: f32 = 3.5;

/// Tops lower than this share of the highest are not compared: with half,
/// the low side limb of a 21 m oak made a second top 9.9 m high.
const MIN_TOP_SHARE: f32 = 0.6;

/// Tops nearer than this are one crown's (metres).
const MIN_APART_M: f32 = 4.0;

/// A dip of at least this share of the lower top's height makes two
/// crowns (see the module docs).
pub(crate) const TWO_CROWNS_DIP: f32 = 0.2;

/// Most tops compared, highest first: a clip of one or two trees has a
/// few; the cap bounds the pairs of a hostile flat canopy. (Without it and
/// the suppression of ties in [`Grid::tops`], a 120 m × 120 m flat roof
/// 10 m over a ground grid took 139 s to reconstruct on a loaded machine,
/// against 1.7 s for the build before this module; with them 1.19 s, as
/// that build on an idle machine, 1.19–1.25 s.)
const MAX_TOPS: usize = 32;

/// Grids larger than this many cells are not searched (a clip hundreds of
/// metres wide is refused as too large before).
const MAX_CELLS: usize = 4_000_000;

/// The two tops with the deepest canopy dip between them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct TwoTops {
    /// Horizontal distance between the tops (metres).
    pub(crate) apart_m: f32,
    /// Height of the lower top above the terrain (smoothed, metres).
    pub(crate) lower_top_m: f32,
    /// Lowest smoothed canopy height on the line between them (metres).
    pub(crate) saddle_m: f32,
}

impl TwoTops {
    /// The dip between the tops as a share of the lower top's height.
    pub(crate) fn dip(&self) -> f32 {
        1.0 - self.saddle_m / self.lower_top_m
    }

    /// The note of a clip whose crown looks like two.
    pub(crate) fn note(&self) -> String {
        format!(
            "best effort: the canopy has two tops {:.1} m apart and dips {:.0} % between them \
             ({:.1} m, the lower top {:.1} m above the ground): the clip may hold two trees \
             whose crowns touch, reconstructed as one (silva reconstructs one tree per clip; \
             cut the clip to one crown)",
            self.apart_m,
            100.0 * self.dip(),
            self.saddle_m,
            self.lower_top_m
        )
    }
}

/// The pair of tops with the deepest dip between them, of `heights` (x and
/// y, and z as the height above the terrain); `None` when the canopy has
/// fewer than two tops far enough apart.
pub(crate) fn two_crowns(heights: &[Vec3]) -> Option<TwoTops> {
    let canopy: Vec<Vec3> = heights
        .iter()
        .copied()
        .filter(|p| p.z > CANOPY_MIN_M && p.is_finite())
        .collect();
    let grid = Grid::highest(&canopy)?.smoothed(SMOOTHING_M);
    let tops = grid.tops(TOP_WINDOW_M, MIN_TOP_SHARE);
    let mut deepest: Option<TwoTops> = None;
    for (i, &a) in tops.iter().enumerate() {
        for &b in &tops[i + 1..] {
            let pair = grid.between(a, b);
            if pair.apart_m >= MIN_APART_M && deepest.is_none_or(|d| pair.dip() > d.dip()) {
                deepest = Some(pair);
            }
        }
    }
    deepest
}

/// A square grid of canopy heights over the clip, row-major.
struct Grid {
    cell_m: f32,
    columns: usize,
    rows: usize,
    height: Vec<f32>,
}

impl Grid {
    /// The highest return per cell (0 where a cell has none), with a margin
    /// of empty cells as wide as the smoothing reaches.
    fn highest(canopy: &[Vec3]) -> Option<Self> {
        let cell_m = cell_size(canopy)?;
        let (min, max) = canopy.iter().fold(
            (
                glam::Vec2::splat(f32::INFINITY),
                glam::Vec2::splat(f32::NEG_INFINITY),
            ),
            |(lo, hi), p| (lo.min(p.truncate()), hi.max(p.truncate())),
        );
        let margin = (3.0 * SMOOTHING_M / cell_m).ceil();
        let span = ((max - min) / cell_m).floor() + 1.0 + 2.0 * margin;
        if span.x * span.y > MAX_CELLS as f32 {
            return None;
        }
        let (columns, rows, margin) = (span.x as usize, span.y as usize, margin as usize);
        let mut height = vec![0.0f32; columns * rows];
        for p in canopy {
            let c = ((p.truncate() - min) / cell_m).floor();
            let k = (c.y as usize + margin) * columns + c.x as usize + margin;
            height[k] = height[k].max(p.z);
        }
        Some(Self {
            cell_m,
            columns,
            rows,
            height,
        })
    }

    /// The grid convolved with a Gaussian of standard deviation `sigma_m`
    /// (truncated at 3σ), rows then columns.
    fn smoothed(self, sigma_m: f32) -> Self {
        let sigma = sigma_m / self.cell_m;
        let reach = (3.0 * sigma).ceil() as isize;
        let weights: Vec<f32> = (-reach..=reach)
            .map(|d| (-0.5 * (d as f32 / sigma).powi(2)).exp())
            .collect();
        let total: f32 = weights.iter().sum();
        let kernel: Vec<f32> = weights.iter().map(|w| w / total).collect();
        let along_rows = self.convolved(&kernel, 1, self.columns);
        along_rows.convolved(&kernel, self.columns, self.rows)
    }

    /// One pass of `kernel` along the axis whose cells are `stride` apart
    /// and `len` long; cells outside the grid count as 0.
    fn convolved(&self, kernel: &[f32], stride: usize, len: usize) -> Self {
        let reach = (kernel.len() / 2) as isize;
        let mut out = vec![0.0f32; self.height.len()];
        for (k, value) in out.iter_mut().enumerate() {
            let along = ((k / stride) % len) as isize;
            *value = kernel
                .iter()
                .enumerate()
                .filter_map(|(j, w)| {
                    let at = along + j as isize - reach;
                    (0..len as isize).contains(&at).then(|| {
                        let shifted = k as isize + (at - along) * stride as isize;
                        w * self.height[shifted as usize]
                    })
                })
                .sum();
        }
        Self {
            height: out,
            ..*self
        }
    }

    /// Cells highest within `window_m` along both axes and at least
    /// `share` of the highest cell, highest first. Of cells that tie (a flat
    /// canopy), only the first within the window is kept, and at most
    /// [`MAX_TOPS`] are, so that a flat roof's thousands of equal cells do
    /// not make millions of pairs.
    fn tops(&self, window_m: f32, share: f32) -> Vec<(usize, usize)> {
        let reach = (window_m / self.cell_m).round() as usize;
        let floor = share * self.height.iter().copied().fold(0.0, f32::max);
        let mut candidates = Vec::new();
        for row in 0..self.rows {
            for column in 0..self.columns {
                let h = self.at(column, row);
                if h > 0.0 && h >= floor && self.highest_around(column, row, reach) <= h {
                    candidates.push((column, row));
                }
            }
        }
        candidates.sort_by(|a, b| self.at(b.0, b.1).total_cmp(&self.at(a.0, a.1)));
        let mut tops: Vec<(usize, usize)> = Vec::new();
        for c in candidates {
            let apart = |t: &(usize, usize)| t.0.abs_diff(c.0).max(t.1.abs_diff(c.1)) > reach;
            if tops.iter().all(apart) {
                tops.push(c);
                if tops.len() == MAX_TOPS {
                    break;
                }
            }
        }
        tops
    }

    /// The highest cell within `reach` cells of (`column`, `row`) along
    /// both axes.
    fn highest_around(&self, column: usize, row: usize, reach: usize) -> f32 {
        let rows = row.saturating_sub(reach)..=(row + reach).min(self.rows - 1);
        rows.flat_map(|r| {
            let columns = column.saturating_sub(reach)..=(column + reach).min(self.columns - 1);
            columns.map(move |c| (c, r))
        })
        .map(|(c, r)| self.at(c, r))
        .fold(f32::NEG_INFINITY, f32::max)
    }

    /// Two tops, their distance and the lowest cell on the straight line
    /// between them (sampled every half cell).
    fn between(&self, a: (usize, usize), b: (usize, usize)) -> TwoTops {
        let (ax, ay) = (a.0 as f32, a.1 as f32);
        let (bx, by) = (b.0 as f32, b.1 as f32);
        let cells = ((bx - ax).powi(2) + (by - ay).powi(2)).sqrt();
        let samples = (2.0 * cells).ceil() as usize + 1;
        let saddle_m = (0..samples)
            .map(|s| {
                let t = s as f32 / (samples - 1).max(1) as f32;
                let c = (ax + t * (bx - ax)).round() as usize;
                let r = (ay + t * (by - ay)).round() as usize;
                self.at(c, r)
            })
            .fold(f32::INFINITY, f32::min);
        TwoTops {
            apart_m: cells * self.cell_m,
            lower_top_m: self.at(a.0, a.1).min(self.at(b.0, b.1)),
            saddle_m,
        }
    }

    fn at(&self, column: usize, row: usize) -> f32 {
        self.height[row * self.columns + column]
    }
}

/// The grid cell for `canopy`: [`MIN_CELL_M`], or larger where the returns
/// are sparser than [`RETURNS_PER_CELL`] per cell (returns per occupied
/// square metre); `None` without returns.
fn cell_size(canopy: &[Vec3]) -> Option<f32> {
    if canopy.is_empty() {
        return None;
    }
    let occupied: std::collections::HashSet<(i64, i64)> = canopy
        .iter()
        .map(|p| (p.x.floor() as i64, p.y.floor() as i64))
        .collect();
    let per_m2 = canopy.len() as f32 / occupied.len() as f32;
    Some(MIN_CELL_M.max((RETURNS_PER_CELL / per_m2).sqrt()))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A hemispherical crown of `radius` with its top `height` above the
    /// ground at (`x`, 0), returns on a 0.25 m grid.
    fn dome(x: f32, radius: f32, height: f32) -> Vec<Vec3> {
        let steps = (radius / 0.25) as i32;
        let mut points = Vec::new();
        for i in -steps..=steps {
            for j in -steps..=steps {
                let (dx, dy) = (i as f32 * 0.25, j as f32 * 0.25);
                let r2 = (dx * dx + dy * dy) / (radius * radius);
                if r2 <= 1.0 {
                    let top = height - radius * (1.0 - (1.0 - r2).sqrt());
                    points.push(Vec3::new(x + dx, dy, top));
                }
            }
        }
        points
    }

    #[test]
    fn one_dome_has_no_second_crown() {
        let crown = dome(0.0, 6.0, 18.0);
        let dip = two_crowns(&crown).map_or(0.0, |t| t.dip());
        assert!(dip < TWO_CROWNS_DIP, "{dip}");
    }

    /// Two crowns 1 m apart (one part for `parts`), their tops 11 m apart.
    #[test]
    fn two_domes_apart_dip_between_their_tops() {
        let mut crowns = dome(0.0, 5.0, 16.0);
        crowns.extend(dome(11.0, 5.0, 14.0));
        let tops = two_crowns(&crowns).expect("two tops");
        assert!((tops.apart_m - 11.0).abs() < 1.0, "{tops:?}");
        assert!(tops.dip() >= TWO_CROWNS_DIP, "{tops:?}");
        assert!(tops.lower_top_m < 14.5, "{tops:?}");
        assert!(tops.note().contains("may hold two trees"));
    }

    #[test]
    fn low_or_empty_canopy_has_no_tops() {
        assert_eq!(two_crowns(&[]), None);
        assert_eq!(two_crowns(&[Vec3::new(0.0, 0.0, 0.5)]), None);
        assert_eq!(two_crowns(&[Vec3::new(0.0, 0.0, 8.0)]), None);
        assert_eq!(two_crowns(&[Vec3::new(f32::NAN, 0.0, 8.0)]), None);
        let far = [Vec3::new(-1e30, 0.0, 8.0), Vec3::new(1e30, 1e30, 9.0)];
        assert_eq!(two_crowns(&far), None);
    }

    /// A flat canopy ties everywhere: one top per window, at most
    /// [`MAX_TOPS`], and no dip between them.
    #[test]
    fn a_flat_roof_has_few_tops_and_no_dip() {
        let roof: Vec<Vec3> = (0..240 * 240)
            .map(|k| Vec3::new((k % 240) as f32 * 0.5, (k / 240) as f32 * 0.5, 10.0))
            .collect();
        let grid = Grid::highest(&roof).unwrap().smoothed(SMOOTHING_M);
        // About a thousand windows tie, so the cap binds; the tops kept lie
        // more than a window apart.
        let tops = grid.tops(TOP_WINDOW_M, MIN_TOP_SHARE);
        assert_eq!(tops.len(), MAX_TOPS);
        let reach = (TOP_WINDOW_M / grid.cell_m).round() as usize;
        for (i, a) in tops.iter().enumerate() {
            for b in &tops[..i] {
                assert!(
                    a.0.abs_diff(b.0).max(a.1.abs_diff(b.1)) > reach,
                    "{a:?} {b:?}"
                );
            }
        }
        let dip = two_crowns(&roof).map_or(0.0, |t| t.dip());
        assert!(dip < TWO_CROWNS_DIP, "{dip}");
    }
}
