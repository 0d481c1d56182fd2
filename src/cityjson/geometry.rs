//! CityJSON geometries of one tree: integer vertices under a transform, a
//! MultiSurface per LOD and the skeleton as a MultiLineString.

use std::collections::HashMap;

use glam::DVec3;
use serde_json::{Value, json};

use crate::mesh::{self, Lod};
use crate::skeleton::{NodeId, Skeleton};

/// Size of one integer vertex step, in metres (CityJSON `transform.scale`).
pub const SCALE_M: f64 = 0.001;

/// An integer vertex in units of [`SCALE_M`] from the translate.
type Key = [i64; 3];

/// Integer vertices shared by all geometries of one document or feature,
/// deduplicated so that no vertex is listed twice.
pub(super) struct VertexPool {
    translate: DVec3,
    index: HashMap<Key, usize>,
    vertices: Vec<Key>,
}

impl VertexPool {
    pub(super) fn new(translate: DVec3) -> Self {
        Self {
            translate,
            index: HashMap::new(),
            vertices: Vec::new(),
        }
    }

    /// The integer grid point of absolute CRS position `p`.
    fn quantise(&self, p: DVec3) -> Key {
        let q = ((p - self.translate) / SCALE_M).round();
        [q.x as i64, q.y as i64, q.z as i64]
    }

    /// The index of a grid point, added on first use: only vertices that a
    /// boundary references are ever listed.
    fn add(&mut self, key: Key) -> usize {
        *self.index.entry(key).or_insert_with(|| {
            self.vertices.push(key);
            self.vertices.len() - 1
        })
    }

    /// The vertices as a JSON array.
    pub(super) fn to_json(&self) -> Value {
        json!(self.vertices)
    }

    /// `[minx, miny, minz, maxx, maxy, maxz]` of the vertices in CRS units,
    /// `None` when there are none.
    pub(super) fn extent(&self) -> Option<[f64; 6]> {
        let first = self.vertices.first()?;
        let (mut lo, mut hi) = (*first, *first);
        for v in &self.vertices {
            for k in 0..3 {
                lo[k] = lo[k].min(v[k]);
                hi[k] = hi[k].max(v[k]);
            }
        }
        let real = |v: [i64; 3], k: usize| round_mm(self.translate[k] + v[k] as f64 * SCALE_M);
        Some([
            real(lo, 0),
            real(lo, 1),
            real(lo, 2),
            real(hi, 0),
            real(hi, 1),
            real(hi, 2),
        ])
    }
}

/// Rounds to the millimetre, so extents print without float noise.
pub(super) fn round_mm(x: f64) -> f64 {
    (x * 1000.0).round() / 1000.0
}

/// The branch mesh of `lod` as a MultiSurface of triangles, or `None` if no
/// triangle survives quantisation. Triangles whose corners fall onto fewer
/// than three distinct, non-collinear integer vertices are dropped.
pub(super) fn mesh_surface(skeleton: &Skeleton, lod: Lod, pool: &mut VertexPool) -> Option<Value> {
    let m = mesh::build_mesh(skeleton, lod);
    let origin = skeleton.anchor().origin;
    let keys: Vec<Key> = m
        .positions
        .iter()
        .map(|p| pool.quantise(origin + p.as_dvec3()))
        .collect();
    let surfaces: Vec<Value> = m
        .triangles()
        .map(|t| t.map(|i| keys[i as usize]))
        .filter(|&t| !is_degenerate(t))
        .map(|t| json!([t.map(|k| pool.add(k))]))
        .collect();
    (!surfaces.is_empty())
        .then(|| json!({"type": "MultiSurface", "lod": lod.as_str(), "boundaries": surfaces}))
}

