//! glTF 2.0 binary (GLB) writer.
//!
//! Georeference: the mesh's vertices stay `f32` relative to the skeleton
//! anchor, and the single root node carries the translation
//! `anchor − local_origin` as JSON numbers (full `f64` precision). Passing the
//! anchor itself as the local origin gives a tree at the scene origin, which
//! every viewer renders without jitter; a tile or scene origin shared by many
//! trees places them relative to each other; `DVec3::ZERO` puts the absolute
//! CRS coordinates in the translation (exact in the file, but viewers that
//! compose transforms in `f32` lose centimetres at national-grid magnitudes).
//! The CRS, anchor and local origin are also recorded in the node's `extras`
//! so the absolute position can always be recovered.
//!
//! We do not use `CESIUM_RTC`: its centre is earth-centred (ECEF), and
//! silva's skeletons live in projected CRSs such as EPSG:28992; converting
//! would need a projection library and would tie the file to Cesium.
//!
//! glTF is y-up: CRS `(x east, y north, z up)` is written as
//! `(x, z, −y)`, a proper rotation, so winding and normals stay outward.

use glam::{DVec3, Vec3};
use serde_json::{Value, json};

use super::Mesh;
use crate::skeleton::Anchor;

const GLB_MAGIC: u32 = 0x4654_6C67;
const CHUNK_JSON: u32 = 0x4E4F_534A;
const CHUNK_BIN: u32 = 0x004E_4942;
const FLOAT: u32 = 5126;
const UNSIGNED_SHORT: u32 = 5123;
const UNSIGNED_INT: u32 = 5125;
const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;

/// A CRS vector in glTF's y-up axes.
fn y_up(v: Vec3) -> Vec3 {
    Vec3::new(v.x, v.z, -v.y)
}

/// Encodes `mesh` as a GLB file: one node, one mesh, one primitive with
/// POSITION, NORMAL and indices (`u16` when fewer than 65,536 vertices,
/// else `u32`), and a bark material. See the module docs for `local_origin`.
pub fn glb(mesh: &Mesh, anchor: &Anchor, local_origin: DVec3) -> Vec<u8> {
    let translation = anchor.origin - local_origin;
    let mut node = json!({
        "name": "tree",
        "translation": [translation.x, translation.z, -translation.y],
        "extras": {
            "crs": anchor.crs,
            "anchor": anchor.origin.to_array(),
            "localOrigin": local_origin.to_array(),
            "axes": "glTF (x, y, z) = CRS (x, z, -y) relative to localOrigin",
        },
    });
    let mut document = json!({
        "asset": {"version": "2.0", "generator": concat!("silva ", env!("CARGO_PKG_VERSION"))},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
    });
    let bin = if mesh.is_empty() {
        Vec::new()
    } else {
        node["mesh"] = json!(0);
        let (bin, parts) = binary_buffer(mesh);
        add_mesh(&mut document, mesh, &parts, bin.len());
        bin
    };
    document["nodes"] = json!([node]);
    assemble(&document, bin)
}

/// Byte ranges of the three arrays in the binary buffer.
struct Parts {
    positions: (usize, usize),
    normals: (usize, usize),
    indices: (usize, usize),
    index_type: u32,
    min: Vec3,
    max: Vec3,
}

fn binary_buffer(mesh: &Mesh) -> (Vec<u8>, Parts) {
    let vertices = mesh.positions.len();
    let small = vertices <= usize::from(u16::MAX);
    let index_size = if small { 2 } else { 4 };
    let mut bin = Vec::with_capacity(vertices * 24 + mesh.indices.len() * index_size + 3);
    let (mut min, mut max) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for &p in &mesh.positions {
        let p = y_up(p);
        min = min.min(p);
        max = max.max(p);
        extend_vec3(&mut bin, p);
    }
    let normals_at = bin.len();
    for &n in &mesh.normals {
        // Normalised again after the axis swap so the validator's unit-length
        // check holds to f32 precision.
        extend_vec3(&mut bin, y_up(n).normalize_or(Vec3::Y));
    }
    let indices_at = bin.len();
    for &i in &mesh.indices {
        if small {
            bin.extend_from_slice(&(i as u16).to_le_bytes());
        } else {
            bin.extend_from_slice(&i.to_le_bytes());
        }
    }
    let parts = Parts {
        positions: (0, normals_at),
        normals: (normals_at, indices_at - normals_at),
        indices: (indices_at, bin.len() - indices_at),
        index_type: if small { UNSIGNED_SHORT } else { UNSIGNED_INT },
        min,
        max,
    };
    (bin, parts)
}

fn extend_vec3(bin: &mut Vec<u8>, v: Vec3) {
    for c in v.to_array() {
        bin.extend_from_slice(&c.to_le_bytes());
    }
}

fn add_mesh(document: &mut Value, mesh: &Mesh, parts: &Parts, buffer_len: usize) {
    let view = |(offset, length): (usize, usize), target: u32| json!({"buffer": 0, "byteOffset": offset, "byteLength": length, "target": target});
    let vertices = mesh.positions.len();
    document["buffers"] = json!([{"byteLength": buffer_len}]);
    document["bufferViews"] = json!([
        view(parts.positions, ARRAY_BUFFER),
        view(parts.normals, ARRAY_BUFFER),
        view(parts.indices, ELEMENT_ARRAY_BUFFER),
    ]);
    document["accessors"] = json!([
        {"bufferView": 0, "componentType": FLOAT, "count": vertices, "type": "VEC3",
         "min": parts.min.to_array(), "max": parts.max.to_array()},
        {"bufferView": 1, "componentType": FLOAT, "count": vertices, "type": "VEC3"},
        {"bufferView": 2, "componentType": parts.index_type, "count": mesh.indices.len(),
         "type": "SCALAR"},
    ]);
    document["materials"] = json!([{
        "name": "bark",
        "pbrMetallicRoughness": {
            "baseColorFactor": [0.33, 0.24, 0.16, 1.0],
            "metallicFactor": 0.0,
            "roughnessFactor": 0.9,
        },
    }]);
    document["meshes"] = json!([{
        "name": "branches",
        "primitives": [{
            "attributes": {"POSITION": 0, "NORMAL": 1},
            "indices": 2,
            "material": 0,
            "mode": 4,
        }],
    }]);
}

/// Writes the GLB container: 12-byte header, JSON chunk padded with spaces,
/// BIN chunk (if any) padded with zeros, every chunk 4-byte aligned.
fn assemble(document: &Value, mut bin: Vec<u8>) -> Vec<u8> {
    let mut json = document.to_string().into_bytes();
    while json.len() % 4 != 0 {
        json.push(b' ');
    }
    while bin.len() % 4 != 0 {
        bin.push(0);
    }
    let bin_chunk = if bin.is_empty() { 0 } else { 8 + bin.len() };
    let total = 12 + 8 + json.len() + bin_chunk;
    let mut out = Vec::with_capacity(total);
    for word in [GLB_MAGIC, 2, total as u32, json.len() as u32, CHUNK_JSON] {
        out.extend_from_slice(&word.to_le_bytes());
    }
    out.extend_from_slice(&json);
    if !bin.is_empty() {
        out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
        out.extend_from_slice(&CHUNK_BIN.to_le_bytes());
        out.extend_from_slice(&bin);
    }
    out
}
