//! Solid geometry of a skeleton for the scan simulators: internode frustums,
//! foliage spheres, and a uniform grid for ray casting.
//!
//! A ray visits only the grid cells it crosses (Amanatides & Woo's 3D DDA),
//! so a scan costs about (rays × cells per ray) rather than (rays × internodes).

use std::ops::ControlFlow;

use glam::Vec3;

use crate::skeleton::Skeleton;

/// Most grid cells; larger scenes get coarser cells instead of more memory.
const MAX_CELLS: usize = 1 << 21;

/// The tapered cylinder around one internode: radius `radius_a_m` at `a`
/// (the parent node) to `radius_b_m` at `b` (the child node).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Frustum {
    pub(crate) a: Vec3,
    pub(crate) b: Vec3,
    pub(crate) radius_a_m: f32,
    pub(crate) radius_b_m: f32,
    /// Unit axis from `a` to `b`.
    pub(crate) axis: Vec3,
    pub(crate) length_m: f32,
}

impl Frustum {
    /// Frustums of all internodes of non-zero length, in internode order.
    pub(crate) fn of_skeleton(tree: &Skeleton) -> Vec<Frustum> {
        tree.internodes()
            .filter_map(|(p, c)| {
                let (a, b) = (tree.position(p), tree.position(c));
                let length_m = a.distance(b);
                (length_m > 1e-6).then(|| Frustum {
                    a,
                    b,
                    radius_a_m: tree.radius(p),
                    radius_b_m: tree.radius(c),
                    axis: (b - a) / length_m,
                    length_m,
                })
            })
            .collect()
    }

    /// Radius at axial fraction `t` in `[0, 1]`.
    pub(crate) fn radius_at(&self, t: f32) -> f32 {
        self.radius_a_m + (self.radius_b_m - self.radius_a_m) * t
    }

    /// Area of the lateral surface, in m².
    pub(crate) fn lateral_area_m2(&self) -> f32 {
        let slant = self.length_m.hypot(self.radius_a_m - self.radius_b_m);
        std::f32::consts::PI * (self.radius_a_m + self.radius_b_m) * slant
    }

    /// Axis-aligned bounds `(min, max)`.
    pub(crate) fn bounds(&self) -> (Vec3, Vec3) {
        let r = Vec3::splat(self.radius_a_m.max(self.radius_b_m));
        (self.a.min(self.b) - r, self.a.max(self.b) + r)
    }

    /// True when `p` lies strictly inside the solid.
    pub(crate) fn contains(&self, p: Vec3) -> bool {
        let h = (p - self.a).dot(self.axis);
        if h <= 0.0 || h >= self.length_m {
            return false;
        }
        let radial = (p - self.a) - self.axis * h;
        let r = self.radius_at(h / self.length_m);
        radial.length_squared() < r * r
    }

    /// First intersection of the ray `origin + t·dir` (unit `dir`) with the
    /// solid, for `t` in `(t_min, t_max)`. The taper within one internode is
    /// millimetres, so the side is taken as a cylinder of the mean radius;
    /// the end discs are included so that rays along the axis are stopped.
    pub(crate) fn ray_hit(&self, origin: Vec3, dir: Vec3, t_min: f32, t_max: f32) -> Option<f32> {
        let r = 0.5 * (self.radius_a_m + self.radius_b_m);
        let w = origin - self.a;
        let (wa, da) = (w.dot(self.axis), dir.dot(self.axis));
        let w_perp = w - self.axis * wa;
        let d_perp = dir - self.axis * da;
        let mut best: Option<f32> = None;
        let mut consider = |t: f32| {
            if t > t_min && t < t_max && best.is_none_or(|b| t < b) {
                best = Some(t);
            }
        };
        let qa = d_perp.length_squared();
        if qa > 1e-12 {
            let qb = 2.0 * w_perp.dot(d_perp);
            let qc = w_perp.length_squared() - r * r;
            let disc = qb * qb - 4.0 * qa * qc;
            if disc >= 0.0 {
                let sq = disc.sqrt();
                for t in [(-qb - sq) / (2.0 * qa), (-qb + sq) / (2.0 * qa)] {
                    let h = wa + t * da;
                    if (0.0..=self.length_m).contains(&h) {
                        consider(t);
                    }
                }
            }
        }
        if da.abs() > 1e-9 {
            for h in [0.0, self.length_m] {
                let t = (h - wa) / da;
                if (w_perp + d_perp * t).length_squared() <= r * r {
                    consider(t);
                }
            }
        }
        best
    }
}

/// A ball of foliage around a twig cluster.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Sphere {
    pub(crate) centre: Vec3,
    pub(crate) radius_m: f32,
}

impl Sphere {
    /// Axis-aligned bounds `(min, max)`.
    pub(crate) fn bounds(&self) -> (Vec3, Vec3) {
        let r = Vec3::splat(self.radius_m);
        (self.centre - r, self.centre + r)
    }