/// True when the triangle's integer corners do not span an area (two equal
/// or all three collinear).
fn is_degenerate([a, b, c]: [Key; 3]) -> bool {
    // Differences within one tree are small; i64 keeps the cross product exact.
    let d = |p: Key, q: Key| [q[0] - p[0], q[1] - p[1], q[2] - p[2]];
    let (u, v) = (d(a, b), d(a, c));
    let cross = [
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ];
    cross == [0, 0, 0]
}

/// The skeleton as a MultiLineString, one polyline per branch (trunk, then
/// each lateral from its fork), or `None` when it has no internode longer
/// than the vertex resolution.
pub(super) fn skeleton_lines(
    skeleton: &Skeleton,
    lod: Lod,
    pool: &mut VertexPool,
) -> Option<Value> {
    let mut lines = Vec::new();
    let mut starts = vec![(None, NodeId::ROOT)];
    for fork in skeleton.ids() {
        for &lateral in skeleton.children(fork).iter().skip(1) {
            starts.push((Some(fork), lateral));
        }
    }
    for (fork, first) in starts {
        let mut line: Vec<Key> = Vec::new();
        let mut push = |id: NodeId| {
            let key = pool.quantise(skeleton.absolute_position(id));
            if line.last() != Some(&key) {
                line.push(key);
            }
        };
        if let Some(fork) = fork {
            push(fork);
        }
        let mut node = first;
        push(node);
        while let Some(&next) = skeleton.children(node).first() {
            node = next;
            push(node);
        }
        if line.len() >= 2 {
            lines.push(
                line.into_iter()
                    .map(|k| pool.add(k))
                    .collect::<Vec<usize>>(),
            );
        }
    }
    (!lines.is_empty())
        .then(|| json!({"type": "MultiLineString", "lod": lod.as_str(), "boundaries": lines}))
}

/// A conservative extent of everything [`mesh_surface`] can produce for this
/// skeleton: node bounds grown by the largest radius (tip caps included).
pub(super) fn skeleton_extent(skeleton: &Skeleton) -> [f64; 6] {
    let (lo, hi) = skeleton.bounds();
    let grow = 2.0
        * f64::from(
            skeleton
                .nodes()
                .iter()
                .map(|n| n.radius_m)
                .fold(mesh::MIN_RADIUS_M, f32::max),
        );
    let origin = skeleton.anchor().origin;
    let lo = origin + lo.as_dvec3() - DVec3::splat(grow);
    let hi = origin + hi.as_dvec3() + DVec3::splat(grow);
    let floor = |x: f64| (x * 1000.0).floor() / 1000.0;
    let ceil = |x: f64| (x * 1000.0).ceil() / 1000.0;
    [
        floor(lo.x),
        floor(lo.y),
        floor(lo.z),
        ceil(hi.x),
        ceil(hi.y),
        ceil(hi.z),
    ]
}

/// The smallest extent holding both.
pub(super) fn union(a: [f64; 6], b: [f64; 6]) -> [f64; 6] {
    [
        a[0].min(b[0]),
        a[1].min(b[1]),
        a[2].min(b[2]),
        a[3].max(b[3]),
        a[4].max(b[4]),
        a[5].max(b[5]),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pool_deduplicates_and_quantises_to_the_millimetre() {
        let mut pool = VertexPool::new(DVec3::new(100.0, 200.0, 0.0));
        let a = pool.quantise(DVec3::new(100.0012, 200.0, 1.0));
        let b = pool.quantise(DVec3::new(100.0014, 200.0004, 1.0));
        assert_eq!(a, [1, 0, 1000]);
        assert_eq!(pool.add(a), pool.add(b));
        assert_eq!(
            pool.extent(),
            Some([100.001, 200.0, 1.0, 100.001, 200.0, 1.0])
        );
        assert!(is_degenerate([a, b, [7, 7, 7]]), "repeated corner");
        assert!(is_degenerate([a, [2, 0, 1000], [3, 0, 1000]]), "collinear");
        assert!(!is_degenerate([a, [2, 0, 1000], [2, 1, 1000]]));
    }
}
