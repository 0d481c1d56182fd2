//! Binary PLY writers for the branch mesh and for the skeleton.
//!
//! lsystem-from-adtree-skeletons §3.4 notes that AdTree's skeleton PLY could
//! not be opened by any viewer; these files declare exactly what they hold.
//! Coordinates are `double`, so absolute national-grid coordinates keep
//! sub-millimetre precision; everything else is `float` or `int`.

use std::fmt::Write;

use glam::DVec3;

use super::Mesh;
use crate::skeleton::{Anchor, Skeleton};

/// Encodes `mesh` (relative to `anchor`) as binary little-endian PLY with
/// `double` coordinates measured from `local_origin`, `float` normals and
/// triangle faces.
pub fn mesh_ply(mesh: &Mesh, anchor: &Anchor, local_origin: DVec3) -> Vec<u8> {
    let mut header = header_start("silva tree mesh, metres, z up", anchor, local_origin);
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

/// Encodes the skeleton as binary little-endian PLY: one vertex per node
/// with absolute `double` coordinates and a `float` radius in metres, and one
/// edge (`int vertex1`, `int vertex2`, parent to child) per internode.
pub fn skeleton_ply(skeleton: &Skeleton) -> Vec<u8> {
    let mut header = header_start(
        "silva tree skeleton, metres, z up",
        skeleton.anchor(),
        DVec3::ZERO,
    );
    let _ = write!(
        header,
        "element vertex {}\nproperty double x\nproperty double y\nproperty double z\n\
         property float radius\nelement edge {}\nproperty int vertex1\nproperty int vertex2\n\
         end_header\n",
        skeleton.len(),
        skeleton.internode_count()
    );
    let mut out = header.into_bytes();
    for id in skeleton.ids() {
        for c in skeleton.absolute_position(id).to_array() {
            out.extend_from_slice(&c.to_le_bytes());
        }
        out.extend_from_slice(&skeleton.radius(id).to_le_bytes());
    }
    for (parent, child) in skeleton.internodes() {
        // Node counts fit in i32 for any skeleton this crate reconstructs;
        // PLY readers expect the signed `int` for edges.
        out.extend_from_slice(&(parent.index() as i32).to_le_bytes());
        out.extend_from_slice(&(child.index() as i32).to_le_bytes());
    }
    out
}

/// The header lines shared by both files, up to the first element.
fn header_start(what: &str, anchor: &Anchor, local_origin: DVec3) -> String {
    let mut header = String::from("ply\nformat binary_little_endian 1.0\n");
    let _ = writeln!(header, "comment {what}");
    if let Some(crs) = &anchor.crs {
        let _ = writeln!(header, "comment crs {crs}");
    }
    let _ = writeln!(
        header,
        "comment origin {} {} {} (add to every vertex for CRS coordinates)",
        local_origin.x, local_origin.y, local_origin.z
    );
    header
}