    /// The ray parameters `(enter, exit)` of the chord through the ball, if
    /// the ray (unit `dir`) crosses it.
    pub(crate) fn chord(&self, origin: Vec3, dir: Vec3) -> Option<(f32, f32)> {
        let w = origin - self.centre;
        let b = w.dot(dir);
        let c = w.length_squared() - self.radius_m * self.radius_m;
        let disc = b * b - c;
        (disc > 0.0).then(|| {
            let sq = disc.sqrt();
            (-b - sq, -b + sq)
        })
    }
}

/// A uniform grid over axis-aligned boxes, stored as compressed rows: the
/// ids of the boxes overlapping cell `c` are `items[starts[c]..starts[c+1]]`.
pub(crate) struct Grid {
    origin: Vec3,
    cell_m: f32,
    dims: [usize; 3],
    starts: Vec<u32>,
    items: Vec<u32>,
}

impl Grid {
    /// Builds the grid with cells of about `cell_m` (coarser if the scene
    /// would need more than `MAX_CELLS`). Box ids are their indices.
    pub(crate) fn build(boxes: &[(Vec3, Vec3)], cell_m: f32) -> Grid {
        let (lo, hi) = boxes.iter().fold(
            (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
            |(lo, hi), &(a, b)| (lo.min(a), hi.max(b)),
        );
        let (lo, hi) = if boxes.is_empty() {
            (Vec3::ZERO, Vec3::ONE)
        } else {
            (lo, hi)
        };
        let extent = (hi - lo).max(Vec3::splat(1e-3));
        let mut cell_m = cell_m.max(1e-3);
        while cells_for(extent, cell_m) > MAX_CELLS {
            cell_m *= 1.25;
        }
        let dims = dims_for(extent, cell_m);
        let mut grid = Grid {
            origin: lo,
            cell_m,
            dims,
            starts: vec![0; dims[0] * dims[1] * dims[2] + 1],
            items: Vec::new(),
        };
        grid.fill(boxes);
        grid
    }

    fn fill(&mut self, boxes: &[(Vec3, Vec3)]) {
        let mut counts = vec![0u32; self.starts.len()];
        for &(a, b) in boxes {
            self.for_cells_in(a, b, |c| counts[c] += 1);
        }
        let mut acc = 0u32;
        for (start, count) in self.starts.iter_mut().zip(&counts) {
            *start = acc;
            acc += count;
        }
        self.items = vec![0; acc as usize];
        let mut cursor: Vec<u32> = self.starts.clone();
        for (id, &(a, b)) in boxes.iter().enumerate() {
            let items = &mut self.items;
            let cursor = &mut cursor;
            let (origin, cell_m, dims) = (self.origin, self.cell_m, self.dims);
            for_cells(origin, cell_m, dims, a, b, |c| {
                items[cursor[c] as usize] = id as u32;
                cursor[c] += 1;
            });
        }
    }

    fn for_cells_in(&self, a: Vec3, b: Vec3, f: impl FnMut(usize)) {
        for_cells(self.origin, self.cell_m, self.dims, a, b, f);
    }

    /// Ids of the boxes overlapping the cell that contains `p` (none outside).
    pub(crate) fn items_at(&self, p: Vec3) -> &[u32] {
        let c = (p - self.origin) / self.cell_m;
        let inside = c.cmpge(Vec3::ZERO).all()
            && (c.x as usize) < self.dims[0]
            && (c.y as usize) < self.dims[1]
            && (c.z as usize) < self.dims[2];
        if !inside {
            return &[];
        }
        self.cell_items(self.index([c.x as usize, c.y as usize, c.z as usize]))
    }

    fn cell_items(&self, c: usize) -> &[u32] {
        &self.items[self.starts[c] as usize..self.starts[c + 1] as usize]
    }

    fn index(&self, c: [usize; 3]) -> usize {
        (c[2] * self.dims[1] + c[1]) * self.dims[0] + c[0]
    }

    /// Visits, in order along the ray `origin + t·dir` for `t` in
    /// `[0, t_max]`, the ids in every cell the ray crosses. A box spanning
    /// several cells is visited once per cell. `visit` may stop the walk.
    pub(crate) fn traverse(
        &self,
        origin: Vec3,
        dir: Vec3,
        t_max: f32,
        mut visit: impl FnMut(&[u32]) -> ControlFlow<()>,
    ) {
        let hi = self.origin
            + Vec3::new(
                self.dims[0] as f32,
                self.dims[1] as f32,
                self.dims[2] as f32,
            ) * self.cell_m;
        let Some((t_enter, t_exit)) = slab(origin, dir, self.origin, hi) else {
            return;
        };
        let (t0, t1) = (t_enter.max(0.0), t_exit.min(t_max));
        if t0 > t1 {
            return;
        }
        let start = (origin + dir * t0 - self.origin) / self.cell_m;
        let mut cell = [0i64; 3];
        let (mut step, mut t_next, mut t_delta) =
            ([0i64; 3], [f32::INFINITY; 3], [f32::INFINITY; 3]);
        for k in 0..3 {
            cell[k] = (start[k].floor() as i64).clamp(0, self.dims[k] as i64 - 1);
            if dir[k] > 0.0 {
                step[k] = 1;
                t_delta[k] = self.cell_m / dir[k];
                t_next[k] = t0 + ((cell[k] + 1) as f32 - start[k]) * t_delta[k];
            } else if dir[k] < 0.0 {
                step[k] = -1;
                t_delta[k] = -self.cell_m / dir[k];
                t_next[k] = t0 + (start[k] - cell[k] as f32) * t_delta[k];
            }
        }
        loop {
            let c = self.index([cell[0] as usize, cell[1] as usize, cell[2] as usize]);
            if visit(self.cell_items(c)).is_break() {
                return;
            }
            let k = if t_next[0] <= t_next[1] && t_next[0] <= t_next[2] {
                0
            } else if t_next[1] <= t_next[2] {
                1
            } else {
                2
            };
            if t_next[k] > t1 {
                return;
            }
            cell[k] += step[k];
            if cell[k] < 0 || cell[k] >= self.dims[k] as i64 {
                return;
            }
            t_next[k] += t_delta[k];
        }
    }
}

fn dims_for(extent: Vec3, cell_m: f32) -> [usize; 3] {
    let d = (extent / cell_m).ceil().max(Vec3::ONE);
    [d.x as usize, d.y as usize, d.z as usize]
}

fn cells_for(extent: Vec3, cell_m: f32) -> usize {
    let d = (extent / cell_m).ceil().max(Vec3::ONE);
    // Computed in f32 first: the product of three large counts must not overflow.
    if d.x * d.y * d.z > MAX_CELLS as f32 {
        usize::MAX
    } else {
        let [x, y, z] = dims_for(extent, cell_m);
        x * y * z
    }
}

fn for_cells(
    origin: Vec3,
    cell_m: f32,
    dims: [usize; 3],
    a: Vec3,
    b: Vec3,
    mut f: impl FnMut(usize),
) {
    let clamp = |v: f32, k: usize| ((v / cell_m).floor().max(0.0) as usize).min(dims[k] - 1);
    let (la, lb) = (a - origin, b - origin);
    let (x0, y0, z0) = (clamp(la.x, 0), clamp(la.y, 1), clamp(la.z, 2));
    let (x1, y1, z1) = (clamp(lb.x, 0), clamp(lb.y, 1), clamp(lb.z, 2));
    for z in z0..=z1 {
        for y in y0..=y1 {
            for x in x0..=x1 {
                f((z * dims[1] + y) * dims[0] + x);
            }
        }
    }
}

/// The ray's parameter interval inside the box `[lo, hi]` (slab method).
fn slab(origin: Vec3, dir: Vec3, lo: Vec3, hi: Vec3) -> Option<(f32, f32)> {
    let (mut t0, mut t1) = (f32::NEG_INFINITY, f32::INFINITY);
    for k in 0..3 {
        if dir[k].abs() < 1e-12 {
            if origin[k] < lo[k] || origin[k] > hi[k] {
                return None;
            }
        } else {
            let (a, b) = ((lo[k] - origin[k]) / dir[k], (hi[k] - origin[k]) / dir[k]);
            t0 = t0.max(a.min(b));
            t1 = t1.min(a.max(b));
        }
    }
    (t0 <= t1).then_some((t0, t1))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn vertical() -> Frustum {
        Frustum {
            a: Vec3::ZERO,
            b: Vec3::new(0.0, 0.0, 2.0),
            radius_a_m: 0.5,
            radius_b_m: 0.5,
            axis: Vec3::Z,
            length_m: 2.0,
        }
    }

    #[test]
    fn ray_hits_side_and_caps() {
        let f = vertical();
        let side = f.ray_hit(Vec3::new(-5.0, 0.0, 1.0), Vec3::X, 0.0, 100.0);
        assert!((side.unwrap() - 4.5).abs() < 1e-5);
        let top = f.ray_hit(Vec3::new(0.1, 0.0, 10.0), -Vec3::Z, 0.0, 100.0);
        assert!((top.unwrap() - 8.0).abs() < 1e-5);
        assert!(
            f.ray_hit(Vec3::new(-5.0, 0.0, 3.0), Vec3::X, 0.0, 100.0)
                .is_none()
        );
        assert!(f.contains(Vec3::new(0.2, 0.0, 1.0)));
        assert!(!f.contains(Vec3::new(0.6, 0.0, 1.0)));
    }

    #[test]
    fn traversal_finds_boxes_along_the_ray_only() {
        let boxes: Vec<(Vec3, Vec3)> = (0..10)
            .map(|i| {
                let c = Vec3::new(i as f32, (i % 2) as f32 * 5.0, 0.0);
                (c - 0.1, c + 0.1)
            })
            .collect();
        let grid = Grid::build(&boxes, 0.5);
        let mut seen = Vec::new();
        grid.traverse(Vec3::new(-1.0, 0.0, 0.0), Vec3::X, 100.0, |ids| {
            seen.extend_from_slice(ids);
            ControlFlow::Continue(())
        });
        seen.dedup();
        assert_eq!(seen, vec![0, 2, 4, 6, 8]);
        assert_eq!(grid.items_at(Vec3::new(1.0, 5.0, 0.0)), &[1]);
    }
}
