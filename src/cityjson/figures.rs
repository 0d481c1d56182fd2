//! Per-LOD output figures for `silva eval`: triangles, file sizes and the
//! time to build the GLB, so that the evaluation table is one call.

use std::time::{Duration, Instant};

use super::{TreeInfo, city_json};
use crate::mesh::{self, Lod, MeshFormat};
use crate::skeleton::Skeleton;

/// What one level of detail of one tree costs.
#[derive(Debug, Clone, PartialEq)]
pub struct LodFigures {
    /// The level.
    pub lod: Lod,
    /// Triangles in the branch mesh.
    pub triangles: usize,
    /// Vertices in the branch mesh.
    pub vertices: usize,
    /// Size of the GLB file.
    pub glb_bytes: usize,
    /// Size of the OBJ file (coordinates relative to the anchor).
    pub obj_bytes: usize,
    /// Size of a CityJSON document holding only this level's mesh plus the
    /// skeleton lines, compact JSON.
    pub cityjson_bytes: usize,
    /// Wall time from skeleton to GLB bytes: LOD selection, sweep, encoding.
    pub glb_build: Duration,
}

/// The figures of every level, coarsest first.
pub fn lod_figures(skeleton: &Skeleton) -> Vec<LodFigures> {
    let anchor = skeleton.anchor();
    Lod::ALL
        .iter()
        .map(|&lod| {
            let start = Instant::now();
            let m = mesh::build_mesh(skeleton, lod);
            let glb = MeshFormat::Glb.encode(&m, anchor, anchor.origin);
            let glb_build = start.elapsed();
            let obj = MeshFormat::Obj.encode(&m, anchor, anchor.origin);
            let cityjson = city_json(&TreeInfo::new("tree", skeleton), &[lod]).to_string();
            LodFigures {
                lod,
                triangles: m.triangle_count(),
                vertices: m.vertex_count(),
                glb_bytes: glb.len(),
                obj_bytes: obj.len(),
                cityjson_bytes: cityjson.len(),
                glb_build,
            }
        })
        .collect()
}
