//! Wavefront OBJ writer: positions, vertex normals, triangles.
//!
//! OBJ has no georeference, so coordinates are written in the CRS's axes
//! (z up) relative to a caller-chosen local origin, with the CRS and that
//! origin in header comments. Positions are printed to 0.1 mm, normals to
//! four decimals: more digits only inflate the file.

use std::fmt::Write;

use glam::DVec3;

use super::Mesh;
use crate::skeleton::Anchor;

/// Encodes `mesh` (relative to `anchor`) as OBJ text, coordinates measured
/// from `local_origin`.
pub fn obj(mesh: &Mesh, anchor: &Anchor, local_origin: DVec3) -> String {
    let shift = anchor.origin - local_origin;
    let mut out = String::with_capacity(mesh.positions.len() * 64 + mesh.indices.len() * 8);
    // Writing into a String cannot fail.
    let _ = writeln!(out, "# silva tree mesh, metres, z up");
    if let Some(crs) = &anchor.crs {
        let _ = writeln!(out, "# crs {crs}");
    }
    let _ = writeln!(
        out,
        "# origin {:.4} {:.4} {:.4} (add to every vertex for CRS coordinates)",
        local_origin.x, local_origin.y, local_origin.z
    );
    for p in &mesh.positions {
        let p = shift + p.as_dvec3();
        let _ = writeln!(out, "v {:.4} {:.4} {:.4}", p.x, p.y, p.z);
    }
    for n in &mesh.normals {
        let _ = writeln!(out, "vn {:.4} {:.4} {:.4}", n.x, n.y, n.z);
    }
    for [a, b, c] in mesh.triangles() {
        let (a, b, c) = (a + 1, b + 1, c + 1);
        let _ = writeln!(out, "f {a}//{a} {b}//{b} {c}//{c}");
    }
    out
}
