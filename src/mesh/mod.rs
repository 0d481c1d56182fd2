//! Branch meshes, levels of detail, and mesh and skeleton writers (issue 5).
//!
//! The tree in lsystem-from-adtree-skeletons §3.4 and §4.5 was drawn as
//! jagged, untapered pipes swept straight along the skeleton. Here each
//! branch is a generalised cylinder: the axis is a
//! smoothed spline through the nodes, rings follow rotation-minimising frames
//! so they do not twist, the radius tapers from node to node, a lateral
//! starts inside its parent so joints have no gaps, and every tube is capped
//! and wound outward. Which branches are swept, and how finely, is decided by
//! the level of detail in [`lod`], defined once for every output and shared
//! with the chain code's LOD reduction (chain-code-tree-compression-lod §3.2).
//!
//! Writers turn a [`Mesh`] into OBJ ([`obj`]), binary PLY ([`mesh_ply`]) and
//! glTF 2.0 binary ([`glb`]); the skeleton itself is written as a
//! TreeQSM-style cylinder table ([`cylinder_table_csv`]); its own file forms
//! are [`Skeleton::to_json`] and [`Skeleton::to_ply`]. Writers
//! return bytes; the caller does the IO.
//!
//! ```
//! use glam::{DVec3, Vec3};
//! use silva::mesh::{self, Lod, MeshFormat};
//! use silva::{Anchor, NodeId, Skeleton};
//!
//! let mut tree = Skeleton::new(Anchor::at(DVec3::new(85_000.0, 446_000.0, 0.0)), 0.2);
//! let top = tree.add_child(NodeId::ROOT, Vec3::new(0.0, 0.0, 3.0), 0.15);
//! tree.add_child(top, Vec3::new(0.0, 0.2, 6.0), 0.05);
//! tree.add_child(top, Vec3::new(1.5, 0.0, 4.0), 0.04);
//! let m = mesh::build_mesh(&tree, Lod::L3);
//! assert!(m.triangle_count() > 0);
//! let glb = MeshFormat::Glb.encode(&m, tree.anchor(), tree.anchor().origin);
//! assert_eq!(&glb[..4], b"glTF");
//! ```

use glam::{DVec3, Vec3};

use crate::skeleton::{Anchor, Skeleton};

pub mod frame;
mod gltf;
pub mod lod;
mod obj;
mod ply;
mod sweep;
mod table;

pub use gltf::glb;
pub use lod::{Lod, prune_thin_branches, select, trunk_radius_m};
pub use obj::obj;
pub use ply::mesh_ply;
pub use sweep::{MIN_RADIUS_M, ring_radius_scale};
pub use table::{CYLINDER_TABLE_HEADER, cylinder_table_csv};

/// An indexed triangle mesh, coordinates in metres relative to the
/// skeleton's anchor (x east, y north, z up, as the skeleton).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Mesh {
    /// Vertex positions relative to the anchor.
    pub positions: Vec<Vec3>,
    /// Unit vertex normals, one per position, pointing out of the branch.
    pub normals: Vec<Vec3>,
    /// Triangles as vertex index triples, counter-clockwise seen from outside.
    pub indices: Vec<u32>,
}

impl Mesh {
    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    /// True when there is no triangle (a skeleton without internodes).
    pub fn is_empty(&self) -> bool {
        self.indices.is_empty()
    }

    /// Axis-aligned bounds of the positions, `(min, max)`; infinite when empty.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        self.positions.iter().fold(
            (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
            |(lo, hi), &p| (lo.min(p), hi.max(p)),
        )
    }

    /// The triangles as vertex index triples.
    pub fn triangles(&self) -> impl Iterator<Item = [u32; 3]> + '_ {
        self.indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]])
    }

    fn push_vertex(&mut self, position: Vec3, normal: Vec3) -> u32 {
        let index = self.positions.len() as u32;
        self.positions.push(position);
        self.normals.push(normal);
        index
    }
}

/// The branch mesh of `skeleton` at level `lod`: [`select`] the branches of
/// the level, then sweep each as a closed, tapered generalised cylinder.
pub fn build_mesh(skeleton: &Skeleton, lod: Lod) -> Mesh {
    sweep::sweep(&select(skeleton, lod), lod)
}

/// The mesh file formats silva writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum MeshFormat {
    /// Wavefront OBJ with vertex normals (text, z up).
    Obj,
    /// Binary little-endian PLY with normals (z up).
    Ply,
    /// glTF 2.0 binary (y up, georeferenced by the root node translation).
    Glb,
}

impl MeshFormat {
    /// Every format, in the order the API lists them.
    pub const ALL: [MeshFormat; 3] = [MeshFormat::Glb, MeshFormat::Obj, MeshFormat::Ply];

    /// The format for a file extension (`"obj"`, `"ply"`, `"glb"`, any case).
    pub fn from_extension(extension: &str) -> Option<MeshFormat> {
        match extension.to_ascii_lowercase().as_str() {
            "obj" => Some(MeshFormat::Obj),
            "ply" => Some(MeshFormat::Ply),
            "glb" => Some(MeshFormat::Glb),
            _ => None,
        }
    }

    /// The usual file extension, without the dot.
    pub fn extension(self) -> &'static str {
        match self {
            MeshFormat::Obj => "obj",
            MeshFormat::Ply => "ply",
            MeshFormat::Glb => "glb",
        }
    }

    /// The media type to serve the format with.
    pub fn media_type(self) -> &'static str {
        match self {
            MeshFormat::Obj => "model/obj",
            MeshFormat::Ply => "application/ply",
            MeshFormat::Glb => "model/gltf-binary",
        }
    }

    /// Encodes `mesh` (relative to `anchor`) with coordinates measured from
    /// `local_origin` in the anchor's CRS: pass `anchor.origin` for
    /// coordinates relative to the trunk base, `DVec3::ZERO` for absolute
    /// ones, or a scene or tile origin shared by many trees.
    pub fn encode(self, mesh: &Mesh, anchor: &Anchor, local_origin: DVec3) -> Vec<u8> {
        match self {
            MeshFormat::Obj => obj(mesh, anchor, local_origin).into_bytes(),
            MeshFormat::Ply => mesh_ply(mesh, anchor, local_origin),
            MeshFormat::Glb => glb(mesh, anchor, local_origin),
        }
    }
}
