//! Binary PLY writer for the branch mesh (the skeleton's PLY form is
//! [`Skeleton::to_ply`](crate::Skeleton::to_ply)).
//!
//! Coordinates are `double`, so absolute national-grid coordinates keep
//! sub-millimetre precision; everything else is `float` or `int`.

use std::fmt::Write;

use glam::DVec3;

use super::Mesh;
use crate::skeleton::{Anchor, ply_header_start};

/// Encodes `mesh` (relative to `anchor`) as binary little-endian PLY with
/// `double` coordinates measured from `local_origin`, `float` normals and
/// triangle faces.
pub fn mesh_ply(mesh: &Mesh, anchor: &Anchor, local_origin: DVec3) -> Vec<u8> {
    let mut header = ply_header_start("silva tree mesh, metres, z up", anchor, local_origin);
    let _ = write!(
        header,
        "element vertex {}\nproperty double x\nproperty double y\nproperty double z\n\
         property float nx\nproperty float ny\nproperty float nz\n\
         element face {}\nproperty list uchar uint vertex_indices\nend_header\n",
        mesh.positions.len(),
        mesh.triangle_count()
    );
    let shift = anchor.origin - local_origin;
    let mut out = header.into_bytes();
    out.reserve(mesh.positions.len() * 36 + mesh.triangle_count() * 13);
    for (p, n) in mesh.positions.iter().zip(&mesh.normals) {
        let p = shift + p.as_dvec3();
        for c in p.to_array() {
            out.extend_from_slice(&c.to_le_bytes());
        }
        for c in n.to_array() {
            out.extend_from_slice(&c.to_le_bytes());
        }
    }
    for triangle in mesh.triangles() {
        out.push(3);
        for i in triangle {
            out.extend_from_slice(&i.to_le_bytes());
        }
    }
    out
}
